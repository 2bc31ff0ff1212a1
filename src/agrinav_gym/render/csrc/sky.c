/* The GNSS sky model's foliage loss (sensors/fixmode.py, SkyModel.attenuation): every
 * (azimuth, elevation) cell's ray from the antenna through the plants' canopy cylinders.
 *
 * The numpy method is the reference and the twin. Each expression is evaluated as numpy
 * evaluates it element by element (C99, no floating-point contraction), the plants in reach
 * are found as cKDTree finds them (a squared distance within the reach's square; here from a
 * grid of cells) and summed in index order, as it returns them: with the uniform foliage the
 * loss is the same to the bit. With the stalk profile u^3 is libm's pow, which numpy's power
 * (its own SIMD loops) matches only to a unit in the last place; the sky fractions the
 * thresholds make of the loss are the same unless a cell's loss lies within that of a
 * threshold (tests compare both). A plant a ray misses (half chord 0) or that lies behind the
 * antenna adds exactly 0 in the twin: skipped here, which is the saving.
 */
#include <stdlib.h>

#include "native.h"

static inline double np_max(double a, double b) { return a >= b || isnan(a) ? a : b; }
static inline double np_min(double a, double b) { return a <= b || isnan(a) ? a : b; }

/* the lowest set bit's position in a non-zero word */
static inline int lowest_bit(uint64_t w) {
#if defined(__GNUC__) || defined(__clang__)
    return __builtin_ctzll(w);
#else
    int b = 0;
    while (!(w & 1)) w >>= 1, b++;
    return b;
#endif
}

/* idx[0 .. m) (distinct, within [lo, hi]) in ascending order, through a bitmap of the span:
 * O(m + span / 64), where a comparison sort cost as much as the ray arithmetic */
static int sort_indices(int32_t *idx, int32_t m, int32_t lo, int32_t hi) {
    size_t words = ((size_t)(hi - lo) >> 6) + 1;
    uint64_t *bits = calloc(words, sizeof *bits);
    if (!bits) return AGN_NO_MEMORY;
    for (int32_t q = 0; q < m; q++) {
        uint32_t off = (uint32_t)(idx[q] - lo);
        bits[off >> 6] |= (uint64_t)1 << (off & 63);
    }
    int32_t q = 0;
    for (size_t w = 0; w < words; w++)
        for (uint64_t word = bits[w]; word; word &= word - 1)
            idx[q++] = lo + (int32_t)(w << 6) + lowest_bit(word);
    free(bits);
    return AGN_OK;
}

/* the grid's cell range [lo, hi] covering [v - r, v + r] along one axis, clamped */
static void cell_range(double v, double r, double cell, int32_t c0, int32_t nc, int32_t *lo,
                       int32_t *hi) {
    double a = floor((v - r) / cell) - c0, b = floor((v + r) / cell) - c0;
    *lo = a < 0 ? 0 : (a > nc - 1 ? nc : (int32_t)a);
    *hi = b < 0 ? -1 : (b > nc - 1 ? nc - 1 : (int32_t)b);
}

/* The plants within ``r`` of (x, y) horizontally, as scipy's cKDTree.query_ball_point finds
 * them (squared distance <= r^2) and returns them for one point (in index order); *found is
 * their count, *idx a buffer the caller frees (NULL when none). */
static int in_reach(const sky_t *s, double x, double y, double r, int32_t **idx,
                    int32_t *found) {
    int32_t i0, i1, j0, j1;
    *idx = NULL, *found = 0;
    cell_range(x, r, s->cell, s->cx0, s->ncx, &i0, &i1);
    cell_range(y, r, s->cell, s->cy0, s->ncy, &j0, &j1);
    if (i0 > i1 || j0 > j1) return AGN_OK;
    int64_t most = 0;
    for (int32_t j = j0; j <= j1; j++)
        most += s->cell_start[j * s->ncx + i1 + 1] - s->cell_start[j * s->ncx + i0];
    if (most == 0) return AGN_OK;
    int32_t *out = malloc((size_t)most * sizeof *out);
    if (!out) return AGN_NO_MEMORY;
    double r2 = r * r;
    int32_t m = 0, lo = s->n, hi = -1;
    for (int32_t j = j0; j <= j1; j++) {
        for (int32_t c = s->cell_start[j * s->ncx + i0]; c < s->cell_start[j * s->ncx + i1 + 1];
             c++) {
            int32_t i = s->cell_items[c];
            if (i < 0 || i >= s->n) {
                free(out);
                return AGN_BAD_SIZE;
            }
            double dx = s->xy[2 * i] - x, dy = s->xy[2 * i + 1] - y;
            if (dx * dx + dy * dy <= r2) {
                out[m++] = i;
                lo = i < lo ? i : lo, hi = i > hi ? i : hi;
            }
        }
    }
    int st = m > 1 ? sort_indices(out, m, lo, hi) : AGN_OK;
    if (st) {
        free(out);
        return st;
    }
    *idx = out, *found = m;
    return AGN_OK;
}

EXPORT int sky_attenuation(sky_attenuation_args_t *a) {
    if (!a || !a->sky) return AGN_NULL_ARRAY;
    const sky_t *s = a->sky;
    if (!s->xy || !s->radius || !s->bottom || !s->top || !s->share || !s->cos_az ||
        !s->sin_az || !s->tan_el || !s->sec_el || !a->out || !s->cell_start || !s->cell_items)
        return AGN_NULL_ARRAY;
    if (s->n < 0 || s->n_az < 1 || s->n_el < 1 || s->ncx < 1 || s->ncy < 1) return AGN_BAD_SIZE;
    if (!(s->cell > 0) || !(a->reach >= 0) || !isfinite(a->reach) || !isfinite(a->x) ||
        !isfinite(a->y) || !isfinite(a->z))
        return AGN_BAD_VALUE;
    const int32_t n_az = s->n_az, n_el = s->n_el, cells = n_az * n_el;
    double *out = a->out;
    for (int32_t c = 0; c < cells; c++) out[c] = 0.0;
    const double ax = a->x, ay = a->y, az = a->z;
    double *s_bot = malloc(2 * (size_t)n_el * sizeof *s_bot), *s_top = s_bot + n_el;
    if (!s_bot) return AGN_NO_MEMORY;
    int32_t *idx, found;
    int st = in_reach(s, ax, ay, a->reach, &idx, &found);
    a->n_found = found;
    if (st) {
        free(s_bot);
        return st;
    }
    for (int32_t q = 0; q < found; q++) {
        int32_t i = idx[q];
        if (!(s->top[i] > az)) continue; /* the twin drops plants not above the antenna */
        double dx = s->xy[2 * i] - ax, dy = s->xy[2 * i + 1] - ay;
        double rho = s->radius[i], share = s->share[i];
        double bot = np_max(s->bottom[i] - az, 0.0), top = s->top[i] - az;
        double rho2 = rho * rho;
        /* where each elevation's ray is within the foliage's height band (the same for every
         * azimuth): computed once a plant */
        for (int32_t k = 0; k < n_el; k++)
            s_bot[k] = bot / s->tan_el[k], s_top[k] = top / s->tan_el[k];
        for (int32_t j = 0; j < n_az; j++) {
            double t = dx * s->cos_az[j] + dy * s->sin_az[j];
            double x = -dx * s->sin_az[j] + dy * s->cos_az[j];
            double chord2 = rho * rho - x * x;
            if (!(chord2 > 0.0)) continue; /* missed (half chord 0): 0 in every cell */
            double half = sqrt(chord2);
            double hi = t + half;
            if (half == 0.0 || !(hi > 0.0)) continue; /* behind: 0 in every cell */
            double lo = np_max(t - half, 0.0);
            double w = 1.0 - (x * x) / rho2;
            for (int32_t k = 0; k < n_el; k++) {
                double lo_k = np_max(lo, s_bot[k]), hi_k = np_min(hi, s_top[k]);
                double length;
                if (!s->stalk) {
                    length = np_max(hi_k - lo_k, 0.0);
                } else if (hi_k > lo_k) {
                    double u1 = lo_k - t, u2 = hi_k - t;
                    length = 2.0 * (w * (u2 - u1) -
                                    (pow(u2, 3.0) - pow(u1, 3.0)) / (3.0 * rho2));
                    length = np_max(length, 0.0);
                } else {
                    length = 0.0;
                }
                out[j * n_el + k] += share * length;
            }
        }
    }
    free(idx);
    free(s_bot);
    for (int32_t j = 0; j < n_az; j++)
        for (int32_t k = 0; k < n_el; k++) {
            double path = out[j * n_el + k] * s->sec_el[k];
            out[j * n_el + k] = 0.0 + s->db_per_m * path;
        }
    return AGN_OK;
}
