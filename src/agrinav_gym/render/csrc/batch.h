/* Batched per-pixel loops for the auto-vectoriser, compiled for AVX2 (four doubles, gathers)
 * and chosen at run time where the CPU has it, each over one row: a visibility buffer's
 * resolve, the first Newton step onto the bilinear terrain, the stereo pair's epipolar test,
 * the soil's and the untextured plants' colour. Elsewhere (and with AGRINAV_AVX2=0) frame.c
 * runs its pixel-by-pixel twins: batched without gathers or a rounding floor these loops were
 * slower than scalar code (measured). Both call the same inline pieces (cam_ray_f, grid_cell,
 * lambert, haze, to_u8, tiled, stereo_row); -std=c99 keeps floating-point contraction off and the rest
 * of each loop repeats its twin's operations in order, so the two give bit-identical images
 * (tested).
 */
#ifndef AGRINAV_BATCH_H
#define AGRINAV_BATCH_H

#include <stdlib.h>

#include "native.h"

/* what the soil's colour needs besides the ray (shading.py; the grid as in geom_t) */
typedef struct {
    cam_t cam;             /* origin and rotation rows */
    double org[2];         /* scene origin: the texture is in world coordinates */
    double itx, itx7;      /* 1 / texel of the two octaves */
    double ca, sa;         /* the second octave's turn */
    double soil_n, inv_n;  /* texture size (a power of two) and its inverse */
    const float *soil;     /* the texture in 8 x 8 tiles (raster_view.tiled_texture) */
    double gx0, gy0, inv_s;
    int nx, ny;
    const double *heights;
    double light[3], ambient, i3f, horizon[3], rgb[3];
} soil_par_t;

/* what the terrain refinement needs (geom_t's grid, cam_t's ray) */
typedef struct {
    cam_t cam;
    double gx0, gy0, inv_s;
    int nx, ny;
    const double *heights;
} step_par_t;

/* what the plants' colour needs besides the ray (frame.c's shade_view) */
typedef struct {
    cam_t cam;
    const float *face_normal; /* (F, 3) over every prototype's faces */
    const float *xfm;         /* (slots, 12) */
    double light[3], ambient, i3f, horizon[3];
} plant_par_t;

#if defined(__GNUC__) || defined(__clang__)
#define SHARED static inline __attribute__((always_inline, unused))
#else
#define SHARED static inline
#endif
/* The helpers below are shared by the pixel-by-pixel code (frame.c) and the AVX2 loops, which
 * inline them: the same operations either way. */

/* two-sided Lambert: albedo times ambient + diffuse sun, the unit normal turned towards the
 * viewer (only its sign and the sun's cosine matter; float is plenty for shading) */
SHARED void lambert(const double *alb, double nx, double ny, double nz, const double *d,
                    const double *light, double ambient, double *out) {
    float len = sqrtf((float)(nx * nx + ny * ny + nz * nz));
    double il = 1.0f / (len < 1e-12f ? 1e-12f : len);
    double side = -(nx * d[0] + ny * d[1] + nz * d[2]);
    double flip = side < 0 ? -il : il;
    double cs = flip * (nx * light[0] + ny * light[1] + nz * light[2]);
    cs = cs < 0 ? 0.0 : cs;
    cs = cs > 1 ? 1.0 : cs;
    double lit = ambient + (1.0 - ambient) * cs;
    for (int i = 0; i < 3; i++) out[i] = alb[i] * lit;
}

/* aerial perspective: towards the horizon colour over 3 ``far`` (inv3far = 1 / (3 far)) */
SHARED void haze(double *rgb, double dist, double inv3far, const double *horizon) {
    double a = dist * inv3far;
    a = a < 0 ? 0.0 : a;
    a = a > 0.6 ? 0.6 : a;
    for (int i = 0; i < 3; i++) rgb[i] = rgb[i] * (1 - a) + horizon[i] * a;
}

SHARED uint8_t to_u8(double x) {
    x = x > 0 ? x : 0.0; /* NaN: 0 */
    x = x > 1 ? 1.0 : x;
    return (uint8_t)(int)(x * 255.0 + 0.5);
}

/* texel (row j, column i) of an n x n texture stored in 8 x 8 tiles
 * (raster_view.tiled_texture): a pixel's neighbours land in the same few cache lines */
SHARED int tiled(int j, int i, int n) {
    return (((j >> 3) * (n >> 3) + (i >> 3)) << 6) + ((j & 7) << 3) + (i & 7);
}

/* stereo_invalid's first test over one row (inverse depths inv, the best occluder ``after``
 * of this row and of the rows above and below, this row's where there is none): flag[u] = 1
 * where the point's match falls left of the right imager (d455.outside_right_imager: invalid),
 * 2 where something may hide it (d455.shadow_candidates: the exact test follows), 0 where it
 * is seen. Inlined into stereo_row_avx2 as well: the same operations either way. */
SHARED void stereo_row(int w, const double *restrict inv, const double *restrict after,
                              const double *restrict above, const double *restrict below,
                              double fb, double ifb, double inear, uint8_t *restrict flag) {
    for (int u = 0; u < w; u++) {
        double iv = inv[u];
        int valid = iv > 0;
        int outside = u - fb * iv < -0.5;
        double near = after[u];
        near = above[u] > near ? above[u] : near;
        near = below[u] > near ? below[u] : near;
        int occluder = near >= iv - (u + 0.5) * ifb;
        int leaves = iv + (w - 1 - u) * ifb < inear;
        int f = outside ? 1 : (occluder | leaves) << 1;
        flag[u] = (uint8_t)(valid ? f : 0);
    }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(AGRINAV_NO_AVX2)
#define AGRINAV_AVX2 1
#define TARGET_AVX2 __attribute__((target("avx2")))

static inline int cpu_has_avx2(void) {
    const char *off = getenv("AGRINAV_AVX2");
    if (off && off[0] == '0') return 0;
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2");
}

/* floor(x) mod n (n a power of two) as an int, exact for every double (no 64-bit conversion,
 * which AVX2 lacks): the texel of frame.c's ``wrap`` */
TARGET_AVX2 static inline int wrap_texel(double x, double n, double inv_n) {
    double f = floor(x);
    return (int)(f - n * floor(f * inv_n));
}

/* The soil's 8-bit colour at n pixels of one row (packed by the caller: column ray terms a,
 * cosines fwd, ray lengths t; the row term b): shade_view's soil branch, operation for
 * operation. */
TARGET_AVX2 static void soil_avx2(const soil_par_t *P, int n, const double *restrict a, double b,
                                    const double *restrict fwd, const double *restrict t,
                                    uint8_t *restrict o0, uint8_t *restrict o1,
                                    uint8_t *restrict o2) {
    /* locals, not P->: byte stores may alias anything, which would stop the vectoriser */
    const cam_t cam = P->cam;
    const double orx = P->org[0], ory = P->org[1];
    const double itx = P->itx, itx7 = P->itx7, ca = P->ca, sa = P->sa;
    const double sn = P->soil_n, isn = P->inv_n, gx0 = P->gx0, gy0 = P->gy0, is = P->inv_s;
    const double amb = P->ambient, i3f = P->i3f;
    const double light[3] = {P->light[0], P->light[1], P->light[2]};
    const double s0 = P->rgb[0], s1 = P->rgb[1], s2 = P->rgb[2];
    const double horizon[3] = {P->horizon[0], P->horizon[1], P->horizon[2]};
    const int nx = P->nx, ny = P->ny, tn = (int)P->soil_n;
    const float *restrict soil = P->soil;
    const double *restrict hg = P->heights;
    for (int i = 0; i < n; i++) {
        double d[3], tk = t[i];
        cam_ray_f(&cam, a[i], b, fwd[i], d);
        double p0 = cam.o[0] + tk * d[0], p1 = cam.o[1] + tk * d[1];
        double x = p0 + orx, yw = p1 + ory;
        int i1 = wrap_texel(x * itx, sn, isn);
        int j1 = wrap_texel(yw * itx, sn, isn);
        double xr = ca * x - sa * yw, yr = sa * x + ca * yw;
        int i2 = wrap_texel(xr * itx7, sn, isn);
        int j2 = wrap_texel(yr * itx7, sn, isn);
        float m = soil[tiled(j1, i1, tn)] * soil[tiled(j2, i2, tn)];
        /* the bilinear surface's slope, clamped as ``bilinear`` clamps */
        double fu, fv;
        int q = grid_cell((p0 - gx0) * is, (p1 - gy0) * is, nx, ny, &fu, &fv);
        double h00 = hg[q], h01 = hg[q + 1], h10 = hg[q + nx], h11 = hg[q + nx + 1];
        double ea = h01 - h00, eb = h11 - h10;
        double z0 = h00 + ea * fu, z1 = h10 + eb * fu;
        double hx = (ea + (eb - ea) * fv) * is, hy = (z1 - z0) * is;
        double alb[3] = {s0 * m, s1 * m, s2 * m}, out[3];
        lambert(alb, -hx, -hy, 1.0, d, light, amb, out);
        haze(out, tk, i3f, horizon);
        o0[i] = to_u8(out[0]), o1[i] = to_u8(out[1]), o2[i] = to_u8(out[2]);
    }
}

/* refine()'s inline first Newton step at n pixels of one row (packed: column ray terms a,
 * cosines fwd, ray lengths tin; the row term b): the refined length in tout[i], and ok[i] = 0
 * where refine() would go on to refine_loop (outside the grid, a flat derivative, a long step
 * or one that leaves the cell), which the caller then runs from tin[i]. */
TARGET_AVX2 static void step_avx2(const step_par_t *P, int n, const double *restrict a, double b,
                                    const double *restrict fwd, const double *restrict tin,
                                    double *restrict tout, uint8_t *restrict ok) {
    const cam_t cam = P->cam;
    const double gx0 = P->gx0, gy0 = P->gy0, is = P->inv_s;
    const int nx = P->nx, ny = P->ny;
    const double umax = nx - 1.0, vmax = ny - 1.0;
    const double *restrict hg = P->heights;
    for (int i = 0; i < n; i++) {
        double d[3], tk = tin[i];
        cam_ray_f(&cam, a[i], b, fwd[i], d);
        double px = cam.o[0] + tk * d[0], py = cam.o[1] + tk * d[1], pz = cam.o[2] + tk * d[2];
        double gu = (px - gx0) * is, gv = (py - gy0) * is;
        int inside = (gu >= 0.0) & (gv >= 0.0) & (gu < umax) & (gv < vmax);
        double fu, fv; /* outside: the nearest cell (the result is discarded) */
        int q = grid_cell(gu, gv, nx, ny, &fu, &fv);
        double h00 = hg[q], h01 = hg[q + 1], h10 = hg[q + nx], h11 = hg[q + nx + 1];
        double ea = h01 - h00, eb = h11 - h10;
        double z0 = h00 + ea * fu, z1 = h10 + eb * fu, dz = z1 - z0;
        double fz = pz - (z0 + dz * fv);
        double df = d[2] - ((ea + (eb - ea) * fv) * d[0] + dz * d[1]) * is;
        int flat = !(fabs(df) > 1e-9);
        double step = fz / (flat ? 1.0 : df);
        int small = !((step > 0.05) | (step < -0.05));
        double fu1 = fu - step * d[0] * is, fv1 = fv - step * d[1] * is;
        int stays = (fu1 >= 0.0) & (fu1 < 1.0) & (fv1 >= 0.0) & (fv1 < 1.0);
        int converged = fabs(fz) < 1e-6;
        tout[i] = converged ? tk : tk - step;
        ok[i] = (uint8_t)(inside & (converged | ((!flat) & small & stays)));
    }
}

/* An untextured plant's 8-bit colour at n pixels of one row (packed: face colour c0..c2, face
 * fl[i] whose normal slot sl[i]'s transform turns, column ray terms a, cosines fwd, ray
 * lengths t; the row term b): two-sided Lambert and haze, shade_view's plant branch,
 * operation for operation. */
TARGET_AVX2 static void plant_avx2(const plant_par_t *P, int n, const int32_t *restrict fl,
                                     const int32_t *restrict sl, const uint8_t *restrict c0,
                                     const uint8_t *restrict c1, const uint8_t *restrict c2,
                                     const double *restrict a, double b,
                                     const double *restrict fwd, const double *restrict t,
                                     uint8_t *restrict o0, uint8_t *restrict o1,
                                     uint8_t *restrict o2) {
    const cam_t cam = P->cam;
    const double amb = P->ambient, i3f = P->i3f;
    const double light[3] = {P->light[0], P->light[1], P->light[2]};
    const double horizon[3] = {P->horizon[0], P->horizon[1], P->horizon[2]};
    const float *restrict fn = P->face_normal, *restrict xf = P->xfm;
    for (int i = 0; i < n; i++) {
        int q = 3 * fl[i], s = 12 * sl[i];
        double d[3], tk = t[i];
        cam_ray_f(&cam, a[i], b, fwd[i], d);
        double m0 = fn[q], m1 = fn[q + 1], m2 = fn[q + 2];
        double nx = (double)xf[s] * m0 + (double)xf[s + 1] * m1 + (double)xf[s + 2] * m2;
        double ny = (double)xf[s + 4] * m0 + (double)xf[s + 5] * m1 + (double)xf[s + 6] * m2;
        double nz = (double)xf[s + 8] * m0 + (double)xf[s + 9] * m1 + (double)xf[s + 10] * m2;
        double alb[3] = {c0[i] / 255.0, c1[i] / 255.0, c2[i] / 255.0}, out[3];
        lambert(alb, nx, ny, nz, d, light, amb, out);
        haze(out, tk, i3f, horizon);
        o0[i] = to_u8(out[0]), o1[i] = to_u8(out[1]), o2[i] = to_u8(out[2]);
    }
}

/* resolve_view's pixel loop over one row of a visibility buffer, before refinement and the
 * robot: ray length (inf: none), class (lab32: each prototype's, widened), plant id, prototype
 * and triangle, operation for operation as resolve_view's pixel-by-pixel code */
TARGET_AVX2 static void resolve_row_avx2(int w, const int32_t *restrict inst,
                                           const float *restrict iz, const double *restrict fwd,
                                           const int32_t *restrict vprim,
                                           const int32_t *restrict slot_proto,
                                           const int32_t *restrict slot_plant,
                                           const int32_t *restrict lab32, double *restrict t,
                                           uint8_t *restrict label, int32_t *restrict plant,
                                           int32_t *restrict proto, int32_t *restrict prim) {
    for (int u = 0; u < w; u++) {
        int32_t s = inst[u];
        int has = s != VB_NONE, obj = s >= 0;
        int32_t si = obj ? s : 0; /* slot 0 exists (the tables hold at least one) */
        double tt = 1.0 / ((double)iz[u] * fwd[u]);
        int32_t pr = slot_proto[si], pl = slot_plant[si]; /* read unconditionally: gathers */
        int32_t lb = lab32[pr];
        t[u] = has ? tt : INFINITY;
        proto[u] = obj ? pr : -1;
        plant[u] = obj ? pl : -1;
        label[u] = (uint8_t)(obj ? lb : s == VB_TERRAIN ? CLS_SOIL : CLS_OTHER);
        prim[u] = has ? vprim[u] : -1;
    }
}

/* stereo_invalid's first test over one row, the same body for both builds */
TARGET_AVX2 static void stereo_row_avx2(int w, const double *restrict inv,
                                          const double *restrict after,
                                          const double *restrict above,
                                          const double *restrict below, double fb, double ifb,
                                          double inear, uint8_t *restrict flag) {
    stereo_row(w, inv, after, above, below, fb, ifb, inear, flag);
}

#else
static inline int cpu_has_avx2(void) { return 0; }
#endif /* AGRINAV_AVX2 */

#endif
