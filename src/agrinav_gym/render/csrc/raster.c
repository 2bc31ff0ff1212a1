/* Z-buffer rasterisation of the instanced plant meshes and the terrain grid: the primary
 * visibility of a pinhole camera, pixel for pixel the first hit of the ray through each pixel
 * centre that the Embree caster finds (the D455 is a rectified pinhole, so rasterising the
 * primary rays is exact; only ties at shared edges may pick the other triangle).
 *
 * The output is a visibility buffer: per pixel 1/z of the nearest surface (0: none within
 * [znear, zfar]), the instance slot (or VB_TERRAIN / VB_NONE) and the triangle. Everything else
 * (depth, labels, shading, the stereo pair) is resolved from it per pixel (frame.c).
 *
 * Triangles are scan-converted at pixel centres in double precision (thin, long maize leaves
 * cover few pixels of a large bounding box, so rows are walked, not boxes); 1/z is affine in
 * the image, so each pixel's depth is exact for the triangle's plane. Triangles crossing the
 * near plane are clipped in camera space. Instances are culled by their bounding spheres and
 * the terrain by blocks of 8 x 8 cells against the frustum, so the cost follows what is in
 * view, not the field.
 */
#include <stdlib.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "native.h"

#define BLOCK 8

/* Hierarchical z: per tile of TILE x TILE pixels the farthest surface drawn so far (the least
 * 1/z; 0 while any pixel is empty), refreshed lazily where pixels were written since. A plant
 * or triangle whose nearest point is farther than that over every tile it may cover is hidden
 * and is skipped: under a canopy most of the far field is. */
#define TILE 8
#define TSHIFT 3

typedef struct {
    float *iz;
    int32_t *inst;
    int32_t *prim;
    double izfar;
    int row0, row1; /* the band of rows this call draws (two threads draw one view) */
    int w, tw;      /* image width, tiles across */
    float *tmin;    /* per tile: the least 1/z of its pixels in the band (valid when clean) */
    uint8_t *dirty; /* per tile: written since tmin was computed */
    int hiz;        /* keep and use the tiles (off where a view hides little: its bookkeeping
                     * would cost more than it saves) */
} vbuf_t;

static inline void mark_row(vbuf_t *b, int y, int x0, int x1) {
    if (!b->hiz) return;
    uint8_t *d = b->dirty + (size_t)(y >> TSHIFT) * b->tw;
    for (int t = x0 >> TSHIFT; t <= x1 >> TSHIFT; t++) d[t] = 1;
}

static inline void mark_column(vbuf_t *b, int x, int y0, int y1) {
    if (!b->hiz) return;
    for (int t = y0 >> TSHIFT; t <= y1 >> TSHIFT; t++) b->dirty[(size_t)t * b->tw + (x >> TSHIFT)] = 1;
}

/* the farthest surface of tile (ty, tx) within the band */
static float tile_min(vbuf_t *b, int ty, int tx) {
    size_t t = (size_t)ty * b->tw + tx;
    if (b->dirty[t]) {
        int y0 = ty << TSHIFT, y1 = y0 + TILE, x0 = tx << TSHIFT, x1 = x0 + TILE;
        if (y0 < b->row0) y0 = b->row0;
        if (y1 > b->row1) y1 = b->row1;
        if (x1 > b->w) x1 = b->w;
        float m = INFINITY;
        for (int y = y0; y < y1; y++) {
            const float *r = b->iz + (size_t)y * b->w;
            for (int x = x0; x < x1; x++) m = r[x] < m ? r[x] : m;
        }
        b->tmin[t] = m;
        b->dirty[t] = 0;
    }
    return b->tmin[t];
}

/* Whether everything in image box [x0, x1] x [y0, y1] is hidden behind what is drawn, for a
 * surface no nearer than 1/z = qmax. ``fresh`` = 0 reads the tiles as last computed: pixels
 * only ever come nearer, so a stale value is a lower bound and the answer stays safe (per
 * triangle, where refreshing after every write would cost more than it saves). */
static int hidden(vbuf_t *b, double x0, double x1, double y0, double y1, double qmax,
                  int fresh) {
    if (x0 < 0) x0 = 0;
    if (y0 < b->row0) y0 = b->row0;
    if (x1 > b->w - 1.0) x1 = b->w - 1.0;
    if (y1 > b->row1 - 1.0) y1 = b->row1 - 1.0;
    if (x0 > x1 || y0 > y1) return 1; /* no pixel of the band */
    if (!b->hiz) return 0;
    int tx0 = (int)x0 >> TSHIFT, tx1 = (int)x1 >> TSHIFT;
    int ty0 = (int)y0 >> TSHIFT, ty1 = (int)y1 >> TSHIFT;
    int all = 1;
    for (int ty = ty0; ty <= ty1; ty++)
        for (int tx = tx0; tx <= tx1; tx++) {
            /* fresh: every tile is brought up to date, for the triangle tests that follow */
            float m = fresh ? tile_min(b, ty, tx) : b->tmin[(size_t)ty * b->tw + tx];
            if (!(m > qmax)) {
                if (!fresh) return 0;
                all = 0;
            }
        }
    return all;
}

typedef struct {
    double X, Y, Z;  /* camera space */
    double sx, sy, q; /* image position and 1/X (valid when X >= znear) */
} cvert_t;

static inline void project(const cam_t *c, cvert_t *v) {
    v->q = 1.0 / v->X;
    v->sx = c->cx - c->fx * v->Y * v->q;
    v->sy = c->cy - c->fy * v->Z * v->q;
}

/* The depth test over pixels c0..c1 of a row where 1/z = A x + row: nearer pixels take the
 * triangle. Branchless: under a canopy the test passes and fails unpredictably. SSE2 (every
 * x86-64) does four pixels at once; 1/z is evaluated per pixel in double either way. */
static inline void fill_span(float *iz, int32_t *in, int32_t *pr, int c0, int c1, double A,
                             double row, int32_t id, int32_t prim) {
    int x = c0;
#ifdef __SSE2__
    const __m128d a2 = _mm_set1_pd(A), r2 = _mm_set1_pd(row), two = _mm_set1_pd(2.0);
    const __m128i idv = _mm_set1_epi32(id), prv = _mm_set1_epi32(prim);
    __m128d x01 = _mm_set_pd(x + 1.0, (double)x);
    for (; x + 3 <= c1; x += 4) {
        __m128d x23 = _mm_add_pd(x01, two);
        __m128d q01 = _mm_add_pd(_mm_mul_pd(a2, x01), r2);
        __m128d q23 = _mm_add_pd(_mm_mul_pd(a2, x23), r2);
        __m128 q = _mm_movelh_ps(_mm_cvtpd_ps(q01), _mm_cvtpd_ps(q23));
        __m128 old = _mm_loadu_ps(iz + x);
        __m128 m = _mm_cmpgt_ps(q, old);
        _mm_storeu_ps(iz + x, _mm_or_ps(_mm_and_ps(m, q), _mm_andnot_ps(m, old)));
        __m128i mi = _mm_castps_si128(m);
        __m128i oi = _mm_loadu_si128((const __m128i *)(in + x));
        _mm_storeu_si128((__m128i *)(in + x), _mm_or_si128(_mm_and_si128(mi, idv), _mm_andnot_si128(mi, oi)));
        __m128i op = _mm_loadu_si128((const __m128i *)(pr + x));
        _mm_storeu_si128((__m128i *)(pr + x), _mm_or_si128(_mm_and_si128(mi, prv), _mm_andnot_si128(mi, op)));
        x01 = _mm_add_pd(x23, two);
    }
#endif
    for (; x <= c1; x++) {
        float qf = (float)(A * x + row);
        int nearer = qf > iz[x];
        iz[x] = nearer ? qf : iz[x];
        in[x] = nearer ? id : in[x];
        pr[x] = nearer ? prim : pr[x];
    }
}

/* ceil and floor of x in [0, 6e4] (image columns and rows, clamped first): an offset turns
 * truncation into flooring without a rounding-mode change or a libm call */
static inline int ceil_px(double x) { return 65536 - (int)(65536.0 - x); }
static inline int floor_px(double x) { return (int)(x + 65536.0) - 65536; }

/* The depth test down pixels r0..r1 of column x where 1/z = B y + col (stride w). */
static inline void fill_column(float *iz, int32_t *in, int32_t *pr, int w, int x, int r0, int r1,
                               double B, double col, int32_t id, int32_t prim) {
    double q = B * r0 + col;
    for (int y = r0; y <= r1; y++, q = B * y + col) {
        size_t k = (size_t)y * w + x;
        float qf = (float)q;
        int nearer = qf > iz[k];
        iz[k] = nearer ? qf : iz[k];
        in[k] = nearer ? id : in[k];
        pr[k] = nearer ? prim : pr[k];
    }
}

/* Pixels k0..k1 along one scan line where 1/z = A k + line: the far limit 1/z >= izfar as a
 * bound on k (1/z is linear along the line); 0 when nothing is left. */
static inline int clip_far(double A, double line, double izfar, int *k0, int *k1) {
    if (A > 0) {
        double kf = ceil((izfar - line) / A);
        if (kf > *k0) *k0 = kf > *k1 + 1 ? *k1 + 1 : (int)kf;
    } else if (A < 0) {
        double kf = floor((izfar - line) / A);
        if (kf < *k1) *k1 = kf < *k0 - 1 ? *k0 - 1 : (int)kf;
    } else if (line < izfar) {
        return 0;
    }
    return *k0 <= *k1;
}

/* scan-convert a triangle given in image space (x, y, 1/z): along rows, or along columns when
 * it is taller than wide (a maize leaf seen from the lane is a few pixels wide and a hundred
 * tall: walking its rows would visit many rows whose span holds no pixel centre) */
static void tri_image(const cam_t *c, vbuf_t *b, const cvert_t *p0, const cvert_t *p1,
                      const cvert_t *p2, int32_t id, int32_t prim) {
    double x0 = p0->sx, y0 = p0->sy, x1 = p1->sx, y1 = p1->sy, x2 = p2->sx, y2 = p2->sy;
    double xmin = MIN2(x0, MIN2(x1, x2)), xmax = MAX2(x0, MAX2(x1, x2));
    double ymin = MIN2(y0, MIN2(y1, y2)), ymax = MAX2(y0, MAX2(y1, y2));
    const double wmax = c->w - 1.0, lo_row = b->row0, hi_row = b->row1 - 1.0;
    if (xmax < 0.0 || ymax < lo_row || xmin > wmax || ymin > hi_row) return;
    /* far away most triangles are smaller than a pixel: none holds a pixel centre */
    if (ceil_px(MAX2(xmin, 0.0)) > floor_px(MIN2(xmax, wmax)) ||
        ceil_px(MAX2(ymin, lo_row)) > floor_px(MIN2(ymax, hi_row)))
        return;
    double area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);
    if (!(fabs(area) > 1e-18)) return; /* seen edge-on: no pixel centre inside */
    double q0 = p0->q, q1 = p1->q, q2 = p2->q;
    if (hidden(b, xmin, xmax, ymin, ymax, MAX2(q0, MAX2(q1, q2)), 0)) return;
    double ia = 1.0 / area;
    double A = ((q1 - q0) * (y2 - y0) - (q2 - q0) * (y1 - y0)) * ia;
    double B = ((x1 - x0) * (q2 - q0) - (x2 - x0) * (q1 - q0)) * ia;
    double C = q0 - A * x0 - B * y0;
    const double izfar = b->izfar;
    int far = MIN2(q0, MIN2(q1, q2)) < izfar; /* the far limit cuts this triangle */
    int by_col = (xmax - xmin) < (ymax - ymin);
    /* (major, minor) coordinates: major is what the outer loop walks */
    double ma[3], mi[3];
    if (by_col) {
        ma[0] = x0, ma[1] = x1, ma[2] = x2, mi[0] = y0, mi[1] = y1, mi[2] = y2;
    } else {
        ma[0] = y0, ma[1] = y1, ma[2] = y2, mi[0] = x0, mi[1] = x1, mi[2] = x2;
    }
    /* vertices by major coordinate: a, m, z */
    int ia_ = 0, im = 1, iz_ = 2, tmp;
    if (ma[im] < ma[ia_]) tmp = ia_, ia_ = im, im = tmp;
    if (ma[iz_] < ma[im]) tmp = im, im = iz_, iz_ = tmp;
    if (ma[im] < ma[ia_]) tmp = ia_, ia_ = im, im = tmp;
    double a = ma[ia_], m = ma[im], z = ma[iz_];
    if (!(z > a)) return;
    double lo_major = by_col ? 0.0 : lo_row, hi_major = by_col ? wmax : hi_row;
    double lo_minor = by_col ? lo_row : 0.0, hi_minor = by_col ? hi_row : wmax;
    int s0 = ceil_px(MAX2(a, lo_major)), s1 = floor_px(MIN2(z, hi_major));
    if (s0 > s1) return;
    double kl = (mi[iz_] - mi[ia_]) / (z - a);
    double ku = m > a ? (mi[im] - mi[ia_]) / (m - a) : 0.0;
    double kd = z > m ? (mi[iz_] - mi[im]) / (z - m) : 0.0;
    double ma_ = by_col ? B : A; /* 1/z slope along the minor axis */
    double mj_ = by_col ? A : B; /* and along the major one */
    for (int sl = s0; sl <= s1; sl++) {
        double el = mi[ia_] + (sl - a) * kl;
        double es = sl < m ? mi[ia_] + (sl - a) * ku : mi[im] + (sl - m) * kd;
        double lo = MIN2(el, es), hi = MAX2(el, es);
        if (hi < lo_minor || lo > hi_minor) continue;
        int k0 = ceil_px(MAX2(lo, lo_minor)), k1 = floor_px(MIN2(hi, hi_minor));
        if (k0 > k1) continue;
        double line = mj_ * sl + C;
        if (far && !clip_far(ma_, line, izfar, &k0, &k1)) continue;
        if (by_col) {
            fill_column(b->iz, b->inst, b->prim, c->w, sl, k0, k1, ma_, line, id, prim);
            mark_column(b, sl, k0, k1);
        } else {
            size_t base = (size_t)sl * c->w;
            fill_span(b->iz + base, b->inst + base, b->prim + base, k0, k1, ma_, line, id, prim);
            mark_row(b, sl, k0, k1);
        }
    }
}

/* a camera-space triangle: culled, clipped at the near plane, scan-converted */
static void tri_camera(const cam_t *c, vbuf_t *b, cvert_t *v0, cvert_t *v1, cvert_t *v2,
                       int32_t id, int32_t prim) {
    const double zn = c->znear, zf = c->zfar;
    if (v0->X > zf && v1->X > zf && v2->X > zf) return;
    int in0 = v0->X >= zn, in1 = v1->X >= zn, in2 = v2->X >= zn;
    if (in0 && in1 && in2) {
        tri_image(c, b, v0, v1, v2, id, prim);
        return;
    }
    if (!in0 && !in1 && !in2) return;
    /* Sutherland-Hodgman against X = znear: at most four vertices */
    cvert_t poly[4];
    int n = 0;
    cvert_t *src[3] = {v0, v1, v2};
    for (int k = 0; k < 3; k++) {
        cvert_t *a = src[k], *e = src[(k + 1) % 3];
        int ia = a->X >= zn, ie = e->X >= zn;
        if (ia) poly[n++] = *a;
        if (ia != ie) {
            double s = (zn - a->X) / (e->X - a->X);
            cvert_t m;
            m.X = zn;
            m.Y = a->Y + s * (e->Y - a->Y);
            m.Z = a->Z + s * (e->Z - a->Z);
            poly[n++] = m;
        }
    }
    for (int k = 0; k < n; k++) project(c, &poly[k]);
    for (int k = 1; k + 1 < n; k++) tri_image(c, b, &poly[0], &poly[k], &poly[k + 1], id, prim);
}

/* whether a sphere (camera-space centre, radius) may reach into the frustum */
static int sphere_visible(const cam_t *c, double X, double Y, double Z, double r) {
    if (X + r < c->znear || X - r > c->zfar) return 0;
    /* side planes through the origin: Y <= sl X etc., distance along the unit normal */
    if ((Y - c->sl * X) > r * sqrt(1.0 + c->sl * c->sl)) return 0;
    if ((-Y - c->sr * X) > r * sqrt(1.0 + c->sr * c->sr)) return 0;
    if ((Z - c->su * X) > r * sqrt(1.0 + c->su * c->su)) return 0;
    if ((-Z - c->sd * X) > r * sqrt(1.0 + c->sd * c->sd)) return 0;
    return 1;
}

/* whether a camera-space sphere in front of the near plane covers no pixel of the band or
 * lies behind what is drawn there (its image box and nearest depth; tiles brought up to date) */
static int sphere_hidden(const cam_t *c, vbuf_t *b, double X, double Y, double Z, double rad,
                         int fresh) {
    if (!(X - rad > c->znear)) return 0;
    double xn = X - rad, xf = X + rad;
    double ylo = MIN2((Y - rad) / xn, (Y - rad) / xf), yhi = MAX2((Y + rad) / xn, (Y + rad) / xf);
    double zlo = MIN2((Z - rad) / xn, (Z - rad) / xf), zhi = MAX2((Z + rad) / xn, (Z + rad) / xf);
    return hidden(b, c->cx - c->fx * yhi, c->cx - c->fx * ylo, c->cy - c->fy * zhi,
                  c->cy - c->fy * zlo, 1.0 / xn, fresh);
}

static inline void to_camera(const cam_t *c, double x, double y, double z, cvert_t *v) {
    double px = x - c->o[0], py = y - c->o[1], pz = z - c->o[2];
    const double *r = c->r;
    v->X = r[0] * px + r[1] * py + r[2] * pz;
    v->Y = r[3] * px + r[4] * py + r[5] * pz;
    v->Z = r[6] * px + r[7] * py + r[8] * pz;
}

typedef struct {
    double X;
    int k;
} order_t;

static int by_depth(const void *a, const void *b) {
    const order_t *p = (const order_t *)a, *q = (const order_t *)b;
    if (p->X != q->X) return p->X < q->X ? -1 : 1;
    return p->k - q->k;
}

/* camera-space transform M = R [A | t - o] of slot k */
static void slot_transform(const cam_t *c, const float *x, double M[12]) {
    const double *r = c->r;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            M[4 * i + j] = r[3 * i] * x[j] + r[3 * i + 1] * x[4 + j] + r[3 * i + 2] * x[8 + j];
        M[4 * i + 3] = r[3 * i] * (x[3] - c->o[0]) + r[3 * i + 1] * (x[7] - c->o[1]) +
                       r[3 * i + 2] * (x[11] - c->o[2]);
    }
}

/* a prototype's point q (float32) through a slot's camera-space transform M */
static inline void transform(const double M[12], const float *q, double *X, double *Y,
                             double *Z) {
    *X = M[0] * q[0] + M[1] * q[1] + M[2] * q[2] + M[3];
    *Y = M[4] * q[0] + M[5] * q[1] + M[6] * q[2] + M[7];
    *Z = M[8] * q[0] + M[9] * q[1] + M[10] * q[2] + M[11];
}

/* the radius of a bounding sphere q (centre, radius) through a transform whose linear part
 * scales by ``scale``, grown past the float32 rounding of its vertices */
static inline double sphere_radius(const float *q, double scale) {
    return q[3] * scale * 1.0001 + 1e-6;
}

/* The plants in view, nearest first (what they hide is then skipped); returns -1 when out of
 * memory. The order only decides exact ties of depth, which stay deterministic. */
static int draw_instances(const cam_t *c, const geom_t *g, vbuf_t *b, cvert_t *scratch) {
    order_t *ord = (order_t *)malloc(sizeof(order_t) * (size_t)(g->n_slots > 0 ? g->n_slots : 1));
    double *sph = (double *)malloc(sizeof(double) * 5 * (size_t)(g->n_slots > 0 ? g->n_slots : 1));
    if (!ord || !sph) {
        free(ord), free(sph);
        return -1;
    }
    int n = 0;
    for (int k = 0; k < g->n_slots; k++) {
        const float *x = g->xfm + 12 * (size_t)k;
        const float *sp = g->proto_sphere + 4 * (size_t)g->slot_proto[k];
        double M[12];
        slot_transform(c, x, M);
        double scale = sqrt((double)x[0] * x[0] + (double)x[4] * x[4] + (double)x[8] * x[8]);
        double X, Y, Z, rad = sphere_radius(sp, scale);
        transform(M, sp, &X, &Y, &Z);
        if (!sphere_visible(c, X, Y, Z, rad)) continue;
        double *s4 = sph + 5 * (size_t)k; /* centre, radius, the transform's scale */
        s4[0] = X, s4[1] = Y, s4[2] = Z, s4[3] = rad, s4[4] = scale;
        ord[n].X = X, ord[n].k = k, n++;
    }
    qsort(ord, (size_t)n, sizeof(order_t), by_depth);
    for (int m = 0; m < n; m++) {
        int k = ord[m].k, p = g->slot_proto[k];
        const double *s4 = sph + 5 * (size_t)k;
        if (sphere_hidden(c, b, s4[0], s4[1], s4[2], s4[3], 1)) continue;
        double M[12];
        slot_transform(c, g->xfm + 12 * (size_t)k, M);
        const float *v = (const float *)(intptr_t)g->proto_vertices[p];
        const uint32_t *f = (const uint32_t *)(intptr_t)g->proto_faces[p];
        int nv = g->proto_nv[p], nf = g->proto_nf[p];
        for (int i = 0; i < nv; i++) {
            cvert_t *o = scratch + i;
            transform(M, v + 3 * (size_t)i, &o->X, &o->Y, &o->Z);
            if (o->X >= c->znear) project(c, o);
        }
        const int cl = g->cluster;
        const float *cs = cl ? (const float *)(intptr_t)g->proto_clusters[p] : NULL;
        const double scale = s4[4];
        for (int i0 = 0; i0 < nf; i0 += cl ? cl : nf) {
            if (cs) { /* a run of faces (a piece of a leaf) outside, off the band or hidden */
                const float *q = cs + 4 * (size_t)(i0 / cl);
                double X, Y, Z, rad = sphere_radius(q, scale);
                transform(M, q, &X, &Y, &Z);
                if (!sphere_visible(c, X, Y, Z, rad) || sphere_hidden(c, b, X, Y, Z, rad, 0)) continue;
            }
            int i1 = cl && i0 + cl < nf ? i0 + cl : nf;
            for (int i = i0; i < i1; i++) {
                const uint32_t *t = f + 3 * (size_t)i;
                tri_camera(c, b, scratch + t[0], scratch + t[1], scratch + t[2], k, i);
            }
        }
    }
    free(ord);
    free(sph);
    return 0;
}

/* whether an axis-aligned box may reach into the frustum (each plane's farthest corner) */
static int box_visible(const cam_t *c, const double lo[3], const double hi[3]) {
    /* inside: n . (p - o) + d >= 0 for camera-space normals n (rows of R combine them) */
    double nc[6][3] = {{1, 0, 0}, {-1, 0, 0}, {c->sl, -1, 0}, {c->sr, 1, 0}, {c->su, 0, -1},
                       {c->sd, 0, 1}};
    double dc[6] = {-c->znear, c->zfar, 0, 0, 0, 0};
    const double *r = c->r;
    for (int k = 0; k < 6; k++) {
        double n[3];
        for (int i = 0; i < 3; i++) n[i] = nc[k][0] * r[i] + nc[k][1] * r[3 + i] + nc[k][2] * r[6 + i];
        double best = dc[k];
        for (int i = 0; i < 3; i++) best += n[i] * ((n[i] >= 0 ? hi[i] : lo[i]) - c->o[i]);
        if (best < 0) return 0;
    }
    return 1;
}

/* whether a box lies wholly in front of the near plane and behind what is drawn */
static int box_hidden(const cam_t *c, vbuf_t *b, const double lo[3], const double hi[3]) {
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY, qmax = 0;
    for (int k = 0; k < 8; k++) {
        cvert_t v;
        to_camera(c, k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2], &v);
        if (!(v.X > c->znear)) return 0;
        project(c, &v);
        x0 = MIN2(x0, v.sx), x1 = MAX2(x1, v.sx), y0 = MIN2(y0, v.sy), y1 = MAX2(y1, v.sy);
        qmax = MAX2(qmax, v.q);
    }
    return hidden(b, x0, x1, y0, y1, qmax, 1);
}

static void draw_terrain(const cam_t *c, const geom_t *g, vbuf_t *b) {
    if (g->nx < 2 || g->ny < 2 || g->heights == NULL) return;
    /* the frustum's horizontal extent: apex and the far plane's corners */
    double xlo = c->o[0], xhi = c->o[0], ylo = c->o[1], yhi = c->o[1];
    double ys[2] = {c->sl, -c->sr}, zs[2] = {c->su, -c->sd};
    const double *r = c->r;
    for (int a = 0; a < 2; a++)
        for (int e = 0; e < 2; e++) {
            double X = c->zfar, Y = ys[a] * c->zfar, Z = zs[e] * c->zfar;
            double wx = c->o[0] + r[0] * X + r[3] * Y + r[6] * Z;
            double wy = c->o[1] + r[1] * X + r[4] * Y + r[7] * Z;
            xlo = MIN2(xlo, wx), xhi = MAX2(xhi, wx), ylo = MIN2(ylo, wy), yhi = MAX2(yhi, wy);
        }
    int nbx = (g->nx - 1 + BLOCK - 1) / BLOCK, nby = (g->ny - 1 + BLOCK - 1) / BLOCK;
    int bj0 = (int)floor((xlo - g->gx0) / (g->s * BLOCK)), bj1 = (int)floor((xhi - g->gx0) / (g->s * BLOCK));
    int bi0 = (int)floor((ylo - g->gy0) / (g->s * BLOCK)), bi1 = (int)floor((yhi - g->gy0) / (g->s * BLOCK));
    if (bj0 < 0) bj0 = 0;
    if (bi0 < 0) bi0 = 0;
    if (bj1 > nbx - 1) bj1 = nbx - 1;
    if (bi1 > nby - 1) bi1 = nby - 1;
    cvert_t vert[(BLOCK + 1) * (BLOCK + 1)];
    for (int bi = bi0; bi <= bi1; bi++)
        for (int bj = bj0; bj <= bj1; bj++) {
            int i0 = bi * BLOCK, j0 = bj * BLOCK;
            int i1 = i0 + BLOCK < g->ny - 1 ? i0 + BLOCK : g->ny - 1;
            int j1 = j0 + BLOCK < g->nx - 1 ? j0 + BLOCK : g->nx - 1;
            double zmin = INFINITY, zmax = -INFINITY;
            for (int i = i0; i <= i1; i++)
                for (int j = j0; j <= j1; j++) {
                    double z = g->heights[(size_t)i * g->nx + j];
                    zmin = MIN2(zmin, z), zmax = MAX2(zmax, z);
                }
            double lo[3] = {g->gx0 + j0 * g->s, g->gy0 + i0 * g->s, zmin};
            double hi[3] = {g->gx0 + j1 * g->s, g->gy0 + i1 * g->s, zmax};
            if (!box_visible(c, lo, hi)) continue;
            if (box_hidden(c, b, lo, hi)) continue;
            int w = j1 - j0 + 1;
            for (int i = i0; i <= i1; i++)
                for (int j = j0; j <= j1; j++) {
                    cvert_t *v = vert + (i - i0) * w + (j - j0);
                    to_camera(c, g->gx0 + j * g->s, g->gy0 + i * g->s,
                              g->heights[(size_t)i * g->nx + j], v);
                    if (v->X >= c->znear) project(c, v);
                }
            for (int i = i0; i < i1; i++)
                for (int j = j0; j < j1; j++) {
                    cvert_t *a = vert + (i - i0) * w + (j - j0);
                    int32_t cell = (int32_t)(i * (g->nx - 1) + j);
                    tri_camera(c, b, a, a + 1, a + w + 1, VB_TERRAIN, 2 * cell);
                    tri_camera(c, b, a, a + w + 1, a + w, VB_TERRAIN, 2 * cell + 1);
                }
        }
}

/* Rasterise the instances and the terrain of ``geom`` for camera ``cam`` into rows
 * [row0, row1) of the visibility buffer (iz zeroed and ids set to VB_NONE there first; two
 * calls on disjoint bands may run at once). ``terrain`` = 0 leaves the ground out; ``hiz`` = 0
 * draws without the coarse depth tiles (the same image). */
EXPORT int raster_view(const raster_view_args_t *a) {
    if (!a) return AGN_NULL_ARRAY;
    cam_t c;
    geom_t g;
    int st = cam_from(&c, a->cam);
    if (st == AGN_OK) st = geom_from(&g, a->geom);
    if (st != AGN_OK) return st;
    const int w = c.w, h = c.h, row0 = a->row0, row1 = a->row1;
    if (!rows_ok(row0, row1, h)) return AGN_BAD_SIZE;
    if (!a->iz || !a->inst || !a->prim) return AGN_NULL_ARRAY;
    float *iz = a->iz;
    int32_t *inst = a->inst, *prim = a->prim;
    for (size_t k = (size_t)row0 * w; k < (size_t)row1 * w; k++)
        iz[k] = 0.0f, inst[k] = VB_NONE, prim[k] = -1;
    int tw = (w + TILE - 1) >> TSHIFT, th = (h + TILE - 1) >> TSHIFT;
    vbuf_t b = {iz, inst, prim, 1.0 / c.zfar, row0, row1, w, tw, NULL, NULL, a->hiz};
    if (row0 >= row1) return AGN_OK;
    int maxv = 1;
    for (int p = 0; p < g.n_protos; p++)
        if (g.proto_nv[p] > maxv) maxv = g.proto_nv[p];
    cvert_t *scratch = (cvert_t *)malloc(sizeof(cvert_t) * (size_t)maxv);
    b.tmin = (float *)calloc((size_t)tw * th, sizeof(float));
    b.dirty = (uint8_t *)calloc((size_t)tw * th, 1);
    int ok = scratch && b.tmin && b.dirty;
    /* plants first, nearest first: the terrain behind them is then mostly skipped */
    if (ok) ok = draw_instances(&c, &g, &b, scratch) == 0;
    if (ok && a->terrain) draw_terrain(&c, &g, &b);
    free(scratch), free(b.tmin), free(b.dirty);
    return ok ? AGN_OK : AGN_NO_MEMORY;
}
