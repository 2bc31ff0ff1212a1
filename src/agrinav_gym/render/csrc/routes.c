/* A task's route per control step: the tracker's nearest segment (routes.Tracker), the route
 * observation's points (routes.RoutePath.lookup_points, observations.RouteObservation) and the
 * metrics' exact nearest segment (metrics.RouteProjector).
 *
 * The Python is the reference and the twin: every expression below is evaluated in the order
 * Python evaluates it (C99, no floating-point contraction), min and max as Python's builtins,
 * so the tracker, the lookups and the nearest segment give the same bits; tests compare them.
 * One difference: the observation's rotation into the robot frame is a multiply and an add
 * here where numpy's matmul may fuse them (OpenBLAS on FMA CPUs, not on others), a difference
 * in a double's last bit that the float32 observation keeps only when a value lies within it
 * of a float32 rounding boundary (tests compare the float32 values).
 */
#include "native.h"

static inline double py_min(double a, double b) { return b < a ? b : a; }
static inline double py_max(double a, double b) { return b > a ? b : a; }

/* Tracker._seg: squared distance, position along and side of segment k */
static void seg(const route_t *r, int32_t k, double x, double y, double *d2, double *u,
                double *cross) {
    double ax = r->xy[2 * k], ay = r->xy[2 * k + 1];
    double bx = r->xy[2 * k + 2], by = r->xy[2 * k + 3];
    double dx = bx - ax, dy = by - ay;
    double px = x - ax, py = y - ay;
    double L2 = dx * dx + dy * dy;
    *u = L2 <= 0 ? 0.0 : py_min(py_max((px * dx + py * dy) / L2, 0.0), 1.0);
    double ex = px - *u * dx, ey = py - *u * dy;
    *d2 = ex * ex + ey * ey;
    *cross = dx * py - dy * px;
}

static int check_route(const route_t *r) {
    if (!r->xy || !r->arc || !r->table || !r->tags) return AGN_NULL_ARRAY;
    if (r->n < 2 || r->m < 2) return AGN_BAD_SIZE;
    if (!(r->table_step > 0)) return AGN_BAD_VALUE;
    return AGN_OK;
}

EXPORT int route_track(route_track_args_t *a) {
    if (!a || !a->route) return AGN_NULL_ARRAY;
    const route_t *r = a->route;
    int st = check_route(r);
    if (st) return st;
    int32_t last = r->n - 2;
    int32_t k = a->k < last ? a->k : last;
    if (k < 0) return AGN_BAD_SIZE;
    double d2, u, cross;
    seg(r, k, a->x, a->y, &d2, &u, &cross);
    for (int step = 1; step >= -1; step -= 2) {
        for (int32_t j = k + step; 0 <= j && j <= last; j += step) {
            double cd2, cu, ccross;
            seg(r, j, a->x, a->y, &cd2, &cu, &ccross);
            if (cd2 > d2 + 1e-12) break;
            k = j, d2 = cd2, u = cu, cross = ccross;
        }
    }
    a->k = k;
    double len = r->arc[k + 1] - r->arc[k];
    a->cte = copysign(sqrt(d2), cross);
    a->s = r->arc[k] + u * len;
    return AGN_OK;
}

/* numpy's saturation of a float32 against float64 bounds: maximum, then minimum */
static float saturate(double v, double lo, double hi) {
    double f = (float)v;
    f = (f >= lo || isnan(f)) ? f : lo;
    f = (f <= hi || isnan(f)) ? f : hi;
    return (float)f;
}

EXPORT int route_points(const route_points_args_t *a) {
    if (!a || !a->route) return AGN_NULL_ARRAY;
    const route_t *r = a->route;
    int st = check_route(r);
    if (st) return st;
    if (a->n < 0) return AGN_BAD_SIZE;
    if (a->n > 0 && (!a->offsets || !a->out)) return AGN_NULL_ARRAY;
    int32_t last = r->m - 2;
    double end = (r->m - 1) * r->table_step;
    for (int32_t i = 0; i < a->n; i++) {
        double v = a->s + a->offsets[i], px, py;
        int tag;
        if (v > end) { /* past the end: the last segment goes on */
            double t = v - r->length;
            px = r->end[0] + t * r->direction[0];
            py = r->end[1] + t * r->direction[1];
            tag = r->furrow_last != 0;
        } else {
            double u = py_max(v, 0.0) / r->table_step;
            if (!(u < 2147483647.0)) return AGN_BAD_VALUE; /* NaN or beyond the table */
            int32_t j = (int32_t)u;
            if (j > last) j = last;
            double f = py_min(u - j, 1.0), g = 1.0 - f;
            const double *p0 = r->table + 2 * j;
            px = p0[0] * g + p0[2] * f;
            py = p0[1] * g + p0[3] * f;
            tag = r->tags[j] != 0;
        }
        double dx = px - a->x, dy = py - a->y; /* world -> robot frame */
        float *o = a->out + 3 * i;
        o[0] = saturate(dx * a->cos_yaw + dy * a->sin_yaw, a->lo, a->hi);
        o[1] = saturate(dx * -a->sin_yaw + dy * a->cos_yaw, a->lo, a->hi);
        o[2] = tag ? 1.0f : 0.0f;
    }
    return AGN_OK;
}

/* the distance and position along segment k of (x, y): RouteProjector.project's loop body */
static double seg_distance(const route_grid_t *g, int32_t k, double x, double y, double *u) {
    const double *s = g->segs + 5 * (size_t)k;
    double ax = s[0], ay = s[1], dx = s[2], dy = s[3], L2 = s[4];
    *u = L2 <= 0 ? 0.0 : py_min(py_max(((x - ax) * dx + (y - ay) * dy) / L2, 0.0), 1.0);
    double ex = x - ax - *u * dx, ey = y - ay - *u * dy;
    return sqrt(ex * ex + ey * ey);
}

/* vertex v's segments (v - 1 and v) as candidates: the nearer kept, the lower on a tie */
static void consider(const route_grid_t *g, int32_t v, double x, double y, double *best_d,
                     int32_t *best_k, double *best_u) {
    for (int32_t k = v - 1; k <= v; k++) {
        if (k < 0 || k >= g->n - 1) continue;
        double u, d = seg_distance(g, k, x, y, &u);
        if (d < *best_d || (d == *best_d && k < *best_k)) *best_d = d, *best_k = k, *best_u = u;
    }
}

EXPORT int route_nearest(route_nearest_args_t *a) {
    if (!a || !a->grid) return AGN_NULL_ARRAY;
    const route_grid_t *g = a->grid;
    if (!g->segs || !g->seg_len || !g->arc || !g->cell_start || !g->cell_items || !g->xy)
        return AGN_NULL_ARRAY;
    if (g->n < 2 || g->ncx < 1 || g->ncy < 1) return AGN_BAD_SIZE;
    if (!(g->cell > 0) || !(a->bound >= 0)) return AGN_BAD_VALUE;
    double x = a->x, y = a->y, c = g->cell;
    double r = a->bound + g->half + 1e-9, r2 = r * r;
    double best_d = INFINITY, best_u = 0.0;
    int32_t best_k = 0;
    /* the cells the disc's box covers, clipped to the grid (cells beyond hold no vertex) */
    double fi0 = floor((x - r) / c) - g->cx0, fi1 = floor((x + r) / c) - g->cx0;
    double fj0 = floor((y - r) / c) - g->cy0, fj1 = floor((y + r) / c) - g->cy0;
    if (fi1 >= 0 && fj1 >= 0 && fi0 < g->ncx && fj0 < g->ncy) {
        int32_t i0 = fi0 < 0 ? 0 : (int32_t)fi0, i1 = fi1 >= g->ncx ? g->ncx - 1 : (int32_t)fi1;
        int32_t j0 = fj0 < 0 ? 0 : (int32_t)fj0, j1 = fj1 >= g->ncy ? g->ncy - 1 : (int32_t)fj1;
        for (int32_t j = j0; j <= j1; j++)
            for (int32_t i = i0; i <= i1; i++) {
                int32_t cell = j * g->ncx + i;
                for (int32_t t = g->cell_start[cell]; t < g->cell_start[cell + 1]; t++) {
                    int32_t v = g->cell_items[t];
                    double ex = g->xy[2 * v] - x, ey = g->xy[2 * v + 1] - y;
                    if (ex * ex + ey * ey <= r2) consider(g, v, x, y, &best_d, &best_k, &best_u);
                }
            }
    }
    a->d = best_d;
    a->k = best_k;
    a->s = best_d == INFINITY ? 0.0 : g->arc[best_k] + best_u * g->seg_len[best_k];
    return AGN_OK;
}
