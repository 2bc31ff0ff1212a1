/* The EKF of estimation/ekf.py, one control step (``Ekf.update``): robot_localization's
 * omnidirectional prediction, the stacked update of the step's odometry, lateral
 * pseudo-measurement, gyro, IMU yaw and accelerometer, and each GNSS fix applied at its epoch
 * with the steps since replayed from the history.
 *
 * ekf.py stays the reference: the same operations in the same order, but its matrix products
 * are numpy's (BLAS sums in another order) and its solve LAPACK's, so the two agree to rounding,
 * not bit for bit (tests bound the difference). The wrap of an angle is Python's float modulo.
 */
#include <string.h>

#include "native.h"

#define N 12
enum { X, Y, PSI, VX, VY, W, AX, AY, BIAS, EE, EN, SCALE };
#define G 9.81
#define DIFFUSE 1e6
#define FIX_NONE 0 /* interface.FIX_LEVELS: none, standalone, float, fixed */
#define MAX_M 7    /* measurements in one update */

/* x <- x + K nu; P <- P - K (P H^T)^T, symmetrised; K = P H^T S^-1, S = H P H^T + diag(R)
 * (Ekf._correct). H is m x N, row-major. */
static int correct(ekf_filter_t *f, int m, const double *nu, const double *H, const double *R) {
    double PHt[N * MAX_M], S[MAX_M * MAX_M], L[MAX_M * MAX_M], K[N * MAX_M];
    const double *P = f->P;
    for (int i = 0; i < N; i++)
        for (int j = 0; j < m; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++) acc += P[i * N + k] * H[j * N + k];
            PHt[i * m + j] = acc;
        }
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++) acc += H[i * N + k] * PHt[k * m + j];
            S[i * m + j] = acc;
        }
    for (int i = 0; i < m; i++) S[i * m + i] += R[i];
    /* Cholesky S = L L^T (LAPACK's dpotrf refuses a pivot <= 0 or NaN) */
    for (int j = 0; j < m; j++) {
        double d = S[j * m + j];
        for (int k = 0; k < j; k++) d -= L[j * m + k] * L[j * m + k];
        if (!(d > 0.0)) return AGN_NOT_POSITIVE;
        d = sqrt(d);
        L[j * m + j] = d;
        for (int i = j + 1; i < m; i++) {
            double v = S[i * m + j];
            for (int k = 0; k < j; k++) v -= L[i * m + k] * L[j * m + k];
            L[i * m + j] = v / d;
        }
        for (int k = j + 1; k < m; k++) L[j * m + k] = 0.0;
    }
    /* each row r of PHt: K[r] = S^-1 PHt[r] (S symmetric), by forward and back substitution */
    for (int r = 0; r < N; r++) {
        double y[MAX_M];
        for (int i = 0; i < m; i++) {
            double v = PHt[r * m + i];
            for (int k = 0; k < i; k++) v -= L[i * m + k] * y[k];
            y[i] = v / L[i * m + i];
        }
        for (int i = m - 1; i >= 0; i--) {
            double v = y[i];
            for (int k = i + 1; k < m; k++) v -= L[k * m + i] * K[r * m + k];
            K[r * m + i] = v / L[i * m + i];
        }
    }
    double dx[N];
    for (int i = 0; i < N; i++) {
        double acc = 0.0;
        for (int j = 0; j < m; j++) acc += K[i * m + j] * nu[j];
        dx[i] = acc;
    }
    for (int i = 0; i < N; i++) f->s[i] = f->s[i] + dx[i];
    f->s[PSI] = angle_wrap(f->s[PSI]);
    double Pn[N * N];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0;
            for (int k = 0; k < m; k++) acc += K[i * m + k] * PHt[j * m + k];
            Pn[i * N + j] = P[i * N + j] - acc;
        }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) f->P[i * N + j] = 0.5 * (Pn[i * N + j] + Pn[j * N + i]);
    return AGN_OK;
}

/* Ekf._predict: the omnidirectional model, P = F P F^T + Q dt */
static void predict(const ekf_config_t *c, ekf_filter_t *f, double dt) {
    double *s = f->s;
    double x = s[X], y = s[Y], psi = s[PSI], vx = s[VX], vy = s[VY], w = s[W], ax = s[AX],
           ay = s[AY], b = s[BIAS], ee = s[EE], en = s[EN], sc = s[SCALE];
    double ch = cos(psi), sh = sin(psi);
    double h2 = 0.5 * dt * dt;
    double F[N * N];
    memset(F, 0, sizeof F);
    for (int i = 0; i < N; i++) F[i * N + i] = 1.0;
    F[X * N + PSI] = (-vx * sh - vy * ch) * dt + (-ax * sh - ay * ch) * h2;
    F[Y * N + PSI] = (vx * ch - vy * sh) * dt + (ax * ch - ay * sh) * h2;
    F[X * N + VX] = ch * dt, F[X * N + VY] = -sh * dt, F[X * N + AX] = ch * h2;
    F[X * N + AY] = -sh * h2;
    F[Y * N + VX] = sh * dt, F[Y * N + VY] = ch * dt, F[Y * N + AX] = sh * h2;
    F[Y * N + AY] = ch * h2;
    F[PSI * N + W] = F[VX * N + AX] = F[VY * N + AY] = dt;
    F[BIAS * N + BIAS] = c->phi_b;
    double q[N];
    q[X] = q[Y] = c->pose_noise * dt;
    q[PSI] = c->yaw_noise * dt;
    q[VX] = q[VY] = c->velocity_noise * dt;
    q[W] = c->yaw_accel_noise * dt;
    q[AX] = q[AY] = c->accel_noise * dt;
    q[BIAS] = c->q_bias;
    q[EE] = q[EN] = 0.0;
    q[SCALE] = c->odom_scale_noise * dt;
    double phi = 1.0;
    if (f->mode >= 0) {
        phi = exp(-dt / c->tau[f->mode]);
        q[EE] = q[EN] = f->gnss_var * (1.0 - phi * phi);
    }
    F[EE * N + EE] = F[EN * N + EN] = phi;
    s[X] = x + (vx * ch - vy * sh) * dt + (ax * ch - ay * sh) * h2;
    s[Y] = y + (vx * sh + vy * ch) * dt + (ax * sh + ay * ch) * h2;
    s[PSI] = angle_wrap(psi + w * dt);
    s[VX] = vx + ax * dt;
    s[VY] = vy + ay * dt;
    s[W] = w;
    s[AX] = ax;
    s[AY] = ay;
    s[BIAS] = b * c->phi_b;
    s[EE] = ee * phi;
    s[EN] = en * phi;
    s[SCALE] = sc;
    double FP[N * N];
    const double *P = f->P;
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++) acc += F[i * N + k] * P[k * N + j];
            FP[i * N + j] = acc;
        }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++) acc += FP[i * N + k] * F[j * N + k];
            f->P[i * N + j] = acc;
        }
    for (int i = 0; i < N; i++) f->P[i * N + i] += q[i];
}

/* Ekf._fuse_step: odometry (v, w / chi), vy = 0, gyro, IMU yaw and accelerometer */
static int fuse_step(const ekf_config_t *c, ekf_filter_t *f, const double *r) {
    const double *s = f->s;
    double psi = s[PSI], vx = s[VX], vy = s[VY], w = s[W], ax = s[AX], ay = s[AY], b = s[BIAS],
           sc = s[SCALE];
    double v_odom = r[0], w_odom = r[1] / c->chi;
    int m = c->use_accel ? 7 : 5;
    double H[MAX_M * N], nu[MAX_M], R[MAX_M];
    memset(H, 0, sizeof H);
    H[0 * N + VX] = 1.0 + sc, H[0 * N + SCALE] = vx;
    H[1 * N + W] = 1.0;
    H[2 * N + VY] = 1.0;
    H[3 * N + W] = 1.0;
    H[4 * N + PSI] = H[4 * N + BIAS] = 1.0;
    nu[0] = v_odom - vx * (1.0 + sc);
    nu[1] = w_odom - w;
    nu[2] = -vy;
    nu[3] = r[2] - w;
    nu[4] = angle_wrap(r[5] - psi - b);
    for (int i = 0; i < m; i++) R[i] = c->r_step[i];
    double e0 = c->odom_speed_rel * fabs(v_odom) + c->odom_floor;
    double e1 = c->odom_yaw_rel * fabs(w_odom) + c->odom_floor;
    R[0] = e0 * e0;
    R[1] = e1 * e1;
    if (c->use_accel) {
        double roll = r[3], pitch = r[4];
        nu[5] = r[6] + G * sin(pitch) - (ax - w * vy);
        nu[6] = r[7] - G * cos(pitch) * sin(roll) - (ay + w * vx);
        H[5 * N + AX] = 1.0, H[5 * N + W] = -vy, H[5 * N + VY] = -w;
        H[6 * N + AY] = 1.0, H[6 * N + W] = vx, H[6 * N + VX] = w;
    }
    return correct(f, m, nu, H, R);
}

/* Ekf._fuse_gnss: the fix through the lever arm (rotated by the IMU's roll and pitch and the
 * state's yaw); a new fix level starts a new error process */
static int fuse_gnss(const ekf_config_t *c, ekf_filter_t *f, const double *g, const double *r) {
    int mode = (int)g[1];
    if (mode != f->mode) {
        f->mode = mode;
        f->gnss_var = (g[4] * g[4] + g[5] * g[5]) / 2.0;
        for (int i = EE; i <= EN; i++) {
            f->s[i] = 0.0;
            for (int j = 0; j < N; j++) f->P[i * N + j] = f->P[j * N + i] = 0.0;
            f->P[i * N + i] = f->gnss_var;
        }
    }
    const double *s = f->s;
    double roll = r[3], pitch = r[4], lever_x = g[7], lever_up = g[8];
    double lx = cos(pitch) * lever_x + sin(pitch) * cos(roll) * lever_up;
    double ly = -sin(roll) * lever_up;
    double ch = cos(s[PSI]), sh = sin(s[PSI]);
    double nu[2] = {g[2] - (s[X] + ch * lx - sh * ly + s[EE]),
                    g[3] - (s[Y] + sh * lx + ch * ly + s[EN])};
    double H[2 * N];
    memset(H, 0, sizeof H);
    H[0 * N + X] = H[1 * N + Y] = H[0 * N + EE] = H[1 * N + EN] = 1.0;
    H[0 * N + PSI] = -sh * lx - ch * ly;
    H[1 * N + PSI] = ch * lx - sh * ly;
    double var = c->gnss_white * c->gnss_white;
    double R[2] = {var, var};
    return correct(f, 2, nu, H, R);
}

/* slot of history entry i (0: the oldest held) */
static int32_t slot(const ekf_filter_t *f, int32_t i) { return (f->head + i) % f->capacity; }

static void store(ekf_filter_t *f, int32_t at, const double *r) {
    memcpy(f->hist_s + (size_t)at * N, f->s, N * sizeof(double));
    memcpy(f->hist_P + (size_t)at * N * N, f->P, N * N * sizeof(double));
    if (r != f->hist_r + (size_t)at * EKF_READING)
        memcpy(f->hist_r + (size_t)at * EKF_READING, r, EKF_READING * sizeof(double));
    f->hist_mode[at] = f->mode;
    f->hist_var[at] = f->gnss_var;
}

/* Ekf._remember: append (the oldest entry goes when the history is full) */
static void remember(ekf_filter_t *f, const double *r) {
    int32_t at;
    if (f->count < f->capacity) {
        at = slot(f, f->count);
        f->count++;
    } else {
        at = f->head;
        f->head = (f->head + 1) % f->capacity;
    }
    store(f, at, r);
}

/* Ekf._fuse_lagged_fix */
static int fuse_lagged_fix(const ekf_config_t *c, ekf_filter_t *f, const double *g,
                           const double *r, double dt) {
    double age = g[6];
    if (age > c->history_s + 1e-9) return AGN_OK; /* older than the history: dropped */
    int32_t len = f->count;
    double back = nearbyint(age / dt); /* Python's round: half to even */
    if (back > len - 1) back = len - 1;
    int32_t start = len - 1 - (int32_t)back;
    int32_t at = slot(f, start);
    memcpy(f->s, f->hist_s + (size_t)at * N, N * sizeof(double));
    memcpy(f->P, f->hist_P + (size_t)at * N * N, N * N * sizeof(double));
    f->mode = f->hist_mode[at];
    f->gnss_var = f->hist_var[at];
    int st = fuse_gnss(c, f, g, r);
    if (st) return st;
    store(f, at, f->hist_r + (size_t)at * EKF_READING);
    for (int32_t i = start + 1; i < len; i++) {
        int32_t k = slot(f, i);
        const double *ri = f->hist_r + (size_t)k * EKF_READING;
        predict(c, f, dt);
        st = fuse_step(c, f, ri);
        if (st) return st;
        store(f, k, ri);
    }
    return AGN_OK;
}

EXPORT int ekf_update(const ekf_update_args_t *a) {
    if (!a || !a->config || !a->filter || !a->reading || !a->gnss) return AGN_NULL_ARRAY;
    const ekf_config_t *c = a->config;
    ekf_filter_t *f = a->filter;
    if (!f->s || !f->P || !f->hist_s || !f->hist_P || !f->hist_r || !f->hist_var ||
        !f->hist_mode)
        return AGN_NULL_ARRAY;
    if (f->capacity < 2 || f->count < 0 || f->count > f->capacity || f->head < 0 ||
        f->head >= f->capacity || f->mode < -1 || f->mode > 3)
        return AGN_BAD_SIZE;
    if (!(a->dt > 0) || !(c->chi > 0)) return AGN_BAD_VALUE;
    const double *r = a->reading, *g = a->gnss;
    int fix = g[0] != 0.0 && (int)g[1] != FIX_NONE;
    if (fix && (!((int)g[1] >= 1 && (int)g[1] <= 3) || !(c->tau[(int)g[1]] > 0)))
        return AGN_BAD_VALUE;
    f->k += 1;
    if (f->k > 0) {
        predict(c, f, a->dt);
    } else if (fix) {
        /* navsat_transform's way: the first fix places the robot */
        for (int j = 0; j < N; j++) {
            f->P[X * N + j] = f->P[j * N + X] = 0.0;
            f->P[Y * N + j] = f->P[j * N + Y] = 0.0;
        }
        f->P[X * N + X] = f->P[Y * N + Y] = DIFFUSE;
    }
    int st = fuse_step(c, f, r);
    if (st) return st;
    remember(f, r);
    if (fix) return fuse_lagged_fix(c, f, g, r, a->dt);
    return AGN_OK;
}
