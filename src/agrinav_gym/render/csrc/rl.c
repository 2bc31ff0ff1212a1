/* robot_localization's planar filter (estimation/robot_localization.py, two_d_mode), one
 * control step (``RobotLocalizationEkf.update``): the step's readings queued by stamp, each
 * one processed as FilterBase::processMeasurement does (predict up to a newer reading, then
 * the Mahalanobis test and the Joseph-form correction), and with smooth_lagged_data a late fix
 * handled as RosFilter::revertTo does (the state saved before its stamp restored, the readings
 * since replayed).
 *
 * robot_localization.py stays the reference: the same operations in the same order, but its
 * matrix products are numpy's (BLAS sums in another order) and its inverse LAPACK's, so the
 * two agree to rounding, not bit for bit (tests bound the difference).
 */
#include <string.h>

#include "native.h"

#define N 8
enum { X, Y, PSI, VX, VY, W, AX, AY };
#define MIN_VARIANCE 1e-9
#define GRAVITY 9.80665 /* the node's gravitational_acceleration default */
enum { O_ODOM, O_IMU, O_IMU_RATE, O_IMU_ACCEL, O_GPS }; /* order of readings with equal stamps */
static const int SOURCE[5] = {0, 1, 1, 1, 2};         /* rejected[]: odom, imu, gps */

static void matmul(const double *A, const double *B, double *C) { /* C = A B, N x N */
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++) acc += A[i * N + k] * B[k * N + j];
            C[i * N + j] = acc;
        }
}

static void matmul_bt(const double *A, const double *B, double *C) { /* C = A B^T */
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++) acc += A[i * N + k] * B[j * N + k];
            C[i * N + j] = acc;
        }
}

/* RobotLocalizationEkf._predict: the omnidirectional model, P = J P J^T + Q dt */
static void predict(const rl_config_t *c, rl_filter_t *f, double dt) {
    double *s = f->s;
    double x = s[X], y = s[Y], psi = s[PSI], vx = s[VX], vy = s[VY], w = s[W], ax = s[AX],
           ay = s[AY];
    double ch = cos(psi), sh = sin(psi);
    double h2 = 0.5 * dt * dt;
    double J[N * N], JP[N * N];
    memset(J, 0, sizeof J);
    for (int i = 0; i < N; i++) J[i * N + i] = 1.0;
    J[X * N + VX] = ch * dt, J[X * N + VY] = -sh * dt, J[X * N + AX] = ch * h2;
    J[X * N + AY] = -sh * h2;
    J[Y * N + VX] = sh * dt, J[Y * N + VY] = ch * dt, J[Y * N + AX] = sh * h2;
    J[Y * N + AY] = ch * h2;
    J[PSI * N + W] = J[VX * N + AX] = J[VY * N + AY] = dt;
    J[X * N + PSI] = (-sh * vx - ch * vy) * dt + (-sh * ax - ch * ay) * h2;
    J[Y * N + PSI] = (ch * vx - sh * vy) * dt + (ch * ax - sh * ay) * h2;
    s[X] = x + (ch * vx - sh * vy) * dt + (ch * ax - sh * ay) * h2;
    s[Y] = y + (sh * vx + ch * vy) * dt + (sh * ax + ch * ay) * h2;
    s[PSI] = angle_wrap(psi + w * dt);
    s[VX] = vx + ax * dt;
    s[VY] = vy + ay * dt;
    matmul(J, f->P, JP);
    matmul_bt(JP, J, f->P);
    for (int i = 0; i < N; i++) f->P[i * N + i] += c->q[i] * dt;
}

/* the inverse of the m x m matrix S (m <= 3) by Gauss-Jordan elimination with partial
 * pivoting, as LAPACK's getrf/getri pivot; AGN_NOT_POSITIVE where it is singular */
static int invert(int m, const double *S, double *inv) {
    double a[RL_MAX_M * 2 * RL_MAX_M];
    int w = 2 * m;
    for (int i = 0; i < m; i++)
        for (int j = 0; j < w; j++)
            a[i * w + j] = j < m ? S[i * m + j] : (j - m == i ? 1.0 : 0.0);
    for (int col = 0; col < m; col++) {
        int p = col;
        for (int i = col + 1; i < m; i++)
            if (fabs(a[i * w + col]) > fabs(a[p * w + col])) p = i;
        if (!(a[p * w + col] != 0.0) || !isfinite(a[p * w + col])) return AGN_NOT_POSITIVE;
        if (p != col)
            for (int j = 0; j < w; j++) {
                double t = a[col * w + j];
                a[col * w + j] = a[p * w + j];
                a[p * w + j] = t;
            }
        double d = a[col * w + col];
        for (int j = 0; j < w; j++) a[col * w + j] /= d;
        for (int i = 0; i < m; i++) {
            if (i == col) continue;
            double e = a[i * w + col];
            for (int j = 0; j < w; j++) a[i * w + j] -= e * a[col * w + j];
        }
    }
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++) inv[i * m + j] = a[i * w + m + j];
    return AGN_OK;
}

/* RobotLocalizationEkf._correct (Ekf::correct): the Mahalanobis test, then the Joseph form */
static int correct(rl_filter_t *f, const rl_measurement_t *mm) {
    int m = mm->m;
    const int32_t *idx = mm->index;
    double PHt[N * RL_MAX_M], S[RL_MAX_M * RL_MAX_M], Si[RL_MAX_M * RL_MAX_M];
    double K[N * RL_MAX_M], R[RL_MAX_M], nu[RL_MAX_M];
    const double *P = f->P;
    for (int a = 0; a < m; a++) R[a] = fmax(fabs(mm->var[a]), MIN_VARIANCE);
    for (int i = 0; i < N; i++)
        for (int a = 0; a < m; a++) PHt[i * m + a] = P[i * N + idx[a]];
    for (int a = 0; a < m; a++)
        for (int b = 0; b < m; b++) S[a * m + b] = PHt[idx[a] * m + b] + (a == b ? R[a] : 0.0);
    int st = invert(m, S, Si);
    if (st) return st;
    for (int i = 0; i < N; i++)
        for (int b = 0; b < m; b++) {
            double acc = 0.0;
            for (int a = 0; a < m; a++) acc += PHt[i * m + a] * Si[a * m + b];
            K[i * m + b] = acc;
        }
    for (int a = 0; a < m; a++) {
        nu[a] = mm->z[a] - f->s[idx[a]];
        if (idx[a] == PSI) nu[a] = angle_wrap(nu[a]);
    }
    if (!isnan(mm->threshold)) {
        double d2 = 0.0;
        for (int b = 0; b < m; b++) {
            double acc = 0.0;
            for (int a = 0; a < m; a++) acc += nu[a] * Si[a * m + b];
            d2 += acc * nu[b];
        }
        if (d2 >= mm->threshold * mm->threshold) {
            f->rejected[SOURCE[mm->order]] += 1;
            return AGN_OK;
        }
    }
    double dx[N];
    for (int i = 0; i < N; i++) {
        double acc = 0.0;
        for (int a = 0; a < m; a++) acc += K[i * m + a] * nu[a];
        dx[i] = acc;
    }
    for (int i = 0; i < N; i++) f->s[i] = f->s[i] + dx[i];
    f->s[PSI] = angle_wrap(f->s[PSI]);
    /* P = G P G^T + K R K^T, G = I - K H */
    double G[N * N], GP[N * N], KR[N * RL_MAX_M];
    memset(G, 0, sizeof G);
    for (int i = 0; i < N; i++) G[i * N + i] = 1.0;
    for (int i = 0; i < N; i++)
        for (int a = 0; a < m; a++) G[i * N + idx[a]] -= K[i * m + a];
    matmul(G, P, GP);
    for (int i = 0; i < N; i++)
        for (int a = 0; a < m; a++) KR[i * m + a] = K[i * m + a] * R[a];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0, kr = 0.0;
            for (int k = 0; k < N; k++) acc += GP[i * N + k] * G[j * N + k];
            for (int a = 0; a < m; a++) kr += KR[i * m + a] * K[j * m + a];
            f->P[i * N + j] = acc + kr;
        }
    return AGN_OK;
}

/* FilterBase::processMeasurement */
static int process(const rl_config_t *c, rl_filter_t *f, const rl_measurement_t *m) {
    double delta = m->time - f->t_last;
    if (delta > 0.0) predict(c, f, delta);
    int st = correct(f, m);
    if (st) return st;
    if (delta >= 0.0) f->t_last = m->time;
    return AGN_OK;
}

/* ------------------------------------------------------------------ readings */
static rl_measurement_t reading(double t, int order, int m, const int32_t *idx, const double *z,
                                const double *var, double threshold) {
    rl_measurement_t r;
    memset(&r, 0, sizeof r);
    r.time = t, r.order = order, r.m = m, r.threshold = threshold;
    for (int a = 0; a < m; a++) r.index[a] = idx[a], r.z[a] = z[a], r.var[a] = var[a];
    return r;
}

static rl_measurement_t odom(const rl_config_t *c, const double *r, double t) {
    static const int32_t idx[3] = {VX, VY, W};
    double z[3] = {r[RL_ODOM_V], 0.0, r[RL_ODOM_W] / c->chi};
    return reading(t, O_ODOM, 3, idx, z, c->odom_var, c->odom_threshold);
}

static rl_measurement_t imu_yaw(const rl_config_t *c, const double *r, double t) {
    static const int32_t idx[1] = {PSI};
    return reading(t, O_IMU, 1, idx, r + RL_YAW, &c->yaw_var, c->imu_threshold);
}

static rl_measurement_t imu_rate(const rl_config_t *c, const double *r, double t) {
    static const int32_t idx[1] = {W};
    return reading(t, O_IMU_RATE, 1, idx, r + RL_GYRO_Z, &c->rate_var, c->imu_threshold);
}

/* imu0's linear acceleration with remove_gravitational_acceleration (x and y in two_d_mode) */
static rl_measurement_t imu_accel(const rl_config_t *c, const double *r, double t) {
    static const int32_t idx[2] = {AX, AY};
    double roll = r[RL_ROLL], pitch = r[RL_PITCH];
    double g = GRAVITY * cos(pitch);
    double z[2] = {r[RL_ACCEL_X] + GRAVITY * sin(pitch), r[RL_ACCEL_Y] - g * sin(roll)};
    return reading(t, O_IMU_ACCEL, 2, idx, z, c->accel_var, c->accel_threshold);
}

/* navsat_transform's GPS odometry: the fix (at base_link unless the lever arm is known) */
static rl_measurement_t gps(const rl_config_t *c, const rl_filter_t *f, const double *r,
                            double t) {
    static const int32_t idx[2] = {X, Y};
    double e = r[RL_EAST], n = r[RL_NORTH];
    if (c->lever_arm) {
        double lx = r[RL_LEVER_X], ly = r[RL_LEVER_Y];
        double ch = cos(f->s[PSI]), sh = sin(f->s[PSI]);
        e = e - (ch * lx - sh * ly), n = n - (sh * lx + ch * ly);
    }
    double z[2] = {e, n};
    double var[2] = {r[RL_SIGMA_E] * r[RL_SIGMA_E], r[RL_SIGMA_N] * r[RL_SIGMA_N]};
    return reading(t, O_GPS, 2, idx, z, var, c->gps_threshold);
}

/* ------------------------------------------------------------------ history rings */
static int32_t state_slot(const rl_filter_t *f, int32_t i) {
    return (f->head + i) % f->capacity;
}
static int32_t done_slot(const rl_filter_t *f, int32_t i) {
    return (f->done_head + i) % f->done_capacity;
}

/* RobotLocalizationEkf._save */
static int save(rl_filter_t *f) {
    int32_t at;
    if (f->count > 0 && f->hist_t[state_slot(f, f->count - 1)] == f->t_last) {
        at = state_slot(f, f->count - 1);
    } else {
        if (f->count == f->capacity) return AGN_BAD_SIZE;
        at = state_slot(f, f->count);
        f->count++;
    }
    f->hist_t[at] = f->t_last;
    memcpy(f->hist_s + (size_t)at * N, f->s, N * sizeof(double));
    memcpy(f->hist_P + (size_t)at * N * N, f->P, N * N * sizeof(double));
    return AGN_OK;
}

/* RobotLocalizationEkf._revert (RosFilter::revertTo(time - 1 ns)): restores the state and
 * writes the readings to replay to out (newest first); returns how many */
static int32_t revert(rl_filter_t *f, double time, rl_measurement_t *out) {
    double t = time - 1e-9;
    int32_t last = -1;
    while (f->count > 0 && f->hist_t[state_slot(f, f->count - 1)] > t) {
        last = state_slot(f, f->count - 1);
        f->count--;
    }
    if (f->count > 0) last = state_slot(f, f->count - 1);
    if (last < 0) return 0;
    memcpy(f->s, f->hist_s + (size_t)last * N, N * sizeof(double));
    memcpy(f->P, f->hist_P + (size_t)last * N * N, N * N * sizeof(double));
    f->t_last = f->hist_t[last];
    int32_t n = 0;
    while (f->done_count > 0 && f->done[done_slot(f, f->done_count - 1)].time > t) {
        const rl_measurement_t *m = &f->done[done_slot(f, f->done_count - 1)];
        f->done_count--;
        if (f->t_last <= m->time) out[n++] = *m;
    }
    return n;
}

/* RobotLocalizationEkf._expire (RosFilter::clearExpiredHistory) */
static void expire(const rl_config_t *c, rl_filter_t *f) {
    double cut = f->t_last - c->history_s;
    while (f->count > 1 && f->hist_t[f->head] < cut) {
        f->head = (f->head + 1) % f->capacity;
        f->count--;
    }
    while (f->done_count > 0 && f->done[f->done_head].time < cut) {
        f->done_head = (f->done_head + 1) % f->done_capacity;
        f->done_count--;
    }
}

/* a stable insertion sort by (time, order), as Python's list.sort */
static void sort_queue(rl_measurement_t *q, int32_t n) {
    for (int32_t i = 1; i < n; i++) {
        rl_measurement_t m = q[i];
        int32_t j = i - 1;
        while (j >= 0 && (q[j].time > m.time || (q[j].time == m.time && q[j].order > m.order))) {
            q[j + 1] = q[j];
            j--;
        }
        q[j + 1] = m;
    }
}

/* RobotLocalizationEkf._start: the filter as the stack left it, from its first readings */
static int start(const rl_config_t *c, rl_filter_t *f, const double *r) {
    rl_measurement_t tw = odom(c, r, 0.0);
    for (int a = 0; a < 3; a++) {
        f->s[tw.index[a]] = tw.z[a];
        f->P[tw.index[a] * (N + 1)] = fmax(tw.var[a], MIN_VARIANCE);
    }
    f->s[PSI] = angle_wrap(r[RL_YAW]);
    f->P[PSI * (N + 1)] = fmax(c->yaw_var, MIN_VARIANCE);
    if (c->fuse_accel) {
        rl_measurement_t acc = imu_accel(c, r, 0.0);
        f->s[AX] = acc.z[0], f->s[AY] = acc.z[1];
        f->P[AX * (N + 1)] = fmax(acc.var[0], MIN_VARIANCE);
        f->P[AY * (N + 1)] = fmax(acc.var[1], MIN_VARIANCE);
    }
    if (r[RL_FIX] != 0.0) {
        rl_measurement_t fix = gps(c, f, r, 0.0);
        f->s[X] = fix.z[0], f->s[Y] = fix.z[1];
        f->P[X * (N + 1)] = fmax(fix.var[0], MIN_VARIANCE);
        f->P[Y * (N + 1)] = fmax(fix.var[1], MIN_VARIANCE);
        f->anchored = 1;
    }
    f->t_last = 0.0;
    return c->smooth ? save(f) : AGN_OK;
}

EXPORT int rl_update(const rl_update_args_t *a) {
    if (!a || !a->config || !a->filter || !a->reading) return AGN_NULL_ARRAY;
    const rl_config_t *c = a->config;
    rl_filter_t *f = a->filter;
    if (!f->s || !f->P || !f->hist_t || !f->hist_s || !f->hist_P || !f->done || !f->queue)
        return AGN_NULL_ARRAY;
    if (f->capacity < 2 || f->count < 0 || f->count > f->capacity || f->head < 0 ||
        f->head >= f->capacity || f->done_capacity < 1 || f->done_count < 0 ||
        f->done_count > f->done_capacity || f->done_head < 0 ||
        f->done_head >= f->done_capacity || f->queue_capacity < f->done_capacity + 5)
        return AGN_BAD_SIZE;
    if (!(c->dt > 0) || !(c->chi > 0)) return AGN_BAD_VALUE;
    const double *r = a->reading;
    f->k += 1;
    if (f->k == 0) return start(c, f, r);
    double now = f->k * c->dt;
    rl_measurement_t *q = f->queue;
    int32_t n = 0;
    q[n++] = odom(c, r, now);
    q[n++] = imu_yaw(c, r, now);
    if (c->fuse_rate) q[n++] = imu_rate(c, r, now);
    if (c->fuse_accel) q[n++] = imu_accel(c, r, now);
    if (r[RL_FIX] != 0.0) {
        /* stamped at its epoch: a whole number of control steps ago (Python's round) */
        double back = nearbyint(r[RL_AGE] / c->dt);
        rl_measurement_t fix = gps(c, f, r, (f->k - back) * c->dt);
        if (!f->anchored) {
            /* navsat_transform's datum: the first fix is tied to the filter's pose now */
            f->s[X] = fix.z[0], f->s[Y] = fix.z[1];
            f->anchored = 1;
        } else {
            q[n++] = fix;
        }
    }
    sort_queue(q, n);
    if (c->smooth && n > 0 && q[0].time < f->t_last) {
        /* the replayed readings go first (then a stable sort), as replay + queue does */
        rl_measurement_t fresh[5];
        memcpy(fresh, q, (size_t)n * sizeof *q);
        int32_t k = revert(f, q[0].time, q);
        memcpy(q + k, fresh, (size_t)n * sizeof *q);
        n += k;
        sort_queue(q, n);
    }
    for (int32_t i = 0; i < n; i++) {
        int st = process(c, f, &q[i]);
        if (st) return st;
        if (c->smooth) {
            if (f->done_count == f->done_capacity) return AGN_BAD_SIZE;
            f->done[done_slot(f, f->done_count)] = q[i];
            f->done_count++;
            st = save(f);
            if (st) return st;
        }
    }
    if (c->smooth) expire(c, f);
    return AGN_OK;
}
