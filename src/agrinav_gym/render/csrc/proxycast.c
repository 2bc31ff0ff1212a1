/* The analytic proxy's ray cast in one compiled call: terrain and plant cylinders.
 *
 * The same geometry as the Embree path of ``DepthCamera`` (sensors/depth.py), intersected
 * exactly in double precision:
 *  - the terrain is the bilinear surface of the height grid (``Terrain.height_at``). Along a
 *    ray, height within one grid cell is a quadratic in t, so each crossing is a root of a
 *    quadratic - no bracketing triangles, no Newton step. Rays walk blocks of B x B cells and
 *    skip every block whose highest vertex lies below the ray's stretch over it, then walk
 *    the cells of the blocks they may touch (Amanatides-Woo steps on both levels).
 *  - the plants are vertical capped cylinders (``PlantField``), binned into a square grid by
 *    the squares around their discs; a ray walks that grid only up to its terrain hit and
 *    stops at the first cell that starts beyond its nearest cylinder hit.
 *
 * One foreign call per frame (ctypes) instead of one per 8-ray packet.
 */
#include "native.h"

#define HIT_NONE (-2)
#define HIT_TERRAIN (-1)

/* A 2-D walk over the cells of a grid (origin gx, gy; square cells of size cs; ni rows along
 * y, nj columns along x) that a ray's horizontal projection crosses from t0 on. */
typedef struct {
    int i, j, di, dj, ni, nj;
    double t, tx, ty, dtx, dty;
} walk_t;

static inline void walk_init(walk_t *w, double ox, double oy, double dx, double dy, double idx,
                      double idy, double t0, double gx, double gy, double cs, double ics, int ni,
                      int nj) {
    double px = ox + t0 * dx, py = oy + t0 * dy;
    double fj = (px - gx) * ics, fi = (py - gy) * ics;
    int j = (int)fj - (fj < 0), i = (int)fi - (fi < 0); /* floor for the cells near the grid */
    /* t0 lies on the grid's clipped stretch: rounding may put it one cell outside */
    if (j < 0) j = 0;
    if (j > nj - 1) j = nj - 1;
    if (i < 0) i = 0;
    if (i > ni - 1) i = ni - 1;
    w->i = i, w->j = j, w->ni = ni, w->nj = nj, w->t = t0;
    if (dx > 0) {
        w->dj = 1, w->dtx = cs * idx, w->tx = t0 + (gx + (j + 1) * cs - px) * idx;
    } else if (dx < 0) {
        w->dj = -1, w->dtx = -cs * idx, w->tx = t0 + (gx + j * cs - px) * idx;
    } else {
        w->dj = 0, w->dtx = INFINITY, w->tx = INFINITY;
    }
    if (dy > 0) {
        w->di = 1, w->dty = cs * idy, w->ty = t0 + (gy + (i + 1) * cs - py) * idy;
    } else if (dy < 0) {
        w->di = -1, w->dty = -cs * idy, w->ty = t0 + (gy + i * cs - py) * idy;
    } else {
        w->di = 0, w->dty = INFINITY, w->ty = INFINITY;
    }
    if (w->tx < t0) w->tx = t0;
    if (w->ty < t0) w->ty = t0;
}

/* where the walk leaves the current cell */
static inline double walk_exit(const walk_t *w) { return w->tx < w->ty ? w->tx : w->ty; }

/* to the next cell; 0 once the walk has left the grid */
static inline int walk_next(walk_t *w) {
    if (w->tx < w->ty) {
        w->t = w->tx, w->tx += w->dtx, w->j += w->dj;
        return w->j >= 0 && w->j < w->nj;
    }
    w->t = w->ty, w->ty += w->dty, w->i += w->di;
    return w->i >= 0 && w->i < w->ni;
}

/* [lo, hi] of t where the ray's horizontal projection is inside [x0, x1] x [y0, y1] */
static int clip_rect(double ox, double oy, double dx, double dy, double x0, double y0,
                     double x1, double y1, double *lo, double *hi) {
    double a = *lo, b = *hi;
    if (dx != 0) {
        double t1 = (x0 - ox) / dx, t2 = (x1 - ox) / dx;
        if (t1 > t2) { double s = t1; t1 = t2; t2 = s; }
        if (t1 > a) a = t1;
        if (t2 < b) b = t2;
    } else if (ox < x0 || ox > x1) {
        return 0;
    }
    if (dy != 0) {
        double t1 = (y0 - oy) / dy, t2 = (y1 - oy) / dy;
        if (t1 > t2) { double s = t1; t1 = t2; t2 = s; }
        if (t1 > a) a = t1;
        if (t2 < b) b = t2;
    } else if (oy < y0 || oy > y1) {
        return 0;
    }
    *lo = a, *hi = b;
    return a <= b;
}

/* smallest root of q0 + q1 s + q2 s^2 in [0, len] (s from the cell's entry), or -1 */
static double first_root(double q0, double q1, double q2, double len) {
    const double eps = 1e-12 * (len > 1 ? len : 1);
    if (q0 == 0) return 0;
    /* above the surface at both ends with no dip between (the usual cell a ray passes over):
     * no root, decided without the square root (the margins keep the exact path's roots at
     * the ends, which it accepts within eps) */
    double qe = q0 + (q1 + q2 * len) * len;
    if (q0 > 1e-9 && qe > 1e-9 && !(q2 > 0 && q1 < 0 && -q1 < 2 * q2 * len)) return -1;
    double scale = fabs(q1) * len;
    if (fabs(q2) * len * len <= 1e-14 * (scale > fabs(q0) ? scale : fabs(q0))) {
        if (q1 == 0) return -1;
        double s = -q0 / q1;
        return (s >= -eps && s <= len + eps) ? (s < 0 ? 0 : s) : -1;
    }
    double disc = q1 * q1 - 4 * q2 * q0;
    if (disc < 0) return -1;
    /* the cancellation-free pair of roots */
    double r = sqrt(disc);
    double q = -0.5 * (q1 + (q1 >= 0 ? r : -r));
    double s1 = q / q2, s2 = (q != 0) ? q0 / q : s1;
    if (s1 > s2) { double s = s1; s1 = s2; s2 = s; }
    if (s1 >= -eps && s1 <= len + eps) return s1 < 0 ? 0 : s1;
    if (s2 >= -eps && s2 <= len + eps) return s2 < 0 ? 0 : s2;
    return -1;
}

/* The ray's first crossing of the bilinear surface within [lo, hi], or INFINITY. ``hmax`` is
 * the highest vertex the ray can reach: a descending ray starts where it drops below it. */
static double terrain_hit(const double *o, const double *d, double idx, double idy, double lo,
                          double hi, const double *h, int nx, int ny, double x0, double y0,
                          double s, const double *bmax, int bsize, int bnx, int bny,
                          double hmax_all) {
    double x1 = x0 + (nx - 1) * s, y1 = y0 + (ny - 1) * s;
    if (nx < 2 || ny < 2) return INFINITY;
    if (d[2] < 0) {
        double t_in = (hmax_all - o[2]) / d[2];
        if (t_in > lo) lo = t_in;
    } else if (o[2] > hmax_all) {
        return INFINITY;
    }
    if (!(lo <= hi)) return INFINITY;
    if (!clip_rect(o[0], o[1], d[0], d[1], x0, y0, x1, y1, &lo, &hi)) return INFINITY;
    const double bs = bsize * s, is = 1.0 / s, ibs = 1.0 / bs;
    const double a = d[0] * is, b = d[1] * is;
    walk_t blk;
    walk_init(&blk, o[0], o[1], d[0], d[1], idx, idy, lo, x0, y0, bs, ibs, bny, bnx);
    for (;;) {
        double b0 = blk.t, b1 = walk_exit(&blk);
        if (b1 > hi) b1 = hi;
        double z0 = o[2] + b0 * d[2], z1 = o[2] + b1 * d[2];
        double zlow = z0 < z1 ? z0 : z1;
        if (zlow <= bmax[blk.i * bnx + blk.j]) {
            walk_t c;
            walk_init(&c, o[0], o[1], d[0], d[1], idx, idy, b0, x0, y0, s, is, ny - 1, nx - 1);
            for (;;) {
                double c0 = c.t, c1 = walk_exit(&c);
                if (c1 > b1) c1 = b1;
                const double *g = h + (size_t)c.i * nx + c.j;
                double h00 = g[0], h01 = g[1], h10 = g[nx], h11 = g[nx + 1];
                double hmax = MAX2(MAX2(h00, h01), MAX2(h10, h11));
                double za = o[2] + c0 * d[2], zb = o[2] + c1 * d[2];
                if ((za < zb ? za : zb) <= hmax && c1 >= c0) {
                    /* cell-local coordinates at the cell's entry; s runs along the ray */
                    double u0 = (o[0] + c0 * d[0] - (x0 + c.j * s)) * is;
                    double v0 = (o[1] + c0 * d[1] - (y0 + c.i * s)) * is;
                    double A = h01 - h00, B = h10 - h00, C = h00 - h01 - h10 + h11;
                    double q0 = za - (h00 + A * u0 + B * v0 + C * u0 * v0);
                    double q1 = d[2] - (A * a + B * b + C * (u0 * b + v0 * a));
                    double q2 = -C * a * b;
                    double r = first_root(q0, q1, q2, c1 - c0);
                    if (r >= 0) return c0 + r;
                }
                if (c1 >= b1 || !walk_next(&c)) break;
            }
        }
        if (b1 >= hi || !walk_next(&blk)) break;
    }
    return INFINITY;
}

/* Nearest hit in (0, tmax] of a vertical capped cylinder (axis at cx, cy; z in [z0, z1];
 * radius r), or INFINITY. A ray starting inside the cylinder meets the wall or cap it leaves
 * through (a camera among leaves sees them close by; Embree's capped cones do the same), one
 * starting in the disc below or above it meets a cap. ``ia``
 * and ``isa`` are 1/a and 1/sqrt(a) of the ray's ground track, a = dx^2 + dy^2. */
static inline double cylinder_hit(const double *o, const double *d, double ia, double isa,
                                  double cx, double cy, double z0, double z1, double r,
                                  double tmax) {
    double ox = o[0] - cx, oy = o[1] - cy;
    double a = d[0] * d[0] + d[1] * d[1];
    /* every hit (side or cap) lies within r of the axis on the ray's ground track: at most
     * r / sqrt(a) before the closest approach */
    double e = ox * d[1] - oy * d[0];
    if (e * e > r * r * a) return INFINITY;
    double b = ox * d[0] + oy * d[1]; /* half of the usual b */
    double tca = -b * ia, half = r * isa;
    if (tca - half > tmax) return INFINITY;
    /* over that stretch the ray's height must meet [z0, z1] */
    double za = o[2] + (tca - half) * d[2], zb = o[2] + (tca + half) * d[2];
    if ((za < zb ? zb : za) < z0 || (za < zb ? za : zb) > z1) return INFINITY;
    double c = ox * ox + oy * oy - r * r;
    if (c <= 0 && o[2] >= z0 && o[2] <= z1) { /* inside: the wall or cap it leaves through */
        double out = INFINITY;
        if (a > 0) {
            double sq = sqrt(b * b - a * c);
            out = b >= 0 ? -c / (b + sq) : (sq - b) * ia; /* the larger root, stable */
        }
        if (d[2] > 0) out = MIN2(out, (z1 - o[2]) / d[2]);
        if (d[2] < 0) out = MIN2(out, (z0 - o[2]) / d[2]);
        return out > 0 && out <= tmax ? out : INFINITY;
    }
    /* from within the disc below or above the cylinder only a cap is seen (tested last) */
    double best = INFINITY;
    if (a > 0 && c > 0) {
        double disc = b * b - a * c;
        if (disc >= 0 && b < 0) {
            double t = c / (-b + sqrt(disc)); /* the entry root, free of cancellation */
            double z = o[2] + t * d[2];
            if (t > 0 && t <= tmax && z >= z0 && z <= z1) return t;
        }
    }
    if (d[2] != 0) { /* top cap seen from above, bottom cap from below */
        double zc = d[2] < 0 ? z1 : z0;
        double t = (zc - o[2]) / d[2];
        if (t > 0 && t <= tmax) {
            double px = ox + t * d[0], py = oy + t * d[1];
            if (px * px + py * py <= r * r) best = t;
        }
    }
    return best;
}

/* Per ray k: the first hit (proxy_cast_args_t, native.h). Terrain: heights h (ny x nx, row i
 * at y0 + i s), bmax the highest vertex of each block of bsize x bsize cells (bny x bnx).
 * Plants: grid cell (i, j) of size gs from (gx, gy) lists cylinders items[start[c]:start[c+1]]
 * with c = i gnx + j, and cyl[5m..5m+4] is the record of cylinder items[m]. */
EXPORT int proxy_cast(const proxy_cast_args_t *a) {
    if (!a || !a->scene) return AGN_NULL_ARRAY;
    const proxy_scene_t *sc = a->scene;
    const int n = a->n;
    if (n < 0) return AGN_BAD_SIZE;
    if (n > 0 && (!a->dirs || !a->tlim || !a->t || !a->what)) return AGN_NULL_ARRAY;
    if (!sc->heights || !sc->block_max) return AGN_NULL_ARRAY;
    if (sc->nx < 2 || sc->ny < 2 || sc->block < 1 || sc->bnx < 1 || sc->bny < 1 || sc->gnx < 0 ||
        sc->gny < 0)
        return AGN_BAD_SIZE;
    if (!(sc->spacing > 0)) return AGN_BAD_VALUE;
    if (sc->gnx > 0 && sc->gny > 0) {
        if (!sc->cell_start || !sc->cell_items || !sc->cylinders) return AGN_NULL_ARRAY;
        if (!(sc->cell > 0)) return AGN_BAD_VALUE;
    }
    const double *o = a->origin, *d = a->dirs, *rot = a->rot, *tlim = a->tlim;
    const double ztop = sc->ztop;
    const double *h = sc->heights;
    const int nx = sc->nx, ny = sc->ny;
    const double x0 = sc->x0, y0 = sc->y0, s = sc->spacing;
    const double *bmax = sc->block_max;
    const int bsize = sc->block, bnx = sc->bnx, bny = sc->bny;
    const int gnx = sc->gnx, gny = sc->gny;
    const double gx = sc->gx, gy = sc->gy, gs = sc->cell;
    const int32_t *start = sc->cell_start, *items = sc->cell_items;
    const double *cyl = sc->cylinders;
    double *t_out = a->t;
    int32_t *what = a->what;
    /* the highest terrain vertex any ray can reach (blocks within the longest ray) */
    double reach = 0;
    for (int k = 0; k < n; k++) reach = tlim[k] > reach ? tlim[k] : reach;
    double hmax_all = -INFINITY;
    {
        double bs = bsize * s;
        int j0 = (int)floor((o[0] - reach - x0) / bs), j1 = (int)floor((o[0] + reach - x0) / bs);
        int i0 = (int)floor((o[1] - reach - y0) / bs), i1 = (int)floor((o[1] + reach - y0) / bs);
        if (j0 < 0) j0 = 0;
        if (i0 < 0) i0 = 0;
        if (j1 > bnx - 1) j1 = bnx - 1;
        if (i1 > bny - 1) i1 = bny - 1;
        for (int i = i0; i <= i1; i++)
            for (int j = j0; j <= j1; j++) hmax_all = MAX2(hmax_all, bmax[i * bnx + j]);
    }
    const double igs = 1.0 / gs;
    for (int k = 0; k < n; k++) {
        double dw[3];
        const double *dk = d + 3 * (size_t)k;
        if (rot) { /* body rays turned into the world here (no BLAS call per frame) */
            for (int i = 0; i < 3; i++)
                dw[i] = rot[3 * i] * dk[0] + rot[3 * i + 1] * dk[1] + rot[3 * i + 2] * dk[2];
            dk = dw;
        }
        double idx = dk[0] != 0 ? 1.0 / dk[0] : INFINITY, idy = dk[1] != 0 ? 1.0 / dk[1] : INFINITY;
        double a = dk[0] * dk[0] + dk[1] * dk[1];
        double ia = a > 0 ? 1.0 / a : INFINITY, isa = a > 0 ? 1.0 / sqrt(a) : INFINITY;
        double tmax = tlim[k];
        double best = terrain_hit(o, dk, idx, idy, 0.0, tmax, h, nx, ny, x0, y0, s, bmax, bsize,
                                  bnx, bny, hmax_all);
        int32_t id = isfinite(best) ? HIT_TERRAIN : HIT_NONE;
        double lo = 0.0, hi = isfinite(best) ? best : tmax;
        if (dk[2] > 0 && (ztop - o[2]) / dk[2] < hi) hi = (ztop - o[2]) / dk[2];
        if (gnx > 0 && gny > 0 &&
            clip_rect(o[0], o[1], dk[0], dk[1], gx, gy, gx + gnx * gs, gy + gny * gs, &lo, &hi)) {
            walk_t w;
            walk_init(&w, o[0], o[1], dk[0], dk[1], idx, idy, lo, gx, gy, gs, igs, gny, gnx);
            double lim = isfinite(best) ? best : tmax;
            for (;;) {
                if (w.t > lim) break;
                int c = w.i * gnx + w.j;
                for (int32_t m = start[c]; m < start[c + 1]; m++) {
                    int32_t p = items[m];
                    const double *q = cyl + 5 * (size_t)m;
                    double t = cylinder_hit(o, dk, ia, isa, q[0], q[1], q[2], q[3], q[4], lim);
                    if (t < lim || (t == lim && p < id)) {
                        lim = t, id = p;
                    }
                }
                if (walk_exit(&w) >= hi || !walk_next(&w)) break;
            }
            best = id == HIT_NONE ? INFINITY : lim;
        }
        t_out[k] = best;
        what[k] = id;
    }
    return AGN_OK;
}
