/* Shared definitions of the compiled sensor kernels (called from Python through ctypes).
 *
 * Coordinates are the scene's: world ENU minus the MeshScene origin (the terrain's centre), so
 * float32 vertices keep sub-millimetre precision on any field. A pinhole camera is given as a
 * double array (see ``cam_from``): origin, the world -> camera rotation rows (camera body
 * frame: x forward, y left, z up), fx, fy, cx, cy and the clip depths; pixel (u, v) looks along
 * (1, -(u - cx)/fx, -(v - cy)/fy) in that frame, as ``CameraModel.pixel_rays``.
 */
#ifndef AGRINAV_NATIVE_H
#define AGRINAV_NATIVE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#ifdef _WIN32
#define EXPORT __declspec(dllexport)
#else
#define EXPORT __attribute__((visibility("default")))
#endif

/* what a visibility-buffer pixel holds besides an instance slot (>= 0) */
#define VB_NONE (-1)
#define VB_TERRAIN (-2)

#define MIN2(a, b) ((a) < (b) ? (a) : (b))
#define MAX2(a, b) ((a) > (b) ? (a) : (b))

/* semantic classes (sim/plant_meshes.py) */
#define CLS_OTHER 0
#define CLS_SOIL 1
#define CLS_ROBOT 4

/* the camera's double parameter block: o[3], r[9], fx, fy, cx, cy, znear, zfar */
#define CAM_PARAMS 18

typedef struct {
    double o[3];
    double r[9]; /* rows: the camera's forward, left and up axes in the world */
    double fx, fy, cx, cy, znear, zfar;
    int w, h;
    /* the frustum through the image's outer pixel edges: -sr X <= Y <= sl X, -sd X <= Z <= su X */
    double sl, sr, su, sd;
} cam_t;

static inline void cam_from(cam_t *c, const double *p, int w, int h) {
    for (int k = 0; k < 3; k++) c->o[k] = p[k];
    for (int k = 0; k < 9; k++) c->r[k] = p[3 + k];
    c->fx = p[12], c->fy = p[13], c->cx = p[14], c->cy = p[15];
    c->znear = p[16], c->zfar = p[17];
    c->w = w, c->h = h;
    c->sl = (c->cx + 0.5) / c->fx;
    c->sr = (w - 0.5 - c->cx) / c->fx;
    c->su = (c->cy + 0.5) / c->fy;
    c->sd = (h - 0.5 - c->cy) / c->fy;
}

/* The unit world direction of pixel (u, v) from its column and row terms a = -(u - cx)/fx,
 * b = -(v - cy)/fy and its cosine to the optical axis f = 1/|(1, a, b)| (PixelRays.forward):
 * no square root or division per pixel */
static inline void cam_ray_f(const cam_t *c, double a, double b, double f, double d[3]) {
    double y = a * f, z = b * f;
    const double *r = c->r;
    d[0] = r[0] * f + r[3] * y + r[6] * z;
    d[1] = r[1] * f + r[4] * y + r[7] * z;
    d[2] = r[2] * f + r[5] * y + r[8] * z;
}

/* floor as an integer, without a libm call */
static inline int64_t ifloor(double x) {
    int64_t i = (int64_t)x;
    return i - (x < (double)i);
}

/* The geometry a visibility buffer refers to: instance slots (a prototype and a row-major 3x4
 * transform each) and the terrain's height grid (row i at gy0 + i s, column j at gx0 + j s). */
typedef struct {
    int n_slots;
    const int32_t *slot_proto;
    const float *xfm; /* (n_slots, 12) */
    int n_protos;
    const int64_t *proto_vertices; /* addresses of float32 (V, 3) arrays */
    const int64_t *proto_faces;    /* addresses of uint32 (F, 3) arrays */
    const int32_t *proto_nv, *proto_nf;
    const float *proto_sphere; /* (n_protos, 4): bounding sphere centre and radius */
    const int64_t *proto_adj;  /* addresses of int32 (F, 3): the face across each edge, -1 */
    /* addresses of float32 (ceil(F / cluster), 4): the bounding sphere of each run of
     * ``cluster`` faces (0: no clusters), culled like an instance before its triangles */
    const int64_t *proto_clusters;
    int cluster;
    const double *heights;
    int nx, ny;
    double gx0, gy0, s, inv_s;
} geom_t;

/* the geometry block passed from Python: pointers as int64 then scalars as doubles */
#define GEOM_PTRS 10
#define GEOM_VALS 8
static inline void geom_from(geom_t *g, const int64_t *p, const double *v) {
    g->slot_proto = (const int32_t *)(intptr_t)p[0];
    g->xfm = (const float *)(intptr_t)p[1];
    g->proto_vertices = (const int64_t *)(intptr_t)p[2];
    g->proto_faces = (const int64_t *)(intptr_t)p[3];
    g->proto_nv = (const int32_t *)(intptr_t)p[4];
    g->proto_nf = (const int32_t *)(intptr_t)p[5];
    g->proto_sphere = (const float *)(intptr_t)p[6];
    g->heights = (const double *)(intptr_t)p[7];
    g->proto_adj = (const int64_t *)(intptr_t)p[8];
    g->proto_clusters = (const int64_t *)(intptr_t)p[9];
    g->n_slots = (int)v[0], g->n_protos = (int)v[1];
    g->nx = (int)v[2], g->ny = (int)v[3];
    g->gx0 = v[4], g->gy0 = v[5], g->s = v[6], g->inv_s = 1.0 / v[6];
    g->cluster = g->proto_clusters ? (int)v[7] : 0;
}

/* the (up to 3) triangles sharing an edge with triangle ``prim`` of slot ``slot``; returns
 * how many */
static inline int geom_adjacent(const geom_t *g, int32_t slot, int32_t prim, int32_t out[3]) {
    int n = 0;
    if (slot == VB_TERRAIN) {
        /* T0 = (i,j),(i,j+1),(i+1,j+1) meets T1 of its cell, of the cell below and of the cell
         * to its right; T1 = (i,j),(i+1,j+1),(i+1,j) meets T0 of its cell, of the cell to its
         * left and of the cell above (Terrain.to_trimesh's split) */
        int cols = g->nx - 1, rows = g->ny - 1;
        int cell = prim >> 1, i = cell / cols, j = cell % cols;
        if (prim & 1) {
            out[n++] = 2 * cell;
            if (j > 0) out[n++] = 2 * (cell - 1);
            if (i + 1 < rows) out[n++] = 2 * (cell + cols);
        } else {
            out[n++] = 2 * cell + 1;
            if (i > 0) out[n++] = 2 * (cell - cols) + 1;
            if (j + 1 < cols) out[n++] = 2 * (cell + 1) + 1;
        }
        return n;
    }
    const int32_t *a = (const int32_t *)(intptr_t)g->proto_adj[g->slot_proto[slot]] + 3 * (size_t)prim;
    for (int e = 0; e < 3; e++)
        if (a[e] >= 0) out[n++] = a[e];
    return n;
}

/* the three world vertices of triangle ``prim`` of slot ``slot`` (or of the terrain) */
static inline void geom_triangle(const geom_t *g, int32_t slot, int32_t prim, double t[9]) {
    if (slot == VB_TERRAIN) {
        int cell = prim >> 1, i = cell / (g->nx - 1), j = cell % (g->nx - 1);
        /* the split of Terrain.to_trimesh: (a, a+1, a+w+1) and (a, a+w+1, a+w) */
        int di[2][3] = {{0, 0, 1}, {0, 1, 1}}, dj[2][3] = {{0, 1, 1}, {0, 1, 0}};
        int k = prim & 1;
        for (int m = 0; m < 3; m++) {
            int ii = i + di[k][m], jj = j + dj[k][m];
            t[3 * m] = g->gx0 + jj * g->s;
            t[3 * m + 1] = g->gy0 + ii * g->s;
            t[3 * m + 2] = g->heights[(size_t)ii * g->nx + jj];
        }
        return;
    }
    int p = g->slot_proto[slot];
    const float *v = (const float *)(intptr_t)g->proto_vertices[p];
    const uint32_t *f = (const uint32_t *)(intptr_t)g->proto_faces[p] + 3 * (size_t)prim;
    const float *x = g->xfm + 12 * (size_t)slot;
    for (int m = 0; m < 3; m++) {
        const float *q = v + 3 * (size_t)f[m];
        for (int i = 0; i < 3; i++)
            t[3 * m + i] = (double)x[4 * i] * q[0] + (double)x[4 * i + 1] * q[1] +
                           (double)x[4 * i + 2] * q[2] + (double)x[4 * i + 3];
    }
}

/* Moller-Trumbore: ray parameter of the hit of o + t d with triangle t[9] (INFINITY: none) and
 * the barycentrics (u at vertex 1, v at vertex 2, as Embree reports them) */
static inline double ray_triangle(const double *o, const double *d, const double *t, double *bu,
                                  double *bv) {
    double e1[3] = {t[3] - t[0], t[4] - t[1], t[5] - t[2]};
    double e2[3] = {t[6] - t[0], t[7] - t[1], t[8] - t[2]};
    double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                   d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    if (det == 0.0) return INFINITY;
    double inv = 1.0 / det;
    double s[3] = {o[0] - t[0], o[1] - t[1], o[2] - t[2]};
    double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) * inv;
    if (u < 0.0 || u > 1.0) return INFINITY;
    double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                   s[0] * e1[1] - s[1] * e1[0]};
    double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
    if (v < 0.0 || u + v > 1.0) return INFINITY;
    if (bu) *bu = u;
    if (bv) *bv = v;
    return (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
}

/* The cell of an nx x ny height grid under grid coordinates (u, v), clamped to the grid as
 * mesh_scene.bilinear clamps: the index of its first corner (row i, column j: i nx + j) and the
 * position (fu, fv) in it. Also inlined into batch.h's AVX2 loops (int indices: gathers). */
static inline int grid_cell(double u, double v, int nx, int ny, double *fu, double *fv) {
    const double umax = nx - 1.0, vmax = ny - 1.0;
    u = u < 0 ? 0.0 : u;
    u = u > umax ? umax : u;
    v = v < 0 ? 0.0 : v;
    v = v > vmax ? vmax : v;
    int j = (int)u, i = (int)v;
    j = j > nx - 2 ? nx - 2 : j;
    i = i > ny - 2 ? ny - 2 : i;
    *fu = u - j, *fv = v - i;
    return i * nx + j;
}

/* height and its x, y derivatives on the bilinear surface (as mesh_scene.bilinear) */
static inline double bilinear(const geom_t *g, double x, double y, double *hx, double *hy) {
    double fu, fv;
    const double *h =
        g->heights + grid_cell((x - g->gx0) * g->inv_s, (y - g->gy0) * g->inv_s, g->nx, g->ny,
                               &fu, &fv);
    double h00 = h[0], h01 = h[1], h10 = h[g->nx], h11 = h[g->nx + 1];
    double a = h01 - h00, b = h11 - h10;
    double z0 = h00 + a * fu, z1 = h10 + b * fu, dz = z1 - z0;
    if (hx) *hx = (a + (b - a) * fv) * g->inv_s;
    if (hy) *hy = dz * g->inv_s;
    return z0 + dz * fv;
}

#endif
