/* Batched per-pixel loops for the auto-vectoriser, compiled for AVX2 (four doubles, gathers)
 * and chosen at run time where the CPU has it, each over one row: a visibility buffer's
 * resolve, the first Newton step onto the bilinear terrain, the stereo pair's epipolar test,
 * the soil's and the untextured plants' colour. Elsewhere (and with AGRINAV_AVX2=0) frame.c
 * runs its pixel-by-pixel twins: batched without gathers or a rounding floor these loops were
 * slower than scalar code (measured).
 * -std=c99 keeps floating-point contraction off and each loop repeats its twin's operations
 * in order, so the two give bit-identical images (tested).
 */
#ifndef AGRINAV_BATCH_H
#define AGRINAV_BATCH_H

#include <stdlib.h>

#include "native.h"

/* what the soil's colour needs besides the ray (shading.py; the grid as in geom_t) */
typedef struct {
    double o[3], r[9];     /* camera origin and rotation rows (cam_t) */
    double org[2];         /* scene origin: the texture is in world coordinates */
    double itx, itx7;      /* 1 / texel of the two octaves */
    double ca, sa;         /* the second octave's turn */
    double soil_n, inv_n;  /* texture size (a power of two) and its inverse */
    const float *soil;     /* the texture in 8 x 8 tiles (raster_view.tiled_texture) */
    double gx0, gy0, inv_s, umax, vmax;
    int nx, jmax, imax;    /* grid columns, the last cell's column and row */
    const double *heights;
    double light[3], ambient, i3f, horizon[3], rgb[3];
} soil_par_t;

/* what the terrain refinement needs (geom_t's grid, cam_t's ray) */
typedef struct {
    double o[3], r[9];
    double gx0, gy0, inv_s, umax, vmax; /* umax = nx - 1, vmax = ny - 1 */
    int nx;
    const double *heights;
} step_par_t;

/* what the plants' colour needs besides the ray (frame.c's shade_view) */
typedef struct {
    double r[9];
    const float *face_normal; /* (F, 3) over every prototype's faces */
    const float *xfm;         /* (slots, 12) */
    double light[3], ambient, i3f, horizon[3];
} plant_par_t;

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

TARGET_AVX2 static inline int tiled32(int j, int i, int n) {
    return ((((j >> 3) * (n >> 3) + (i >> 3)) << 6) + ((j & 7) << 3) + (i & 7));
}

TARGET_AVX2 static inline uint8_t u8_of(double x) {
    x = x > 0 ? x : 0.0; /* NaN: 0 */
    x = x > 1 ? 1.0 : x;
    return (uint8_t)(int)(x * 255.0 + 0.5);
}

/* The soil's 8-bit colour at n pixels of one row (packed by the caller: column ray terms a,
 * cosines fwd, ray lengths t; the row term b): shade_view's soil branch, operation for
 * operation. */
TARGET_AVX2 static void soil_avx2(const soil_par_t *P, int n, const double *restrict a, double b,
                                    const double *restrict fwd, const double *restrict t,
                                    uint8_t *restrict o0, uint8_t *restrict o1,
                                    uint8_t *restrict o2) {
    /* locals, not P->: byte stores may alias anything, which would stop the vectoriser */
    const double r0 = P->r[0], r1 = P->r[1], r3 = P->r[3], r4 = P->r[4], r6 = P->r[6],
                 r7 = P->r[7], r2 = P->r[2], r5 = P->r[5], r8 = P->r[8];
    const double ox = P->o[0], oy = P->o[1], orx = P->org[0], ory = P->org[1];
    const double itx = P->itx, itx7 = P->itx7, ca = P->ca, sa = P->sa;
    const double sn = P->soil_n, isn = P->inv_n, gx0 = P->gx0, gy0 = P->gy0, is = P->inv_s;
    const double umax = P->umax, vmax = P->vmax, amb = P->ambient, i3f = P->i3f;
    const double L0 = P->light[0], L1 = P->light[1], L2 = P->light[2];
    const double s0 = P->rgb[0], s1 = P->rgb[1], s2 = P->rgb[2];
    const double H0 = P->horizon[0], H1 = P->horizon[1], H2 = P->horizon[2];
    const int nx = P->nx, jmax = P->jmax, imax = P->imax, tn = (int)P->soil_n;
    const float *restrict soil = P->soil;
    const double *restrict hg = P->heights;
    for (int i = 0; i < n; i++) {
        double f = fwd[i], y = a[i] * f, z = b * f, tk = t[i];
        double d0 = r0 * f + r3 * y + r6 * z;
        double d1 = r1 * f + r4 * y + r7 * z;
        double d2 = r2 * f + r5 * y + r8 * z;
        double p0 = ox + tk * d0, p1 = oy + tk * d1;
        double x = p0 + orx, yw = p1 + ory;
        int i1 = wrap_texel(x * itx, sn, isn);
        int j1 = wrap_texel(yw * itx, sn, isn);
        double xr = ca * x - sa * yw, yr = sa * x + ca * yw;
        int i2 = wrap_texel(xr * itx7, sn, isn);
        int j2 = wrap_texel(yr * itx7, sn, isn);
        float m = soil[tiled32(j1, i1, tn)] * soil[tiled32(j2, i2, tn)];
        /* the bilinear surface's slope, clamped as ``bilinear`` clamps */
        double gu = (p0 - gx0) * is, gv = (p1 - gy0) * is;
        gu = gu < 0 ? 0.0 : gu;
        gu = gu > umax ? umax : gu;
        gv = gv < 0 ? 0.0 : gv;
        gv = gv > vmax ? vmax : gv;
        int j = (int)gu, ii = (int)gv;
        j = j > jmax ? jmax : j;
        ii = ii > imax ? imax : ii;
        double fu = gu - j, fv = gv - ii;
        int q = ii * nx + j;
        double h00 = hg[q], h01 = hg[q + 1], h10 = hg[q + nx], h11 = hg[q + nx + 1];
        double ea = h01 - h00, eb = h11 - h10;
        double z0 = h00 + ea * fu, z1 = h10 + eb * fu;
        double nxs = -((ea + (eb - ea) * fv) * is), nys = -((z1 - z0) * is);
        /* two-sided Lambert (frame.c's lambert with the normal (nxs, nys, 1)) */
        float len = sqrtf((float)(nxs * nxs + nys * nys + 1.0));
        double il = 1.0f / (len < 1e-12f ? 1e-12f : len);
        double side = -(nxs * d0 + nys * d1 + 1.0 * d2);
        double flip = side < 0 ? -il : il;
        double cs = flip * (nxs * L0 + nys * L1 + 1.0 * L2);
        cs = cs < 0 ? 0.0 : cs;
        cs = cs > 1 ? 1.0 : cs;
        double lit = amb + (1.0 - amb) * cs;
        double ah = tk * i3f;
        ah = ah < 0 ? 0.0 : ah;
        ah = ah > 0.6 ? 0.6 : ah;
        o0[i] = u8_of(s0 * m * lit * (1 - ah) + H0 * ah);
        o1[i] = u8_of(s1 * m * lit * (1 - ah) + H1 * ah);
        o2[i] = u8_of(s2 * m * lit * (1 - ah) + H2 * ah);
    }
}

/* refine()'s inline first Newton step at n pixels of one row (packed: column ray terms a,
 * cosines fwd, ray lengths tin; the row term b): the refined length in tout[i], and ok[i] = 0
 * where refine() would go on to refine_loop (outside the grid, a flat derivative, a long step
 * or one that leaves the cell), which the caller then runs from tin[i]. */
TARGET_AVX2 static void step_avx2(const step_par_t *P, int n, const double *restrict a, double b,
                                    const double *restrict fwd, const double *restrict tin,
                                    double *restrict tout, uint8_t *restrict ok) {
    const double r0 = P->r[0], r1 = P->r[1], r2 = P->r[2], r3 = P->r[3], r4 = P->r[4],
                 r5 = P->r[5], r6 = P->r[6], r7 = P->r[7], r8 = P->r[8];
    const double ox = P->o[0], oy = P->o[1], oz = P->o[2], gx0 = P->gx0, gy0 = P->gy0;
    const double is = P->inv_s, umax = P->umax, vmax = P->vmax;
    const int nx = P->nx, jmax = (int)umax - 1, imax = (int)vmax - 1;
    const double *restrict hg = P->heights;
    for (int i = 0; i < n; i++) {
        double f = fwd[i], y = a[i] * f, z = b * f, tk = tin[i];
        double d0 = r0 * f + r3 * y + r6 * z;
        double d1 = r1 * f + r4 * y + r7 * z;
        double d2 = r2 * f + r5 * y + r8 * z;
        double px = ox + tk * d0, py = oy + tk * d1, pz = oz + tk * d2;
        double gu = (px - gx0) * is, gv = (py - gy0) * is;
        int inside = (gu >= 0.0) & (gv >= 0.0) & (gu < umax) & (gv < vmax);
        /* outside: the nearest cell (the result is discarded) */
        double cu = gu < 0 ? 0.0 : gu, cv = gv < 0 ? 0.0 : gv;
        cu = cu > umax ? umax : cu;
        cv = cv > vmax ? vmax : cv;
        int j = (int)cu, ii = (int)cv;
        j = j > jmax ? jmax : j;
        ii = ii > imax ? imax : ii;
        double fu = cu - j, fv = cv - ii;
        int q = ii * nx + j;
        double h00 = hg[q], h01 = hg[q + 1], h10 = hg[q + nx], h11 = hg[q + nx + 1];
        double ea = h01 - h00, eb = h11 - h10;
        double z0 = h00 + ea * fu, z1 = h10 + eb * fu, dz = z1 - z0;
        double fz = pz - (z0 + dz * fv);
        double df = d2 - ((ea + (eb - ea) * fv) * d0 + dz * d1) * is;
        int flat = !(fabs(df) > 1e-9);
        double step = fz / (flat ? 1.0 : df);
        int small = !((step > 0.05) | (step < -0.05));
        double fu1 = fu - step * d0 * is, fv1 = fv - step * d1 * is;
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
    const double r0 = P->r[0], r1 = P->r[1], r2 = P->r[2], r3 = P->r[3], r4 = P->r[4],
                 r5 = P->r[5], r6 = P->r[6], r7 = P->r[7], r8 = P->r[8];
    const double amb = P->ambient, i3f = P->i3f;
    const double L0 = P->light[0], L1 = P->light[1], L2 = P->light[2];
    const double H0 = P->horizon[0], H1 = P->horizon[1], H2 = P->horizon[2];
    const float *restrict fn = P->face_normal, *restrict xf = P->xfm;
    for (int i = 0; i < n; i++) {
        int q = 3 * fl[i], s = 12 * sl[i];
        double f = fwd[i], y = a[i] * f, z = b * f, tk = t[i];
        double d0 = r0 * f + r3 * y + r6 * z;
        double d1 = r1 * f + r4 * y + r7 * z;
        double d2 = r2 * f + r5 * y + r8 * z;
        double m0 = fn[q], m1 = fn[q + 1], m2 = fn[q + 2];
        double nx = (double)xf[s] * m0 + (double)xf[s + 1] * m1 + (double)xf[s + 2] * m2;
        double ny = (double)xf[s + 4] * m0 + (double)xf[s + 5] * m1 + (double)xf[s + 6] * m2;
        double nz = (double)xf[s + 8] * m0 + (double)xf[s + 9] * m1 + (double)xf[s + 10] * m2;
        float len = sqrtf((float)(nx * nx + ny * ny + nz * nz));
        double il = 1.0f / (len < 1e-12f ? 1e-12f : len);
        double side = -(nx * d0 + ny * d1 + nz * d2);
        double flip = side < 0 ? -il : il;
        double cs = flip * (nx * L0 + ny * L1 + nz * L2);
        cs = cs < 0 ? 0.0 : cs;
        cs = cs > 1 ? 1.0 : cs;
        double lit = amb + (1.0 - amb) * cs;
        double ah = tk * i3f;
        ah = ah < 0 ? 0.0 : ah;
        ah = ah > 0.6 ? 0.6 : ah;
        o0[i] = u8_of(c0[i] / 255.0 * lit * (1 - ah) + H0 * ah);
        o1[i] = u8_of(c1[i] / 255.0 * lit * (1 - ah) + H1 * ah);
        o2[i] = u8_of(c2[i] / 255.0 * lit * (1 - ah) + H2 * ah);
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

/* stereo_invalid's first test over one row (inverse depths inv, the best occluder ``after``
 * of this row and of the rows above and below, this row's where there is none): flag[u] = 1
 * where the point's match falls left of the right imager (invalid), 2 where something may hide
 * it (the exact test follows), 0 where it is seen */
TARGET_AVX2 static void stereo_row_avx2(int w, const double *restrict inv,
                                          const double *restrict after,
                                          const double *restrict above,
                                          const double *restrict below, double fb, double ifb,
                                          double inear, uint8_t *restrict flag) {
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

#else
static inline int cpu_has_avx2(void) { return 0; }
#endif /* AGRINAV_AVX2 */

#endif
