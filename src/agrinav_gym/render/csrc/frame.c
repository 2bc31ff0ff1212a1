/* Per-pixel work on rasterised views (raster.c): what the hits are, the D455's stereo pair,
 * the depth image and the colour image. Each function is the compiled twin of numpy code that
 * stays the reference (render/mesh_scene.py, sensors/mesh_camera.py, sensors/d455.py,
 * render/shading.py); tests compare the two.
 */
#include <stdlib.h>

#include "batch.h"
#include "native.h"
#include "pixel_noise.h"

/* the column and row terms of cam_ray_f: a[u] = -(u - cx)/fx, b[v] = -(v - cy)/fy (one block) */
static double *ray_terms(const cam_t *c) {
    double *a = (double *)malloc(sizeof(double) * (size_t)(c->w + c->h));
    if (!a) return NULL;
    for (int u = 0; u < c->w; u++) a[u] = -(u - c->cx) / c->fx;
    for (int v = 0; v < c->h; v++) a[c->w + v] = -(v - c->cy) / c->fy;
    return a;
}

/* Ray parameter moved from a terrain triangle onto the bilinear surface: refine_ground's
 * Newton iteration, step for step (mesh_scene.refine_ground). */
static double refine_loop(const geom_t *g, const double *o, const double *d, double t0) {
    double t = t0;
    for (int k = 0; k < 4; k++) {
        double p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
        double hx, hy, h = bilinear(g, p[0], p[1], &hx, &hy);
        double f = p[2] - h;
        if (fabs(f) < 1e-6) return t;
        double df = d[2] - hx * d[0] - hy * d[1];
        double step = fabs(df) > 1e-9 ? f / df : 0.0;
        if (step > 0.05) step = 0.05;
        if (step < -0.05) step = -0.05;
        t -= step;
        if (k == 0) { /* a step that stays in its cell has converged */
            double qx = p[0] - step * d[0], qy = p[1] - step * d[1];
            if (ifloor((p[0] - g->gx0) * g->inv_s) == ifloor((qx - g->gx0) * g->inv_s) &&
                ifloor((p[1] - g->gy0) * g->inv_s) == ifloor((qy - g->gy0) * g->inv_s))
                return t;
        }
    }
    double p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
    if (fabs(p[2] - bilinear(g, p[0], p[1], NULL, NULL)) >= 1e-5) return t0;
    return t;
}

/* The same; its first step inline for hits inside the grid, where "the step stays in its
 * cell" is "the cell-local coordinates stay in [0, 1)" (no floors) */
static inline double refine(const geom_t *g, const double *o, const double *d, double t) {
    double px = o[0] + t * d[0], py = o[1] + t * d[1], pz = o[2] + t * d[2];
    double u = (px - g->gx0) * g->inv_s, v = (py - g->gy0) * g->inv_s;
    if (!(u >= 0.0 && v >= 0.0 && u < g->nx - 1.0 && v < g->ny - 1.0))
        return refine_loop(g, o, d, t);
    int j = (int)u, i = (int)v;
    double fu = u - j, fv = v - i;
    const double *hp = g->heights + (size_t)i * g->nx + j;
    double h00 = hp[0], h01 = hp[1], h10 = hp[g->nx], h11 = hp[g->nx + 1];
    double a = h01 - h00, b = h11 - h10;
    double z0 = h00 + a * fu, z1 = h10 + b * fu, dz = z1 - z0;
    double f = pz - (z0 + dz * fv);
    if (fabs(f) < 1e-6) return t;
    double df = d[2] - ((a + (b - a) * fv) * d[0] + dz * d[1]) * g->inv_s;
    if (!(fabs(df) > 1e-9)) return refine_loop(g, o, d, t);
    double step = f / df;
    if (step > 0.05 || step < -0.05) return refine_loop(g, o, d, t);
    double fu1 = fu - step * d[0] * g->inv_s, fv1 = fv - step * d[1] * g->inv_s;
    if (fu1 >= 0.0 && fu1 < 1.0 && fv1 >= 0.0 && fv1 < 1.0) return t - step;
    return refine_loop(g, o, d, t);
}

#ifdef AGRINAV_AVX2
/* resolve_view with AVX2, row by row: the row resolved at once, its terrain pixels' first
 * Newton step together where ``refine`` (refine_loop where that step is not enough, as refine
 * does), then the robot's hits laid over it. The same numbers as the pixel-by-pixel loop. */
static int resolve_rows_avx2(const cam_t *c, const geom_t *g, const double *ab, int w,
                             const double *fwd, const float *iz, const int32_t *inst,
                             const int32_t *vprim, const int32_t *slot_plant,
                             const uint8_t *proto_label, int refine, const double *robot_t,
                             const int32_t *robot_prim, double *t_out, uint8_t *label,
                             int32_t *plant, int32_t *proto, int32_t *prim, int row0, int row1) {
    /* a row's terrain pixels: column, then (packed) length before and after the step, ray
     * term, cosine; the prototypes' classes widened for the gathers */
    int32_t *us = (int32_t *)malloc(sizeof(int32_t) * (size_t)w);
    double *tin = (double *)malloc(sizeof(double) * 4 * (size_t)w);
    uint8_t *ok = (uint8_t *)malloc((size_t)w);
    size_t np = (size_t)(g->n_protos > 0 ? g->n_protos : 1);
    int32_t *lab32 = (int32_t *)malloc(sizeof(int32_t) * np);
    if (!us || !tin || !ok || !lab32) {
        free(us), free(tin), free(ok), free(lab32);
        return AGN_NO_MEMORY;
    }
    double *tout = tin + w, *pa = tin + 2 * w, *pf = tin + 3 * w;
    lab32[0] = CLS_OTHER;
    for (int i = 0; i < g->n_protos; i++) lab32[i] = proto_label[i];
    int32_t none = -1; /* slot_plant when there are no slots (slot 0 is read, never used) */
    step_par_t sp = {.cam = *c, .gx0 = g->gx0, .gy0 = g->gy0, .inv_s = g->inv_s, .nx = g->nx,
                     .ny = g->ny, .heights = g->heights};
    for (int v = row0; v < row1; v++) {
        size_t r = (size_t)v * w;
        resolve_row_avx2(w, inst + r, iz + r, fwd + r, vprim + r, g->slot_proto,
                         slot_plant ? slot_plant : &none, lab32, t_out + r, label + r, plant + r,
                         proto + r, prim + r);
        int n = 0;
        for (int u = 0; refine && u < w; u++)
            if (inst[r + u] == VB_TERRAIN)
                us[n] = u, tin[n] = t_out[r + u], pa[n] = ab[u], pf[n++] = fwd[r + u];
        if (n) step_avx2(&sp, n, pa, ab[c->w + v], pf, tin, tout, ok);
        for (int i = 0; i < n; i++) {
            double t = tout[i];
            if (!ok[i]) {
                double d[3];
                cam_ray_f(c, pa[i], ab[c->w + v], pf[i], d);
                t = refine_loop(g, c->o, d, tin[i]);
            }
            t_out[r + us[i]] = t;
        }
        for (size_t k = r; robot_t && k < r + w; k++)
            if (robot_t[k] < t_out[k]) {
                t_out[k] = robot_t[k], label[k] = CLS_ROBOT, plant[k] = -1;
                proto[k] = -1, prim[k] = robot_prim[k];
            }
    }
    free(us), free(tin), free(ok), free(lab32);
    return AGN_OK;
}
#endif

/* Per pixel of a visibility buffer: ray length t (inf: none), class, plant id (-1), prototype
 * (-1) and triangle. ``refine_terrain`` moves terrain hits onto the bilinear surface; the
 * robot's own constant hits (robot_t, robot_prim; NULL: none in view) win where nearer. */
EXPORT int resolve_view(const resolve_view_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    cam_t c;
    geom_t g;
    int st = cam_from(&c, a->cam);
    if (st == AGN_OK) st = geom_from(&g, a->geom);
    if (st != AGN_OK) return st;
    const int w = c.w, row0 = a->row0, row1 = a->row1;
    if (!rows_ok(row0, row1, c.h)) return AGN_BAD_SIZE;
    if (!a->forward || !a->vis_iz || !a->vis_inst || !a->vis_prim || !a->proto_label || !a->t ||
        !a->label || !a->plant || !a->proto || !a->prim || (g.n_slots > 0 && !a->slot_plant) ||
        (!a->robot_t != !a->robot_prim))
        return AGN_NULL_ARRAY;
    const double *fwd = a->forward, *robot_t = a->robot_t;
    const float *iz = a->vis_iz;
    const int32_t *inst = a->vis_inst, *vprim = a->vis_prim, *slot_plant = a->slot_plant;
    const int32_t *robot_prim = a->robot_prim;
    const uint8_t *proto_label = a->proto_label;
    double *t_out = a->t;
    uint8_t *label = a->label;
    int32_t *plant = a->plant, *proto = a->proto, *prim = a->prim;
    double *ab = ray_terms(&c);
    if (!ab) return AGN_NO_MEMORY;
    const int refine_ok = a->refine_terrain && g.heights != NULL && g.nx >= 2 && g.ny >= 2;
    int ret = AGN_OK;
#ifdef AGRINAV_AVX2
    if (cpu_has_avx2()) {
        ret = resolve_rows_avx2(&c, &g, ab, w, fwd, iz, inst, vprim, slot_plant, proto_label,
                                refine_ok, robot_t, robot_prim, t_out, label, plant, proto, prim,
                                row0, row1);
        free(ab);
        return ret;
    }
#endif
    for (int v = row0; v < row1; v++)
        for (int u = 0; u < w; u++) {
            size_t k = (size_t)v * w + u;
            double t = INFINITY;
            int32_t s = inst[k];
            uint8_t lab = CLS_OTHER;
            int32_t pl = -1, pr = -1, tri = vprim[k];
            if (s != VB_NONE) {
                t = 1.0 / ((double)iz[k] * fwd[k]);
                if (s == VB_TERRAIN) {
                    lab = CLS_SOIL;
                    if (refine_ok) {
                        double d[3];
                        cam_ray_f(&c, ab[u], ab[w + v], fwd[k], d);
                        t = refine(&g, c.o, d, t);
                    }
                } else {
                    pr = g.slot_proto[s];
                    pl = slot_plant[s];
                    lab = proto_label[pr];
                }
            } else {
                tri = -1;
            }
            if (robot_t && robot_t[k] < t) {
                t = robot_t[k], lab = CLS_ROBOT, pl = -1, pr = -1, tri = robot_prim[k];
            }
            t_out[k] = t, label[k] = lab, plant[k] = pl, proto[k] = pr, prim[k] = tri;
        }
    free(ab);
    return ret;
}

/* A segment (from the right imager R along seg, to t = tfar) tested against triangles once
 * each, the point's own triangle skipped */
#define SEEN 24

/* World triangles by (slot, triangle), direct-mapped: neighbouring pixels of a shadow test the
 * same few occluders, and building one from its instance costs more than the test itself */
#define TRI_CACHE 512
typedef struct {
    uint64_t key[TRI_CACHE]; /* (slot << 32 | triangle) + 1 as unsigned; 0: empty */
    double tri[TRI_CACHE][9];
} tri_cache_t;

static const double *cached_triangle(tri_cache_t *tc, const geom_t *g, int32_t si, int32_t sp) {
    uint64_t key = (((uint64_t)(uint32_t)si << 32) | (uint32_t)sp) + 1;
    uint32_t hsh = (uint32_t)si * 2654435761u ^ (uint32_t)sp * 2246822519u;
    size_t e = (hsh >> 7) & (TRI_CACHE - 1);
    if (tc->key[e] != key) {
        geom_triangle(g, si, sp, tc->tri[e]);
        tc->key[e] = key;
    }
    return tc->tri[e];
}

typedef struct {
    int32_t i[SEEN], p[SEEN];
    int n;
    int32_t own_i, own_p;
    const geom_t *g;
    tri_cache_t *cache;
    const double *R, *seg;
    double tfar;
} seg_test_t;

static int seg_test(seg_test_t *s, int32_t si, int32_t sp) {
    if (si == s->own_i && sp == s->own_p) return 0;
    for (int e = 0; e < s->n; e++)
        if (s->i[e] == si && s->p[e] == sp) return 0;
    if (s->n == SEEN) return 0;
    s->i[s->n] = si, s->p[s->n] = sp, s->n++;
    double th = ray_triangle(s->R, s->seg, cached_triangle(s->cache, s->g, si, sp), NULL, NULL);
    return th > 0.0 && th <= s->tfar;
}

/* The stereo test's per-row preparation (``scratch``: 3 w h doubles): inverse depth, and for
 * each pixel the best occluder candidate after it along the row (the maximum over u' > u of
 * 1/z(u') - u'/(f B)) and its column. Every row first: stereo_invalid reads the rows beside. */
EXPORT int stereo_prepare(const stereo_prepare_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    const int w = a->width, row0 = a->row0, row1 = a->row1;
    if (w < 1 || a->height < 1 || !rows_ok(row0, row1, a->height)) return AGN_BAD_SIZE;
    if (!a->t || !a->forward || !a->scratch) return AGN_NULL_ARRAY;
    if (!(a->fx > 0) || !(a->baseline > 0)) return AGN_BAD_VALUE;
    const double fx = a->fx, baseline = a->baseline, *t = a->t, *fwd = a->forward;
    double *scratch = a->scratch;
    const size_t n = (size_t)w * a->height;
    const double ifb = 1.0 / (fx * baseline);
    double *inv = scratch, *after = scratch + n;
    int32_t *arg = (int32_t *)(scratch + 2 * (size_t)n); /* the column of ``after``'s maximum */
    for (size_t k = (size_t)row0 * w; k < (size_t)row1 * w; k++) {
        double z = t[k] * fwd[k];
        inv[k] = (z < INFINITY && z > 0) ? 1.0 / z : 0.0;
    }
    for (int v = row0; v < row1; v++) { /* max over u' > u of 1/z(u') - u'/fB */
        double m = -INFINITY;
        int32_t am = -1;
        const double *iv = inv + (size_t)v * w;
        double *af = after + (size_t)v * w;
        int32_t *ag = arg + (size_t)v * w;
        for (int u = w - 1; u >= 0; u--) {
            af[u] = m, ag[u] = am;
            double gk = iv[u] - u * ifb;
            if (gk > m) m = gk, am = u;
        }
    }
    return AGN_OK;
}

/* Which pixels the stereo pair cannot match (sensors/d455.py): left of the right imager's
 * image, or in its occlusion shadow. Candidates for the shadow come from the epipolar test on
 * the depth image (d455.shadow_candidates, the same expression; ``stereo_prepare`` first, on
 * every row, since a row reads the rows beside it); each is then decided by
 * intersecting the segment from the right imager to the point (stopping 1 cm + 0.2 % short of
 * it, as the ray-cast path does) with the triangles that the right imager's own rasterised view
 * shows at the four pixels of its row around the point's image there. The segment passes
 * through the right imager's centre, so an occluder covers that image point: one wider than a
 * pixel there is seen at one of the four unless a nearer surface hides it at all of them.
 * Candidates whose two right-view pixels around that image point both show the point's own
 * triangle or nothing nearer than the point are seen (the ray lies between those two rays).
 * Where one of those surfaces is nearer than the point, the triangles sharing an edge with
 * its triangle are tested as well: a mesh's quads split along a diagonal leave slivers of
 * their second triangle, narrower than a pixel, between the pixel centres of a row. The
 * triangles the left view shows where the epipolar test found its nearest sample (on the
 * point's row and the rows beside it) are tested too: there the segment passes behind the
 * surface the left imager sees. What can still slip through is a whole occluder narrower than
 * a pixel in both views. ``scratch`` holds 3 w h doubles (``stereo_prepare``). Returns 0, or
 * -1 when out of memory. */
EXPORT int stereo_invalid(const stereo_invalid_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    cam_t c;
    geom_t g;
    int st = cam_from(&c, a->cam);
    if (st == AGN_OK) st = geom_from(&g, a->geom);
    if (st != AGN_OK) return st;
    if (g.n_slots > 0 && !g.proto_adj) return AGN_BAD_GEOMETRY; /* the faces beside a face */
    const int w = c.w, h = c.h, row0 = a->row0, row1 = a->row1;
    if (!rows_ok(row0, row1, h)) return AGN_BAD_SIZE;
    if (!a->t || !a->forward || !a->left_inst || !a->left_prim || !a->right_iz ||
        !a->right_inst || !a->right_prim || !a->scratch || !a->bad)
        return AGN_NULL_ARRAY;
    if (!(a->baseline > 0) || !(a->nearest > 0)) return AGN_BAD_VALUE;
    const double baseline = a->baseline, nearest = a->nearest;
    const double *t = a->t, *fwd = a->forward, *scratch = a->scratch;
    const int32_t *linst = a->left_inst, *lprim = a->left_prim;
    const float *riz = a->right_iz;
    const int32_t *rinst = a->right_inst, *rprim = a->right_prim;
    uint8_t *bad = a->bad;
    const double fb = c.fx * baseline, ifb = 1.0 / fb, inear = 1.0 / nearest;
    const size_t n = (size_t)w * h;
    const double *inv = scratch, *after = scratch + n;
    const int32_t *arg = (const int32_t *)(scratch + 2 * n);
    double *ab = ray_terms(&c);
    tri_cache_t *cache = (tri_cache_t *)calloc(1, sizeof(tri_cache_t));
    if (!ab || !cache) {
        free(ab), free(cache);
        return AGN_NO_MEMORY;
    }
    /* the right imager's centre: B to the right of the depth origin (-y in the camera) */
    double R[3] = {c.o[0] - baseline * c.r[3], c.o[1] - baseline * c.r[4],
                   c.o[2] - baseline * c.r[5]};
    void (*first)(int, const double *, const double *, const double *, const double *, double,
                  double, double, uint8_t *) = stereo_row;
#ifdef AGRINAV_AVX2
    if (cpu_has_avx2()) first = stereo_row_avx2;
#endif
    for (int v = row0; v < row1; v++) {
        /* the first test for the whole row, into bad[]; the candidates (2) are decided below */
        const double *af = after + (size_t)v * w;
        first(w, inv + (size_t)v * w, af, v > 0 ? af - w : af, v < h - 1 ? af + w : af, fb, ifb,
              inear, bad + (size_t)v * w);
        for (int u = 0; u < w; u++) {
            size_t k = (size_t)v * w + u;
            if (bad[k] != 2) continue; /* 1: outside the right imager; 0: seen */
            bad[k] = 0;
            double iv = inv[k];
            int k0 = (int)ifloor(u - fb * iv);
            /* Seen: the rays of the two right-view pixels around the point's image both meet
             * the point's own triangle first, or nothing nearer than the point; the ray to the
             * point lies between them in their epipolar plane, so only something narrower than
             * a pixel could block it. */
            int clear = 1;
            for (int kk = k0; kk <= k0 + 1 && clear; kk++) {
                if (kk < 0 || kk >= w) continue;
                size_t q = (size_t)v * w + kk;
                int own = rinst[q] == linst[k] && rprim[q] == lprim[k];
                clear = own || (double)riz[q] <= iv;
            }
            if (clear) continue;
            double d[3];
            cam_ray_f(&c, ab[u], ab[w + v], fwd[k], d);
            double P[3] = {c.o[0] + t[k] * d[0], c.o[1] + t[k] * d[1], c.o[2] + t[k] * d[2]};
            double seg[3] = {P[0] - R[0], P[1] - R[1], P[2] - R[2]};
            double len = sqrt(seg[0] * seg[0] + seg[1] * seg[1] + seg[2] * seg[2]);
            double tfar = 1.0 - (0.01 + 0.002 * len) / len;
            /* (row, column, view) of the triangles to test: the right view around the point's
             * image, then the left view where its depth came nearest to the segment */
            int cand_v[7], cand_u[7], cand_r[7], nc = 0;
            const int order[4] = {k0, k0 + 1, k0 - 1, k0 + 2};
            for (int m = 0; m < 4; m++) cand_v[nc] = v, cand_u[nc] = order[m], cand_r[nc++] = 1;
            for (int dv = -1; dv <= 1; dv++) {
                if (v + dv < 0 || v + dv >= h) continue;
                cand_v[nc] = v + dv, cand_u[nc] = arg[k + dv * w], cand_r[nc++] = 0;
            }
            seg_test_t st; /* field by field: an initialiser would zero the lists too */
            st.n = 0, st.own_i = linst[k], st.own_p = lprim[k], st.g = &g, st.cache = cache;
            st.R = R, st.seg = seg, st.tfar = tfar;
            int hit = 0;
            for (int m = 0; m < nc && !hit; m++) {
                int kk = cand_u[m];
                if (kk < 0 || kk >= w) continue;
                size_t q = (size_t)cand_v[m] * w + kk;
                int32_t si = cand_r[m] ? rinst[q] : linst[q], sp = cand_r[m] ? rprim[q] : lprim[q];
                if (si == VB_NONE) continue;
                hit = seg_test(&st, si, sp);
                if (!hit && cand_r[m] && (double)riz[q] > iv) { /* nearer than the point */
                    int32_t adj[3];
                    int na = geom_adjacent(&g, si, sp, adj);
                    for (int e = 0; e < na && !hit; e++) hit = seg_test(&st, si, adj[e]);
                }
            }
            if (hit) bad[k] = 1;
        }
    }
    free(ab), free(cache);
    return AGN_OK;
}

/* The depth image: noise (sigma = z^2 s / (f B) times pixel i's draw for the frame's ``key``,
 * pixel_noise.h; ``tables`` NULL: none) on every valid hit, then 0 where invalid (``bad``: the
 * stereo pair's, NULL: none); and the labels cut at the far limit. */
EXPORT int finish_depth(const finish_depth_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    const int i0 = a->i0, i1 = a->i1;
    if (i0 < 0 || i1 < i0) return AGN_BAD_SIZE;
    if (!a->t || !a->forward || !a->depth || (!a->label != !a->plant)) return AGN_NULL_ARRAY;
    const double *t = a->t, *fwd = a->forward, *tables = a->noise_tables;
    const uint64_t key = a->noise_key;
    const double k_sigma = a->k_sigma, min_range = a->min_range, max_range = a->max_range;
    const uint8_t *bad = a->bad;
    float *depth = a->depth;
    uint8_t *label = a->label;
    int32_t *plant = a->plant;
    pnoise_t pn = {0};
    if (tables) pn = pn_init(tables, key);
    for (int i = i0; i < i1; i++) {
        double z = t[i] * fwd[i];
        int hit = isfinite(z) && !(bad && bad[i]);
        double zn = z;
        if (hit && tables) zn += k_sigma * z * z * pn_normal(&pn, (uint64_t)i);
        int valid = hit && zn >= min_range && zn <= max_range;
        depth[i] = valid ? (float)zn : 0.0f;
        if (label && !(isfinite(z) && z <= max_range)) {
            label[i] = CLS_OTHER;
            plant[i] = -1;
        }
    }
    return AGN_OK;
}

/* pixels i0..i1's draws for ``key`` (the ray-cast paths' and the tests') */
EXPORT int pixel_normals(const pixel_normals_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    if (a->i0 < 0 || a->i1 < a->i0) return AGN_BAD_SIZE;
    if (!a->tables || !a->out) return AGN_NULL_ARRAY;
    pnoise_t pn = pn_init(a->tables, a->key);
    for (int i = a->i0; i < a->i1; i++) a->out[i - a->i0] = pn_normal(&pn, (uint64_t)i);
    return AGN_OK;
}

/* the bilinear surface's x, y derivatives (``bilinear``'s), without its clamps inside the grid */
static inline void slope(const geom_t *g, double x, double y, double *hx, double *hy) {
    double u = (x - g->gx0) * g->inv_s, v = (y - g->gy0) * g->inv_s;
    if (!(u >= 0.0 && v >= 0.0 && u < g->nx - 1.0 && v < g->ny - 1.0)) {
        bilinear(g, x, y, hx, hy);
        return;
    }
    int j = (int)u, i = (int)v;
    double fu = u - j, fv = v - i;
    const double *hp = g->heights + (size_t)i * g->nx + j;
    double h00 = hp[0], h01 = hp[1], h10 = hp[g->nx], h11 = hp[g->nx + 1];
    double a = h01 - h00, b = h11 - h10;
    *hx = (a + (b - a) * fv) * g->inv_s;
    *hy = (h10 + b * fu - (h00 + a * fu)) * g->inv_s;
}

/* floor(x) mod n, n a power of two (the soil texture's 512) */
static inline int64_t wrap(double x, int64_t n) { return ifloor(x) & (n - 1); }

#define SKY_STEPS 4096


/* Linear RGB of every pixel of a resolved colour view, as MeshCamera.shade: sky, distant
 * ground in haze, textured soil lit through the bilinear normal, plants by face colour or
 * texture (the texel at the hit's barycentrics) lit through their rotated face normal, the
 * robot by its face colours (materials_t, shading_t: native.h). */
EXPORT int shade_view(const shade_view_args_t *a) {
    if (!a || !a->materials || !a->shading) return AGN_NULL_ARRAY;
    cam_t c;
    geom_t g;
    int st = cam_from(&c, a->cam);
    if (st == AGN_OK) st = geom_from(&g, a->geom);
    if (st != AGN_OK) return st;
    const int w = c.w, row0 = a->row0, row1 = a->row1;
    if (!rows_ok(row0, row1, c.h)) return AGN_BAD_SIZE;
    const materials_t *mt = a->materials;
    const shading_t *sh = a->shading;
    if (!a->forward || !a->t || !a->label || !a->vis_inst || !a->proto || !a->prim || !a->rgb ||
        !mt->face_offset || !mt->face_rgb || !mt->face_normal || !mt->tex_image || !mt->tex_uv ||
        !mt->tex_hw || !mt->soil || (a->robot_rot && (!a->robot_rgb || !a->robot_normal)))
        return AGN_NULL_ARRAY;
    const int soil_n = mt->soil_n;
    /* a power of two, at least one tile (shading.TEX_SIZE) */
    if (soil_n < 8 || (soil_n & (soil_n - 1))) return AGN_BAD_SIZE;
    if (!(sh->far > 0) || !(sh->texel > 0)) return AGN_BAD_VALUE;
    const double *fwd = a->forward, *t = a->t, *robot_rot = a->robot_rot;
    const uint8_t *label = a->label, *face_rgb = mt->face_rgb, *robot_rgb = a->robot_rgb;
    const int32_t *vinst = a->vis_inst, *proto = a->proto, *prim = a->prim, *tex_hw = mt->tex_hw;
    const int64_t *face_offset = mt->face_offset, *tex_image = mt->tex_image, *tex_uv = mt->tex_uv;
    const float *face_normal = mt->face_normal, *soil = mt->soil, *robot_normal = a->robot_normal;
    uint8_t *rgb = a->rgb;
    const double *light = sh->light, *horizon = sh->sky_horizon, *zenith = sh->sky_zenith;
    const double ambient = sh->ambient, far = sh->far, texel = sh->texel;
    const double ca = cos(0.65), sa = sin(0.65), i3f = 1.0 / (3.0 * far), itx = 1.0 / texel;
    const double itx7 = 1.0 / (7.3 * texel);
    double ground[3]; /* beyond the loaded world: the soil colour in haze */
    for (int i = 0; i < 3; i++) ground[i] = sh->soil_rgb[i] * (ambient + 0.4);
    haze(ground, far, i3f, horizon);
    /* the sky's blend a = d_z^0.6, tabulated (linear interpolation: |error| < 3e-7) */
    double sky_a[SKY_STEPS + 2];
    for (int i = 0; i <= SKY_STEPS; i++) sky_a[i] = pow((double)i / SKY_STEPS, 0.6);
    sky_a[SKY_STEPS + 1] = 1.0;
    double *ab = ray_terms(&c);
    /* per row, batched: the soil pixels (us) and the untextured plant pixels (up: their face
     * fl, slot sl, face colour pc), and their colours sc, qc */
    int32_t *us = (int32_t *)malloc(sizeof(int32_t) * 4 * (size_t)w);
    uint8_t *sc = (uint8_t *)malloc(9 * (size_t)w);
    /* the batches' column ray terms, cosines and ray lengths, packed: soil, then plants */
    double *pk = (double *)malloc(sizeof(double) * 6 * (size_t)w);
    if (!ab || !us || !sc || !pk) {
        free(ab), free(us), free(sc), free(pk);
        return AGN_NO_MEMORY;
    }
    int32_t *up = us + w, *fl = us + 2 * (size_t)w, *sl = us + 3 * (size_t)w;
    uint8_t *pc = sc + 3 * (size_t)w;
#ifdef AGRINAV_AVX2
    uint8_t *qc = sc + 6 * (size_t)w;
    plant_par_t pp = {.cam = c, .face_normal = face_normal, .xfm = g.xfm, .ambient = ambient,
                      .i3f = i3f};
    soil_par_t sp = {.cam = c, .org = {sh->origin[0], sh->origin[1]}, .itx = itx,
                     .itx7 = itx7, .ca = ca, .sa = sa, .soil_n = soil_n, .inv_n = 1.0 / soil_n,
                     .soil = soil, .gx0 = g.gx0, .gy0 = g.gy0, .inv_s = g.inv_s, .nx = g.nx,
                     .ny = g.ny, .heights = g.heights, .ambient = ambient, .i3f = i3f};
    for (int i = 0; i < 3; i++) {
        pp.light[i] = sp.light[i] = light[i], pp.horizon[i] = sp.horizon[i] = horizon[i];
        sp.rgb[i] = sh->soil_rgb[i];
    }
#endif
    const int batch = cpu_has_avx2(); /* else pixel by pixel, as below */
    for (int v = row0; v < row1; v++) {
        int ns = 0, np = 0;
        for (int u = 0; u < w; u++) {
            size_t k = (size_t)v * w + u;
            double tk = t[k];
            uint8_t lab = label[k];
            if (batch && lab == CLS_SOIL && isfinite(tk)) { /* batched below */
                pk[ns] = ab[u], pk[w + ns] = fwd[k], pk[2 * w + ns] = tk;
                us[ns++] = u;
                continue;
            }
            if (batch && lab != CLS_ROBOT && proto[k] >= 0 && !tex_image[proto[k]]) {
                size_t flat = (size_t)face_offset[proto[k]] + prim[k];
                if (flat < (size_t)INT32_MAX / 3 && vinst[k] < INT32_MAX / 12) {
                    const uint8_t *col = face_rgb + 3 * flat;
                    up[np] = u, fl[np] = (int32_t)flat, sl[np] = vinst[k];
                    pk[3 * w + np] = ab[u], pk[4 * w + np] = fwd[k], pk[5 * w + np] = tk;
                    pc[np] = col[0], pc[w + np] = col[1], pc[2 * (size_t)w + np] = col[2];
                    np++;
                    continue;
                }
            }
            double d[3], out[3];
            cam_ray_f(&c, ab[u], ab[w + v], fwd[k], d);
            if (!isfinite(tk)) {
                if (d[2] < 0) {
                    out[0] = ground[0], out[1] = ground[1], out[2] = ground[2];
                } else {
                    double x = (d[2] > 1 ? 1.0 : d[2]) * SKY_STEPS;
                    int i0 = (int)x;
                    double a = sky_a[i0] + (x - i0) * (sky_a[i0 + 1] - sky_a[i0]);
                    if (a < 0.02) a = pow(d[2], 0.6); /* steep near the horizon: exact */
                    for (int i = 0; i < 3; i++) out[i] = horizon[i] * (1 - a) + zenith[i] * a;
                }
            } else if (lab == CLS_SOIL) {
                double p[3] = {c.o[0] + tk * d[0], c.o[1] + tk * d[1], c.o[2] + tk * d[2]};
                double x = p[0] + sh->origin[0], y = p[1] + sh->origin[1];
                int64_t i1 = wrap(x * itx, soil_n), j1 = wrap(y * itx, soil_n);
                double xr = ca * x - sa * y, yr = sa * x + ca * y;
                int64_t i2 = wrap(xr * itx7, soil_n), j2 = wrap(yr * itx7, soil_n);
                float m = soil[tiled((int)j1, (int)i1, soil_n)] * soil[tiled((int)j2, (int)i2, soil_n)];
                double alb[3] = {sh->soil_rgb[0] * m, sh->soil_rgb[1] * m, sh->soil_rgb[2] * m};
                double hx, hy;
                slope(&g, p[0], p[1], &hx, &hy);
                lambert(alb, -hx, -hy, 1.0, d, light, ambient, out);
                haze(out, tk, i3f, horizon);
            } else if (lab == CLS_ROBOT) {
                const uint8_t *col = robot_rgb + 3 * (size_t)prim[k];
                const float *nr = robot_normal + 3 * (size_t)prim[k];
                double alb[3] = {col[0] / 255.0, col[1] / 255.0, col[2] / 255.0};
                const double *r = robot_rot;
                lambert(alb, r[0] * nr[0] + r[1] * nr[1] + r[2] * nr[2],
                        r[3] * nr[0] + r[4] * nr[1] + r[5] * nr[2],
                        r[6] * nr[0] + r[7] * nr[1] + r[8] * nr[2], d, light, ambient, out);
            } else if (proto[k] >= 0) {
                int32_t pk = proto[k], f = prim[k], s = vinst[k];
                size_t flat = (size_t)face_offset[pk] + f;
                double alb[3];
                const uint8_t *tx = (const uint8_t *)(intptr_t)tex_image[pk];
                if (tx) {
                    double tri[9], bu = 0, bv = 0;
                    geom_triangle(&g, s, f, tri);
                    ray_triangle(c.o, d, tri, &bu, &bv);
                    const float *uv = (const float *)(intptr_t)tex_uv[pk];
                    const uint32_t *fc = (const uint32_t *)(intptr_t)g.proto_faces[pk] + 3 * (size_t)f;
                    double w0 = 1.0 - bu - bv;
                    double tu = uv[2 * fc[0]] * w0 + uv[2 * fc[1]] * bu + uv[2 * fc[2]] * bv;
                    double tv = uv[2 * fc[0] + 1] * w0 + uv[2 * fc[1] + 1] * bu + uv[2 * fc[2] + 1] * bv;
                    int th = tex_hw[2 * pk], tw = tex_hw[2 * pk + 1];
                    double mu = tu - (double)ifloor(tu), mv = tv - (double)ifloor(tv);
                    int64_t xi = ifloor(mu * tw), yi = ifloor((1.0 - mv) * th);
                    if (xi < 0) xi = 0;
                    if (xi > tw - 1) xi = tw - 1;
                    if (yi < 0) yi = 0;
                    if (yi > th - 1) yi = th - 1;
                    const uint8_t *px = tx + 3 * ((size_t)yi * tw + xi);
                    alb[0] = px[0] / 255.0, alb[1] = px[1] / 255.0, alb[2] = px[2] / 255.0;
                } else {
                    const uint8_t *col = face_rgb + 3 * flat;
                    alb[0] = col[0] / 255.0, alb[1] = col[1] / 255.0, alb[2] = col[2] / 255.0;
                }
                const float *nf = face_normal + 3 * flat;
                const float *x = g.xfm + 12 * (size_t)s;
                lambert(alb, (double)x[0] * nf[0] + (double)x[1] * nf[1] + (double)x[2] * nf[2],
                        (double)x[4] * nf[0] + (double)x[5] * nf[1] + (double)x[6] * nf[2],
                        (double)x[8] * nf[0] + (double)x[9] * nf[1] + (double)x[10] * nf[2], d,
                        light, ambient, out);
                haze(out, tk, i3f, horizon);
            } else {
                out[0] = out[1] = out[2] = 0.0;
            }
            for (int i = 0; i < 3; i++) rgb[3 * k + i] = to_u8(out[i]);
        }
#ifdef AGRINAV_AVX2
        uint8_t *row = rgb + 3 * (size_t)v * w;
        if (ns) {
            soil_avx2(&sp, ns, pk, ab[w + v], pk + w, pk + 2 * w, sc, sc + w, sc + 2 * (size_t)w);
            for (int i = 0; i < ns; i++) {
                uint8_t *px = row + 3 * (size_t)us[i];
                px[0] = sc[i], px[1] = sc[w + i], px[2] = sc[2 * (size_t)w + i];
            }
        }
        if (np) {
            plant_avx2(&pp, np, fl, sl, pc, pc + w, pc + 2 * (size_t)w, pk + 3 * w, ab[w + v],
                       pk + 4 * w, pk + 5 * w, qc, qc + w, qc + 2 * (size_t)w);
            for (int i = 0; i < np; i++) {
                uint8_t *px = row + 3 * (size_t)up[i];
                px[0] = qc[i], px[1] = qc[w + i], px[2] = qc[2 * (size_t)w + i];
            }
        }
#endif
    }
    free(ab), free(us), free(sc), free(pk);
    return AGN_OK;
}

/* ``mesh_scene.refine_ground`` for n rays from one origin ``o`` along float32 directions ``d``:
 * the hits ``t`` flagged in ``ground`` moved onto the bilinear surface, in place (world
 * coordinates; the geometry needs only the height grid). */
EXPORT int refine_rays(const refine_rays_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    geom_t g;
    int st = geom_from(&g, a->geom);
    if (st != AGN_OK) return st;
    if (!g.heights) return AGN_BAD_GEOMETRY;
    const int n = a->n;
    if (n < 0) return AGN_BAD_SIZE;
    if (n > 0 && (!a->dirs || !a->t || !a->ground)) return AGN_NULL_ARRAY;
    const double *o = a->origin;
    const float *d = a->dirs;
    double *t = a->t;
    const uint8_t *ground = a->ground;
    for (int k = 0; k < n; k++) {
        if (!ground[k]) continue;
        double dk[3] = {d[3 * (size_t)k], d[3 * (size_t)k + 1], d[3 * (size_t)k + 2]};
        t[k] = refine(&g, o, dk, t[k]);
    }
    return AGN_OK;
}
