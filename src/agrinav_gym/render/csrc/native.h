/* Shared definitions of the compiled sensor kernels (called from Python through ctypes).
 *
 * The boundary: every kernel takes one argument, a pointer to its own struct of named fields
 * (declared below; render/native.py declares the same structs as ctypes.Structure and checks
 * their layout against ``agrinav_layout`` when it loads a build), and returns a status: AGN_OK,
 * or why it did nothing (``agrinav_status`` names each; native.py raises an error naming the
 * kernel). Blocks that several kernels read (a camera, the scene's geometry, the proxy scene,
 * the materials and the shading) are structs of their own, pointed to from the arguments.
 *
 * Coordinates are the scene's: world ENU minus the MeshScene origin (the terrain's centre), so
 * float32 vertices keep sub-millimetre precision on any field. A pinhole camera (``camera_t``):
 * origin, the world -> camera rotation rows (camera body frame: x forward, y left, z up), fx,
 * fy, cx, cy and the clip depths; pixel (u, v) looks along (1, -(u - cx)/fx, -(v - cy)/fy) in
 * that frame, as ``CameraModel.pixel_rays``.
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

/* ------------------------------------------------------------------ statuses */
enum {
    AGN_OK = 0,
    AGN_NO_MEMORY = 1,    /* a working buffer could not be allocated */
    AGN_BAD_SIZE = 2,     /* a count, size or row range out of bounds */
    AGN_NULL_ARRAY = 3,   /* an array the call reads or writes is missing (NULL) */
    AGN_BAD_VALUE = 4,    /* a parameter out of its range */
    AGN_BAD_CAMERA = 5,   /* the camera block: size, focal lengths or clip depths */
    AGN_BAD_GEOMETRY = 6, /* the geometry block: counts, arrays or the height grid */
    AGN_NOT_POSITIVE = 7, /* a matrix that must be positive definite is not */
    AGN_STATUSES = 8
};

/* ------------------------------------------------------------------ shared blocks */

/* a pinhole camera of width x height pixels (raster_view.camera_params) */
typedef struct {
    double origin[3]; /* scene coordinates */
    double rot[9];    /* rows: the camera's forward, left and up axes in the world */
    double fx, fy, cx, cy;
    double znear, zfar;
    int32_t width, height;
} camera_t;

/* The geometry a visibility buffer refers to: instance slots (a prototype and a row-major 3x4
 * transform each) and the terrain's height grid (row i at y0 + i spacing, column j at
 * x0 + j spacing; heights NULL: no terrain). A prototype's arrays are given by address
 * (int64), in one table per kind. */
typedef struct {
    int32_t n_slots, n_protos;
    const int32_t *slot_proto;     /* (n_slots,) the prototype of each slot */
    const float *xfm;              /* (n_slots, 12) */
    const int64_t *proto_vertices; /* addresses of float32 (V, 3) arrays */
    const int64_t *proto_faces;    /* addresses of uint32 (F, 3) arrays */
    const int32_t *proto_nv, *proto_nf;
    const float *proto_sphere; /* (n_protos, 4): bounding sphere centre and radius */
    const int64_t *proto_adj;  /* addresses of int32 (F, 3): the face across each edge, -1 */
    /* addresses of float32 (ceil(F / cluster), 4): the bounding sphere of each run of
     * ``cluster`` faces (NULL: no clusters), culled like an instance before its triangles */
    const int64_t *proto_clusters;
    int32_t cluster;
    const double *heights; /* (ny, nx) */
    int32_t nx, ny;
    double x0, y0, spacing;
} geometry_t;

/* The proxy camera's scene (proxy_geometry.ProxyGeometry): the terrain with the highest vertex
 * of each block of ``block`` x ``block`` cells (bny x bnx), and the plant cylinders listed per
 * square cell of size ``cell`` of a gny x gnx grid from (gx, gy): cell c = i gnx + j holds
 * cylinders cell_items[cell_start[c]:cell_start[c+1]], and cylinders[5m..5m+4] = (x, y, bottom
 * z, top z, radius) is the record of cylinder cell_items[m] (in cell order: read one after
 * another). ``ztop``: the tallest cylinder's top (a rising ray above it meets no plant). */
typedef struct {
    const double *heights; /* (ny, nx) */
    int32_t nx, ny;
    double x0, y0, spacing;
    const double *block_max; /* (bny, bnx) */
    int32_t block, bnx, bny;
    int32_t gnx, gny;
    double gx, gy, cell;
    const int32_t *cell_start; /* (gnx gny + 1,) */
    const int32_t *cell_items;
    const double *cylinders;
    double ztop;
} proxy_scene_t;

/* What the colour camera's surfaces are made of (raster_view.SceneGeometry): prototype k's
 * faces start at face_offset[k] in the face tables; tex_image[k] and tex_uv[k] are the
 * addresses of its texture (h, w, 3 uint8) and of its float32 UVs (0: untextured), tex_hw[2k]
 * and tex_hw[2k+1] the texture's size. ``soil``: the soil texture (soil_n x soil_n, soil_n a
 * power of two, at least one 8 x 8 tile) stored in tiles (raster_view.tiled_texture). */
typedef struct {
    const int64_t *face_offset;
    const uint8_t *face_rgb;  /* (F, 3) over every prototype's faces */
    const float *face_normal; /* (F, 3) */
    const int64_t *tex_image, *tex_uv;
    const int32_t *tex_hw;
    const float *soil;
    int32_t soil_n;
} materials_t;

/* the light of a colour frame (render/shading.py) */
typedef struct {
    double soil_rgb[3];
    double light[3]; /* towards the sun */
    double sky_horizon[3], sky_zenith[3];
    double ambient;   /* ambient share of Lambert */
    double far;       /* haze distance scale */
    double origin[2]; /* the scene origin's x, y (the soil texture is in world coordinates) */
    double texel;     /* soil texel size */
} shading_t;

/* ------------------------------------------------------------------ the kernels */

/* proxycast.c: per ray k (from ``origin``, unit direction dirs[3k..3k+2] in the world, or in
 * the body frame when the row-major rotation ``rot`` (body -> world) is given; length limit
 * tlim[k]): the first hit's t (INFINITY: none) and what it hit (-1 terrain, -2 nothing, else
 * the cylinder's index). */
typedef struct {
    const proxy_scene_t *scene;
    int32_t n;
    double origin[3];
    const double *dirs; /* (n, 3) */
    const double *rot;  /* 3 x 3 or NULL */
    const double *tlim; /* (n,) */
    double *t;          /* (n,) out */
    int32_t *what;      /* (n,) out */
} proxy_cast_args_t;
EXPORT int proxy_cast(const proxy_cast_args_t *a);

/* raster.c: rows [row0, row1) of the visibility buffer of ``cam`` over ``geom`` */
typedef struct {
    const camera_t *cam;
    const geometry_t *geom;
    int32_t terrain; /* 0: the ground left out */
    int32_t hiz;     /* 0: no coarse depth tiles (the same image) */
    float *iz;       /* (h w,) out: 1/z, 0 where nothing */
    int32_t *inst;   /* (h w,) out: the slot, VB_TERRAIN or VB_NONE */
    int32_t *prim;   /* (h w,) out: the triangle */
    int32_t row0, row1;
} raster_view_args_t;
EXPORT int raster_view(const raster_view_args_t *a);

/* frame.c: rows [row0, row1) of a visibility buffer resolved */
typedef struct {
    const camera_t *cam;
    const geometry_t *geom;
    const double *forward; /* (h w,) each pixel ray's cosine to the optical axis */
    const float *vis_iz;   /* the visibility buffer (raster_view) */
    const int32_t *vis_inst, *vis_prim;
    const int32_t *slot_plant;  /* (n_slots,) the plant of each slot (NULL: no slots) */
    const uint8_t *proto_label; /* (n_protos,) */
    int32_t refine_terrain;
    const double *robot_t; /* (h w,) the robot's own hits, or NULL: none in view */
    const int32_t *robot_prim;
    double *t; /* (h w,) out: ray length, INFINITY where none */
    uint8_t *label;
    int32_t *plant, *proto, *prim;
    int32_t row0, row1;
} resolve_view_args_t;
EXPORT int resolve_view(const resolve_view_args_t *a);

/* frame.c: the stereo test's per-row preparation into ``scratch`` */
typedef struct {
    int32_t width, height;
    double fx, baseline;
    const double *t, *forward; /* (h w,) */
    double *scratch;           /* (3 h w,) out */
    int32_t row0, row1;
} stereo_prepare_args_t;
EXPORT int stereo_prepare(const stereo_prepare_args_t *a);

/* frame.c: rows [row0, row1) of ``bad``: 1 where the stereo pair cannot match */
typedef struct {
    const camera_t *cam;
    const geometry_t *geom;
    double baseline, nearest;
    const double *t, *forward;            /* the left (depth) view, resolved */
    const int32_t *left_inst, *left_prim; /* its visibility buffer */
    const float *right_iz;                /* the right imager's visibility buffer */
    const int32_t *right_inst, *right_prim;
    const double *scratch; /* stereo_prepare's, every row */
    uint8_t *bad;          /* (h w,) out */
    int32_t row0, row1;
} stereo_invalid_args_t;
EXPORT int stereo_invalid(const stereo_invalid_args_t *a);

/* frame.c: pixels [i0, i1) of the depth image, and the labels cut at the far limit */
typedef struct {
    int32_t i0, i1;
    const double *t, *forward;
    const double *noise_tables; /* pixel_noise.TABLES, or NULL: no noise */
    uint64_t noise_key;
    double k_sigma, min_range, max_range;
    const uint8_t *bad; /* the stereo pair's invalid pixels, or NULL: none */
    float *depth;       /* out */
    uint8_t *label;     /* in place, or NULL (and plant NULL): no labels */
    int32_t *plant;
} finish_depth_args_t;
EXPORT int finish_depth(const finish_depth_args_t *a);

/* frame.c: pixels [i0, i1)'s standard normal draws for ``key`` (pixel_noise.h) */
typedef struct {
    const double *tables;
    uint64_t key;
    int32_t i0, i1;
    double *out; /* (i1 - i0,) */
} pixel_normals_args_t;
EXPORT int pixel_normals(const pixel_normals_args_t *a);

/* frame.c: mesh_scene.refine_ground for n rays from ``origin`` (world coordinates; ``geom``
 * needs only the height grid) */
typedef struct {
    const geometry_t *geom;
    int32_t n;
    double origin[3];
    const float *dirs;     /* (n, 3) */
    double *t;             /* (n,) in place */
    const uint8_t *ground; /* (n,) the hits to move */
} refine_rays_args_t;
EXPORT int refine_rays(const refine_rays_args_t *a);

/* frame.c: rows [row0, row1) of the 8-bit RGB of a resolved colour view */
typedef struct {
    const camera_t *cam;
    const geometry_t *geom;
    const materials_t *materials;
    const shading_t *shading;
    const double *forward, *t; /* the view, resolved */
    const uint8_t *label;
    const int32_t *vis_inst, *proto, *prim;
    const double *robot_rot;   /* the robot's 3 x 3 rotation, or NULL: not in view */
    const uint8_t *robot_rgb;  /* its face colours */
    const float *robot_normal; /* and normals */
    uint8_t *rgb;              /* (h w, 3) out */
    int32_t row0, row1;
} shade_view_args_t;
EXPORT int shade_view(const shade_view_args_t *a);

/* packets.c: Embree's 8-ray packet queries, ``count`` packets ``stride`` bytes apart */
typedef struct {
    void *fn; /* rtcIntersect8 or rtcOccluded8 */
    const void *valid;
    void *scene;
    char *first;
    int64_t count, stride;
} embree_packets_args_t;
EXPORT int embree_packets(const embree_packets_args_t *a);

/* ------------------------------------------------------------------ physics and estimation */

/* The ground a tyre stands on: the terrain's height grid (row i at y0 + i spacing, column j at
 * x0 + j spacing), read as its bilinear surface, and the soil (config.soil, docs/physics.md). */
typedef struct {
    double *heights;        /* (ny, nx); a yielding ground (bearing) is cut in place */
    const double *heights0; /* a yielding ground's heights before any cut (else NULL) */
    int32_t nx, ny;
    double x0, y0, spacing;
    double radius;             /* wheel radius, m */
    double dt;                 /* physics step, s */
    double kz, cz;             /* vertical stiffness N/m and corner damping N s/m */
    double friction;           /* mu */
    double shear_modulus;      /* Janosi-Hanamoto K, m */
    double contact_length;     /* l, m */
    double rolling_resistance; /* c_rr */
    double shear_damping;      /* tau_d, s */
    double contact_width;      /* across the tread, m */
    int32_t slices;            /* discs across the tread; 0: a point contact */
    int32_t bearing;           /* 1: each disc bears at most the soil's capacity (yields) */
    double bear_cohesive;      /* sim.terramechanics.DiscBearing: c Nc sc A, N */
    double bear_weight;        /* 1/2 gamma B Ngamma sgamma A, N */
    double bear_k3;            /* 1 / (Nc tan phi) */
} tyre_ground_t;

/* tyres.c: one physics step of the tyre model (sim/tyres.py's twin, the same bits): per wheel
 * k, wheels[14k..14k+13] = centre (3), link orientation quaternion x y z w (4), linear (3) and
 * angular (3) velocity in the world, joint speed (1); shear[3k..3k+2] the patch's shear state
 * (in and out); out: normal[k], and out[7k..7k+6] = 1 in contact (else 0 and no force),
 * the force (3) and the world point it acts at (3). */
typedef struct {
    const tyre_ground_t *ground;
    int32_t n;
    const double *wheels; /* (n, 14) */
    double *shear;        /* (n, 3) in/out */
    double *normal;       /* (n,) out */
    double *out;          /* (n, 7) out */
} tyre_forces_args_t;
EXPORT int tyre_forces(const tyre_forces_args_t *a);

/* The EKF's constants (estimation/ekf.py, computed there from config.localisation): the state
 * is x, y, yaw, vx, vy, vyaw, ax, ay, heading bias, GNSS error east, north, odometry scale. */
typedef struct {
    double chi;             /* the drive's skid factor: odometry yaw rate / chi */
    double phi_b, q_bias;   /* heading-bias decay and process noise per step */
    double pose_noise, yaw_noise, velocity_noise, yaw_accel_noise, accel_noise;
    double odom_scale_noise; /* process noise densities (x dt per step) */
    double tau[4];           /* GNSS error correlation time by fix level (interface.FIX_LEVELS) */
    double r_step[7];        /* variances of the step measurements (the odometry's two unused) */
    double odom_speed_rel, odom_yaw_rel, odom_floor;
    double gnss_white; /* std of each fix's white error */
    double history_s;  /* oldest fix age applied */
    int32_t use_accel;
} ekf_config_t;

/* The EKF's state, read and written by ekf_update: s (12) and P (12 x 12, row-major); the GNSS
 * error process (its fix level, -1 before the first fix, and variance); k, the steps since the
 * reset (-1 before the first update); and the history of the last ``capacity`` steps (a ring
 * from slot ``head``, ``count`` held): each step's posterior state, covariance, GNSS process
 * and readings (EKF_READING values). */
typedef struct {
    double *s;
    double *P;
    int32_t mode;
    double gnss_var;
    int32_t k;
    int32_t capacity, count, head;
    double *hist_s;     /* (capacity, 12) */
    double *hist_P;     /* (capacity, 144) */
    double *hist_r;     /* (capacity, EKF_READING) */
    double *hist_var;   /* (capacity,) */
    int32_t *hist_mode; /* (capacity,) */
} ekf_filter_t;

/* the readings of one control step the EKF fuses: odometry v and yaw rate, gyro z, IMU roll,
 * pitch and yaw, accelerometer x and y */
#define EKF_READING 8
/* the fix of this step: new (1 or 0), fix level (FIX_LEVELS), east, north, the receiver's sigma
 * east and north, age (s), antenna lever arm x and up in base_link */
#define EKF_GNSS 9

/* ekf.c: Ekf.update, one control step (ekf.py is the reference; the same filter to rounding):
 * predict (from the second update on), fuse the step's readings, remember them, and apply a new
 * fix at its epoch, replaying the steps since. AGN_NOT_POSITIVE: an innovation covariance was
 * not positive definite (the filter is left part-updated, as numpy's would raise). */
typedef struct {
    const ekf_config_t *config;
    ekf_filter_t *filter;
    double dt;
    const double *reading; /* (EKF_READING,) */
    const double *gnss;    /* (EKF_GNSS,) */
} ekf_update_args_t;
EXPORT int ekf_update(const ekf_update_args_t *a);

/* robot_localization's planar filter (estimation/robot_localization.py, computed there from
 * config.localisation.robot_localization): the state is x, y, yaw (world), vx, vy, vyaw
 * (base_link), ax, ay. Thresholds are Mahalanobis distances, NaN for never. */
typedef struct {
    double chi;         /* the drive's skid factor: odometry yaw rate / chi */
    double dt;          /* the control period: readings are stamped k dt */
    double q[8];        /* process_noise_covariance's diagonal (x dt per prediction) */
    double odom_var[3]; /* the twist's vx, vy, vyaw variances */
    double yaw_var, rate_var;
    double accel_var[2];
    double odom_threshold, imu_threshold, accel_threshold, gps_threshold;
    double history_s; /* history_length */
    int32_t smooth;   /* smooth_lagged_data */
    int32_t fuse_rate, fuse_accel, lever_arm;
} rl_config_t;

/* most variables one reading measures */
#define RL_MAX_M 3
/* one queued reading: its stamp, order among equal stamps (odom, imu yaw, imu rate, imu
 * acceleration, gps), the state variables it measures, their values and variances */
typedef struct {
    double time;
    int32_t order, m;
    int32_t index[RL_MAX_M];
    double z[RL_MAX_M], var[RL_MAX_M];
    double threshold;
} rl_measurement_t;

/* The filter's state, read and written by rl_update: s (8) and P (8 x 8, row-major), the time
 * of its last reading, k (the steps since the reset, -1 before the first update), whether
 * navsat_transform has its datum, the readings rejected (odom, imu, gps); with
 * smooth_lagged_data the saved states (a ring from slot ``head``, ``count`` held: stamp, s, P)
 * and the readings processed (a ring from ``done_head``); ``queue`` is scratch space for a
 * step's readings and those replayed. */
typedef struct {
    double *s;
    double *P;
    double t_last;
    int32_t k, anchored;
    int32_t rejected[3];
    int32_t capacity, count, head;
    double *hist_t; /* (capacity,) */
    double *hist_s; /* (capacity, 8) */
    double *hist_P; /* (capacity, 64) */
    int32_t done_capacity, done_count, done_head;
    rl_measurement_t *done;  /* (done_capacity,) */
    int32_t queue_capacity;  /* at least done_capacity + 5 */
    rl_measurement_t *queue; /* (queue_capacity,) */
} rl_filter_t;

/* one control step's readings, in this order (RL_READING values) */
enum {
    RL_ODOM_V, RL_ODOM_W, RL_ROLL, RL_PITCH, RL_YAW, RL_GYRO_Z, RL_ACCEL_X, RL_ACCEL_Y,
    RL_FIX,     /* 1: a new fix with a solution (the receiver reports one), else 0 */
    RL_EAST, RL_NORTH, RL_SIGMA_E, RL_SIGMA_N, RL_AGE, RL_LEVER_X, RL_LEVER_Y,
    RL_READING
};

/* rl.c: RobotLocalizationEkf.update, one control step (robot_localization.py is the reference;
 * the same filter to rounding). AGN_NOT_POSITIVE: an innovation covariance was singular (the
 * filter is left part-updated, as numpy's would raise); AGN_BAD_SIZE: a history ring is full. */
typedef struct {
    const rl_config_t *config;
    rl_filter_t *filter;
    const double *reading; /* (RL_READING,) */
} rl_update_args_t;
EXPORT int rl_update(const rl_update_args_t *a);

/* A route (routes.RoutePath): n waypoints xy[2i], xy[2i+1] and their arc lengths; the table
 * of points every table_step of arc length (m of them, each with its furrow tag) that lookups
 * interpolate; past the table's end the last segment goes on from ``end`` along ``direction``
 * (its unit vector) at true distances, tagged ``furrow_last``. */
typedef struct {
    const double *xy;  /* (n, 2) */
    const double *arc; /* (n,) */
    int32_t n;
    const double *table; /* (m, 2) */
    const uint8_t *tags; /* (m,) */
    int32_t m;
    double table_step;
    double end[2], direction[2];
    double length;
    int32_t furrow_last;
} route_t;

/* routes.c: Tracker.update, the nearest segment searched from segment k (in/out) by walking
 * forward, then backward, while the distance shrinks: the signed cross-track error and the
 * arc length of (x, y) (out). */
typedef struct {
    const route_t *route;
    double x, y;
    int32_t k;
    double cte, s; /* out */
} route_track_args_t;
EXPORT int route_track(route_track_args_t *a);

/* routes.c: the route observation's points (observations.RouteObservation): the route at arc
 * lengths s + offsets[i] (RoutePath.lookup), in the frame of a robot at (x, y) whose heading
 * has cosine cos_yaw and sine sin_yaw, saturated to [lo, hi] as numpy saturates float32 against float64
 * bounds; out[3i..3i+2] = forward, left, furrow tag (0 or 1). */
typedef struct {
    const route_t *route;
    double s;
    int32_t n;
    const double *offsets; /* (n,) */
    double x, y, cos_yaw, sin_yaw;
    double lo, hi;
    float *out; /* (n, 3) */
} route_points_args_t;
EXPORT int route_points(const route_points_args_t *a);

/* The exact nearest-segment search of metrics.RouteProjector: per segment (ax, ay, dx, dy, dx^2
 * + dy^2) and length, the route's arc lengths, half the longest segment; the vertices by square
 * cell of side ``cell`` of an ncx x ncy grid whose first cell is (cx0, cy0) in cell units:
 * cell (i, j) lists cell_items[cell_start[c] .. cell_start[c + 1]), c = j ncx + i. */
typedef struct {
    int32_t n; /* vertices */
    const double *segs;    /* (n - 1, 5) */
    const double *seg_len; /* (n - 1,) */
    const double *arc;     /* (n,) */
    double half;
    double cell;
    int32_t cx0, cy0, ncx, ncy;
    const int32_t *cell_start; /* (ncx ncy + 1,) */
    const int32_t *cell_items;
    const double *xy; /* (n, 2) */
} route_grid_t;

/* routes.c: RouteProjector.project with a bound: the distance, segment and arc length of the
 * route point nearest (x, y), given any upper bound of that distance (ties: the lowest
 * segment). */
typedef struct {
    const route_grid_t *grid;
    double x, y, bound;
    double d, s; /* out */
    int32_t k;   /* out */
} route_nearest_args_t;
EXPORT int route_nearest(route_nearest_args_t *a);

/* The GNSS sky model's canopy (sensors/fixmode.py, Canopy and SkyModel): n plants, each a
 * cylinder at xy[2i], xy[2i+1] of radius[i] from bottom[i] to top[i] (ENU heights) holding
 * share[i] of the row's foliage; the sky's n_az azimuth cells (their cosines and sines) and
 * n_el elevation cells (tangents and secants); the foliage profile (0 uniform, 1 stalk) and
 * its loss in dB per metre. */
typedef struct {
    int32_t n;
    const double *xy; /* (n, 2) */
    const double *radius, *bottom, *top, *share; /* (n,) */
    int32_t n_az, n_el;
    const double *cos_az, *sin_az; /* (n_az,) */
    const double *tan_el, *sec_el; /* (n_el,) */
    int32_t stalk;
    double db_per_m;
    /* the plants by square cell of side ``cell`` of an ncx x ncy grid whose first cell is
     * (cx0, cy0) in cell units: cell (i, j) lists cell_items[cell_start[c] .. cell_start[c + 1])
     * in index order, c = j ncx + i */
    double cell;
    int32_t cx0, cy0, ncx, ncy;
    const int32_t *cell_start; /* (ncx ncy + 1,) */
    const int32_t *cell_items; /* (n,) */
} sky_t;

/* sky.c: SkyModel.attenuation, the foliage loss (dB) of every cell's ray from the antenna at
 * (x, y, z) through the plants within ``reach`` of it horizontally (summed in index order):
 * out[j n_el + k] for azimuth j and elevation k; n_found (out) is how many plants were in
 * reach. */
typedef struct {
    const sky_t *sky;
    double x, y, z, reach;
    double *out; /* (n_az, n_el) */
    int32_t n_found;
} sky_attenuation_args_t;
EXPORT int sky_attenuation(sky_attenuation_args_t *a);

/* ------------------------------------------------------------------ inside the kernels */
/* what a visibility-buffer pixel holds besides an instance slot (>= 0) */
#define VB_NONE (-1)
#define VB_TERRAIN (-2)

#define MIN2(a, b) ((a) < (b) ? (a) : (b))
#define MAX2(a, b) ((a) > (b) ? (a) : (b))

/* semantic classes (render/classes.py) */
#define CLS_OTHER 0
#define CLS_SOIL 1
#define CLS_ROBOT 4

/* the camera as the kernels read it */
typedef struct {
    double o[3];
    double r[9]; /* rows: the camera's forward, left and up axes in the world */
    double fx, fy, cx, cy, znear, zfar;
    int w, h;
    /* the frustum through the image's outer pixel edges: -sr X <= Y <= sl X, -sd X <= Z <= su X */
    double sl, sr, su, sd;
} cam_t;

/* the kernels' camera from its block (AGN_BAD_CAMERA: no camera) */
static inline int cam_from(cam_t *c, const camera_t *p) {
    if (!p) return AGN_NULL_ARRAY;
    if (p->width < 1 || p->height < 1 || !(p->fx > 0) || !(p->fy > 0) || !(p->znear > 0) ||
        !(p->zfar > p->znear))
        return AGN_BAD_CAMERA;
    for (int k = 0; k < 3; k++) c->o[k] = p->origin[k];
    for (int k = 0; k < 9; k++) c->r[k] = p->rot[k];
    c->fx = p->fx, c->fy = p->fy, c->cx = p->cx, c->cy = p->cy;
    c->znear = p->znear, c->zfar = p->zfar;
    int w = p->width, h = p->height;
    c->w = w, c->h = h;
    c->sl = (c->cx + 0.5) / c->fx;
    c->sr = (w - 0.5 - c->cx) / c->fx;
    c->su = (c->cy + 0.5) / c->fy;
    c->sd = (h - 0.5 - c->cy) / c->fy;
    return AGN_OK;
}

/* whether [row0, row1) is a band of an image ``h`` rows high */
static inline int rows_ok(int32_t row0, int32_t row1, int h) {
    return 0 <= row0 && row0 <= row1 && row1 <= h;
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

/* an angle into [-pi, pi) as the filters' numpy twins wrap it: (a + pi) % (2 pi) - pi with
 * Python's float modulo (the result takes the divisor's sign) */
static inline double angle_wrap(double a) {
    const double pi = 3.141592653589793;
    double b = 2.0 * pi, x = a + pi;
    double mod = fmod(x, b);
    if (mod != 0.0) {
        if ((b < 0) != (mod < 0)) mod += b;
    } else {
        mod = copysign(0.0, b);
    }
    return mod - pi;
}

/* floor as an integer, without a libm call */
static inline int64_t ifloor(double x) {
    int64_t i = (int64_t)x;
    return i - (x < (double)i);
}

/* the geometry as the kernels read it */
typedef struct {
    int n_slots;
    const int32_t *slot_proto;
    const float *xfm; /* (n_slots, 12) */
    int n_protos;
    const int64_t *proto_vertices;
    const int64_t *proto_faces;
    const int32_t *proto_nv, *proto_nf;
    const float *proto_sphere;
    const int64_t *proto_adj;
    const int64_t *proto_clusters;
    int cluster; /* 0: no clusters */
    const double *heights;
    int nx, ny;
    double gx0, gy0, s, inv_s;
} geom_t;

/* the kernels' geometry from its block (AGN_BAD_GEOMETRY: inconsistent) */
static inline int geom_from(geom_t *g, const geometry_t *p) {
    if (!p) return AGN_NULL_ARRAY;
    if (p->n_slots < 0 || p->n_protos < 0 || p->cluster < 0) return AGN_BAD_GEOMETRY;
    if (p->n_slots > 0 && (!p->slot_proto || !p->xfm || p->n_protos < 1)) return AGN_BAD_GEOMETRY;
    if (p->n_protos > 0 && (!p->proto_vertices || !p->proto_faces || !p->proto_nv ||
                            !p->proto_nf || !p->proto_sphere))
        return AGN_BAD_GEOMETRY;
    if (p->heights && (p->nx < 2 || p->ny < 2 || !(p->spacing > 0))) return AGN_BAD_GEOMETRY;
    g->slot_proto = p->slot_proto;
    g->xfm = p->xfm;
    g->proto_vertices = p->proto_vertices;
    g->proto_faces = p->proto_faces;
    g->proto_nv = p->proto_nv;
    g->proto_nf = p->proto_nf;
    g->proto_sphere = p->proto_sphere;
    g->proto_adj = p->proto_adj;
    g->proto_clusters = p->proto_clusters;
    g->heights = p->heights;
    g->n_slots = p->n_slots, g->n_protos = p->n_protos;
    g->nx = p->nx, g->ny = p->ny;
    g->gx0 = p->x0, g->gy0 = p->y0, g->s = p->spacing, g->inv_s = 1.0 / p->spacing;
    g->cluster = g->proto_clusters ? p->cluster : 0;
    return AGN_OK;
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
