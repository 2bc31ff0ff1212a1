/* The tyre model of sim/tyres.py (docs/physics.md), one physics step of every wheel: normal
 * force from the tyre and soil's vertical spring-damper on the terrain's bilinear surface,
 * Janosi-Hanamoto shear with the relaxation-length shear state, rolling resistance.
 *
 * The Python model (TyreModel._forces) is the reference: every expression below is evaluated
 * in the order Python evaluates its twin (C99, no floating-point contraction, exp from the same
 * libm), so both give the same bits; tests compare them exactly. min and max follow Python's
 * builtins (the first argument unless the second is strictly smaller / larger).
 */
#include "native.h"

/* sim/tyres.py: SHEAR_CAP and RR_SPEED */
#define SHEAR_CAP 4.0
#define RR_SPEED 0.01

static inline double py_min(double a, double b) { return b < a ? b : a; }
static inline double py_max(double a, double b) { return b > a ? b : a; }

/* the grid cell (row i, column j) under (x, y), clamped to the grid, and where in it:
 * TyreModel._cell */
static void cell(const tyre_ground_t *g, double x, double y, int32_t *i_out, int32_t *j_out,
                 double *fu, double *fv) {
    double sp = g->spacing;
    double u = py_min(py_max((x - g->x0) / sp, 0.0), g->nx - 1.0);
    double v = py_min(py_max((y - g->y0) / sp, 0.0), g->ny - 1.0);
    int32_t j = (int32_t)u, i = (int32_t)v;
    if (j > g->nx - 2) j = g->nx - 2;
    if (i > g->ny - 2) i = g->ny - 2;
    *i_out = i;
    *j_out = j;
    *fu = u - j;
    *fv = v - i;
}

/* height and slope (dz/dx, dz/dy) of the bilinear surface of grid (the ground's heights, or
 * the field's before any cut) at (x, y): TyreModel.surface */
static void surface_of(const tyre_ground_t *g, const double *grid, double x, double y,
                       double *z, double *hx, double *hy) {
    double sp = g->spacing, fu, fv;
    int32_t i, j;
    cell(g, x, y, &i, &j, &fu, &fv);
    const double *row0 = grid + (size_t)i * g->nx, *row1 = row0 + g->nx;
    double a = row0[j], b = row0[j + 1], c = row1[j], d = row1[j + 1];
    double z0 = a + (b - a) * fu, z1 = c + (d - c) * fu;
    *z = z0 + (z1 - z0) * fv;
    *hx = ((b - a) * (1.0 - fv) + (d - c) * fv) / sp;
    *hy = (z1 - z0) / sp;
}

static void surface(const tyre_ground_t *g, double x, double y, double *z, double *hx,
                    double *hy) {
    surface_of(g, g->heights, x, y, z, hx, hy);
}

/* A yielding ground's cut: the corners of the cell under (x, y) lowered to z where they are
 * above it (TyreModel._cut) */
static void cut(const tyre_ground_t *g, double x, double y, double z) {
    double fu, fv;
    int32_t i, j;
    cell(g, x, y, &i, &j, &fu, &fv);
    double *row0 = g->heights + (size_t)i * g->nx, *row1 = row0 + g->nx;
    if (row0[j] > z) row0[j] = z;
    if (row0[j + 1] > z) row0[j + 1] = z;
    if (row1[j] > z) row1[j] = z;
    if (row1[j + 1] > z) row1[j + 1] = z;
}

/* A point contact: the wheel as a sphere of its radius on the tangent plane under its centre
 * (TyreModel._point). Returns 0 when it does not press on the ground. */
static int point(const tyre_ground_t *g, const double *c, const double *v, double *n_force,
                 double *nx, double *ny, double *nz, double *rx, double *ry, double *rz) {
    double r = g->radius, h, hx, hy;
    surface(g, c[0], c[1], &h, &hx, &hy);
    double inv = 1.0 / sqrt(hx * hx + hy * hy + 1.0);
    double mx = -hx * inv, my = -hy * inv, mz = inv;
    double dist = (c[2] - h) * mz; /* wheel centre to the local tangent plane */
    double f = g->kz * (r - dist) - g->cz * (v[0] * mx + v[1] * my + v[2] * mz);
    if (dist >= r || f <= 0.0) return 0;
    *n_force = f;
    *nx = mx;
    *ny = my;
    *nz = mz;
    *rx = -dist * mx; /* centre -> contact point */
    *ry = -dist * my;
    *rz = -dist * mz;
    return 1;
}

/* A cylindrical tread contact_width wide: slices discs across it, each a spring-damper of
 * 1/slices of the stiffness and damping along the surface normal under it, summed into one
 * force on the line through their resultant (TyreModel._tread). */
static int tread(const tyre_ground_t *g, const double *c, const double *axle, const double *v,
                 const double *w, double *n_force, double *nx_out, double *ny_out,
                 double *nz_out, double *rx, double *ry, double *rz) {
    double r = g->radius;
    int32_t n = g->slices;
    double ks = g->kz / n, cs = g->cz / n;
    double ax = axle[0], ay = axle[1], az = axle[2];
    double fx = 0.0, fy = 0.0, fz = 0.0, mx = 0.0, my = 0.0, mz = 0.0;
    double gx = 0.0, gy = 0.0, gz = 0.0, total = 0.0;
    for (int32_t k = 0; k < n; k++) {
        double off = g->contact_width * ((k + 0.5) / n - 0.5);
        double ox = off * ax, oy = off * ay, oz = off * az;
        double h, hx, hy;
        surface(g, c[0] + ox, c[1] + oy, &h, &hx, &hy);
        double inv = 1.0 / sqrt(hx * hx + hy * hy + 1.0);
        double nx = -hx * inv, ny = -hy * inv, nz = inv;
        double dist = (c[2] + oz - h) * nz;
        double na = nx * ax + ny * ay + nz * az;
        double px = nx - na * ax, py = ny - na * ay, pz = nz - na * az;
        double pl = sqrt(px * px + py * py + pz * pz);
        if (pl < 1e-9) continue;
        double depth = r * pl - dist;
        if (depth <= 0.0) continue;
        double lx = ox - r * px / pl + depth * nx;
        double ly = oy - r * py / pl + depth * ny;
        double lz = oz - r * pz / pl + depth * nz;
        double vx = v[0] + w[1] * lz - w[2] * ly;
        double vy = v[1] + w[2] * lx - w[0] * lz;
        double vz = v[2] + w[0] * ly - w[1] * lx;
        double spring = ks * depth;
        if (g->bearing) {
            /* the slope the soil stands at: the field's, or a cut bench's where flatter */
            double z0, fx0, fy0;
            surface_of(g, g->heights0, c[0] + ox, c[1] + oy, &z0, &fx0, &fy0);
            double t = py_min(sqrt(hx * hx + hy * hy), sqrt(fx0 * fx0 + fy0 * fy0));
            double gq = t < 1.0 ? (1.0 - t) * (1.0 - t) : 0.0;
            double cap = py_max(g->bear_cohesive * (gq - (1.0 - gq) * g->bear_k3) +
                                    g->bear_weight * gq,
                                0.0);
            if (spring > cap) {
                /* the soil flows: the ground under the disc is cut down to where it holds the
                 * disc at its capacity (the elastic part of the sinkage, cap/k, stays) */
                spring = cap;
                cut(g, c[0] + lx - depth * nx, c[1] + ly - depth * ny,
                    c[2] + lz - depth * nz + cap / ks);
            }
        }
        double f = spring - cs * (vx * nx + vy * ny + vz * nz);
        if (f <= 0.0) continue;
        double ex = f * nx, ey = f * ny, ez = f * nz;
        fx = fx + ex;
        fy = fy + ey;
        fz = fz + ez;
        mx = mx + (ly * ez - lz * ey);
        my = my + (lz * ex - lx * ez);
        mz = mz + (lx * ey - ly * ex);
        gx = gx + f * lx;
        gy = gy + f * ly;
        gz = gz + f * lz;
        total = total + f;
    }
    double nf = sqrt(fx * fx + fy * fy + fz * fz);
    if (nf <= 0.0) return 0;
    double nx = fx / nf, ny = fy / nf, nz = fz / nf;
    double n2 = nf * nf;
    double depth = (gx * nx + gy * ny + gz * nz) / total;
    *rx = (fy * mz - fz * my) / n2 + depth * nx;
    *ry = (fz * mx - fx * mz) / n2 + depth * ny;
    *rz = (fx * my - fy * mx) / n2 + depth * nz;
    *n_force = nf;
    *nx_out = nx;
    *ny_out = ny;
    *nz_out = nz;
    return 1;
}

EXPORT int tyre_forces(const tyre_forces_args_t *a) {
    if (!a || !a->ground) return AGN_NULL_ARRAY;
    const tyre_ground_t *g = a->ground;
    if (a->n < 0 || a->n > 64) return AGN_BAD_SIZE;
    if (!g->heights || (a->n > 0 && (!a->wheels || !a->shear || !a->normal || !a->out)))
        return AGN_NULL_ARRAY;
    if (g->nx < 2 || g->ny < 2) return AGN_BAD_SIZE;
    if (!(g->spacing > 0) || !(g->dt > 0) || !(g->shear_modulus > 0) ||
        !(g->contact_length > 0) || !(g->radius > 0))
        return AGN_BAD_VALUE;
    if (g->slices < 0 || g->slices > 64 || (g->slices > 0 && !(g->contact_width >= 0)))
        return AGN_BAD_VALUE;
    if (g->bearing && !(g->bear_cohesive >= 0 && g->bear_weight >= 0 && g->bear_k3 >= 0))
        return AGN_BAD_VALUE;
    if (g->bearing && !g->heights0) return AGN_NULL_ARRAY;
    double dt = g->dt, r = g->radius, big_k = g->shear_modulus, length = g->contact_length;
    for (int32_t i = 0; i < a->n; i++) {
        const double *s = a->wheels + 14 * i;
        const double *c = s, *q = s + 3, *v = s + 7, *w = s + 10;
        double *shear = a->shear + 3 * i, *out = a->out + 7 * i;
        /* the axle: the wheel frame's y axis */
        double qx = q[0], qy = q[1], qz = q[2], qw = q[3];
        double axle[3] = {2 * (qx * qy - qw * qz), 1 - 2 * (qx * qx + qz * qz),
                          2 * (qy * qz + qw * qx)};
        double ax = axle[0], ay = axle[1], az = axle[2];
        double n_force, nx, ny, nz, rx, ry, rz;
        int touching = g->slices > 0
                           ? tread(g, c, axle, v, w, &n_force, &nx, &ny, &nz, &rx, &ry, &rz)
                           : point(g, c, v, &n_force, &nx, &ny, &nz, &rx, &ry, &rz);
        if (!touching) { /* airborne: the patch's shear is gone */
            shear[0] = shear[1] = shear[2] = 0.0;
            a->normal[i] = 0.0;
            for (int k = 0; k < 7; k++) out[k] = 0.0;
            continue;
        }
        a->normal[i] = n_force;
        /* velocity of the tyre material at the contact point, tangential part = slip */
        double vx = v[0] + w[1] * rz - w[2] * ry;
        double vy = v[1] + w[2] * rx - w[0] * rz;
        double vz = v[2] + w[0] * ry - w[1] * rx;
        double vn = vx * nx + vy * ny + vz * nz;
        double sx = vx - vn * nx, sy = vy - vn * ny, sz = vz - vn * nz;
        double jx = shear[0], jy = shear[1], jz = shear[2];
        double u = fabs(s[13]) * r; /* tread speed through the patch */
        double kx, ky, kz;
        if (u > 1e-6) { /* exact step of dj/dt = s - (u/l) j */
            double decay = exp(-u * dt / length);
            double gain = length / u * (1.0 - decay);
            kx = jx * decay + sx * gain;
            ky = jy * decay + sy * gain;
            kz = jz * decay + sz * gain;
        } else {
            kx = jx + sx * dt;
            ky = jy + sy * dt;
            kz = jz + sz * dt;
        }
        double kn = kx * nx + ky * ny + kz * nz;
        kx = kx - kn * nx;
        ky = ky - kn * ny;
        kz = kz - kn * nz;
        double mag = sqrt(kx * kx + ky * ky + kz * kz);
        if (mag > SHEAR_CAP * big_k) {
            double f = SHEAR_CAP * big_k / mag;
            kx = kx * f;
            ky = ky * f;
            kz = kz * f;
            mag = SHEAR_CAP * big_k;
        }
        double tmax = g->friction * n_force;
        double elastic = mag > 0.0 ? tmax * (1.0 - exp(-mag / big_k)) / mag : 0.0;
        /* soil viscosity on the deflection rate: damps the stiction spring at rest, zero in
         * steady rolling */
        double damp = tmax / big_k * g->shear_damping / dt;
        double fx = -elastic * kx - damp * (kx - jx);
        double fy = -elastic * ky - damp * (ky - jy);
        double fz = -elastic * kz - damp * (kz - jz);
        double ft = sqrt(fx * fx + fy * fy + fz * fz);
        if (ft > tmax) {
            double f = tmax / ft;
            fx = fx * f;
            fy = fy * f;
            fz = fz * f;
        }
        shear[0] = kx;
        shear[1] = ky;
        shear[2] = kz;
        /* rolling direction = axle x normal */
        double ex = ay * nz - az * ny, ey = az * nx - ax * nz, ez = ax * ny - ay * nx;
        double en = sqrt(ex * ex + ey * ey + ez * ez);
        double travel = (v[0] * ex + v[1] * ey + v[2] * ez) / en;
        double rr = -g->rolling_resistance * n_force * py_max(-1.0, py_min(1.0, travel / RR_SPEED)) / en;
        out[0] = 1.0;
        out[1] = fx + rr * ex + n_force * nx;
        out[2] = fy + rr * ey + n_force * ny;
        out[3] = fz + rr * ez + n_force * nz;
        out[4] = c[0] + rx;
        out[5] = c[1] + ry;
        out[6] = c[2] + rz;
    }
    return AGN_OK;
}
