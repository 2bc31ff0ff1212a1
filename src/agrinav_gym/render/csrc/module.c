/* The compiled sensor kernels as one extension module. Python reaches the functions through
 * ctypes (render/native.py), which keeps them free of the Python C API; the module object only
 * lets setuptools build and install them like any extension (optional: without a compiler the
 * numpy and Embree paths are used). Besides the kernels it exports what native.py checks a
 * build against: the hash of its sources, the layout of every struct at the boundary and the
 * statuses' meanings.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

#include "native.h"

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_native",
                                    "Compiled sensor kernels (called through ctypes).", -1, NULL};

PyMODINIT_FUNC PyInit__native(void) { return PyModule_Create(&module); }

#ifndef AGRINAV_SOURCE_HASH
#define AGRINAV_SOURCE_HASH "unknown"
#endif

/* the hash of the sources this build was made from (setup.py): render/native.py refuses a
 * build whose sources differ from those beside it */
EXPORT const char *agrinav_source_hash(void) {
    return AGRINAV_SOURCE_HASH;
}

/* what each status means (native.py's errors quote it) */
EXPORT const char *agrinav_status(int status) {
    static const char *const what[AGN_STATUSES] = {
        "ok",
        "out of memory",
        "a count, size or row range out of bounds",
        "an array it needs is missing (NULL)",
        "a parameter out of its range",
        "an invalid camera (size, focal lengths or clip depths)",
        "an invalid geometry block (counts, arrays or height grid)",
        "a matrix that must be positive definite is not",
    };
    return status >= 0 && status < AGN_STATUSES ? what[status] : "unknown status";
}

/* The layout of the structs at the boundary as this compiler lays them out: native.py
 * compares its ctypes declarations field by field and refuses a build that differs. */
typedef struct {
    const char *type, *field; /* field "": the struct's size */
    size_t value;
} layout_t;

#define SIZE(T) {#T, "", sizeof(T)}
#define AT(T, f) {#T, #f, offsetof(T, f)}
static const layout_t LAYOUT[] = {
    SIZE(camera_t), AT(camera_t, origin), AT(camera_t, rot), AT(camera_t, fx), AT(camera_t, fy),
    AT(camera_t, cx), AT(camera_t, cy), AT(camera_t, znear), AT(camera_t, zfar),
    AT(camera_t, width), AT(camera_t, height),

    SIZE(geometry_t), AT(geometry_t, n_slots), AT(geometry_t, n_protos),
    AT(geometry_t, slot_proto), AT(geometry_t, xfm), AT(geometry_t, proto_vertices),
    AT(geometry_t, proto_faces), AT(geometry_t, proto_nv), AT(geometry_t, proto_nf),
    AT(geometry_t, proto_sphere), AT(geometry_t, proto_adj), AT(geometry_t, proto_clusters),
    AT(geometry_t, cluster), AT(geometry_t, heights), AT(geometry_t, nx), AT(geometry_t, ny),
    AT(geometry_t, x0), AT(geometry_t, y0), AT(geometry_t, spacing),

    SIZE(proxy_scene_t), AT(proxy_scene_t, heights), AT(proxy_scene_t, nx),
    AT(proxy_scene_t, ny), AT(proxy_scene_t, x0), AT(proxy_scene_t, y0),
    AT(proxy_scene_t, spacing), AT(proxy_scene_t, block_max), AT(proxy_scene_t, block),
    AT(proxy_scene_t, bnx), AT(proxy_scene_t, bny), AT(proxy_scene_t, gnx),
    AT(proxy_scene_t, gny), AT(proxy_scene_t, gx), AT(proxy_scene_t, gy),
    AT(proxy_scene_t, cell), AT(proxy_scene_t, cell_start), AT(proxy_scene_t, cell_items),
    AT(proxy_scene_t, cylinders), AT(proxy_scene_t, ztop),

    SIZE(materials_t), AT(materials_t, face_offset), AT(materials_t, face_rgb),
    AT(materials_t, face_normal), AT(materials_t, tex_image), AT(materials_t, tex_uv),
    AT(materials_t, tex_hw), AT(materials_t, soil), AT(materials_t, soil_n),

    SIZE(shading_t), AT(shading_t, soil_rgb), AT(shading_t, light), AT(shading_t, sky_horizon),
    AT(shading_t, sky_zenith), AT(shading_t, ambient), AT(shading_t, far),
    AT(shading_t, origin), AT(shading_t, texel),

    SIZE(proxy_cast_args_t), AT(proxy_cast_args_t, scene), AT(proxy_cast_args_t, n),
    AT(proxy_cast_args_t, origin), AT(proxy_cast_args_t, dirs), AT(proxy_cast_args_t, rot),
    AT(proxy_cast_args_t, tlim), AT(proxy_cast_args_t, t), AT(proxy_cast_args_t, what),

    SIZE(raster_view_args_t), AT(raster_view_args_t, cam), AT(raster_view_args_t, geom),
    AT(raster_view_args_t, terrain), AT(raster_view_args_t, hiz), AT(raster_view_args_t, iz),
    AT(raster_view_args_t, inst), AT(raster_view_args_t, prim), AT(raster_view_args_t, row0),
    AT(raster_view_args_t, row1),

    SIZE(resolve_view_args_t), AT(resolve_view_args_t, cam), AT(resolve_view_args_t, geom),
    AT(resolve_view_args_t, forward), AT(resolve_view_args_t, vis_iz),
    AT(resolve_view_args_t, vis_inst), AT(resolve_view_args_t, vis_prim),
    AT(resolve_view_args_t, slot_plant), AT(resolve_view_args_t, proto_label),
    AT(resolve_view_args_t, refine_terrain), AT(resolve_view_args_t, robot_t),
    AT(resolve_view_args_t, robot_prim), AT(resolve_view_args_t, t),
    AT(resolve_view_args_t, label), AT(resolve_view_args_t, plant),
    AT(resolve_view_args_t, proto), AT(resolve_view_args_t, prim),
    AT(resolve_view_args_t, row0), AT(resolve_view_args_t, row1),

    SIZE(stereo_prepare_args_t), AT(stereo_prepare_args_t, width),
    AT(stereo_prepare_args_t, height), AT(stereo_prepare_args_t, fx),
    AT(stereo_prepare_args_t, baseline), AT(stereo_prepare_args_t, t),
    AT(stereo_prepare_args_t, forward), AT(stereo_prepare_args_t, scratch),
    AT(stereo_prepare_args_t, row0), AT(stereo_prepare_args_t, row1),

    SIZE(stereo_invalid_args_t), AT(stereo_invalid_args_t, cam), AT(stereo_invalid_args_t, geom),
    AT(stereo_invalid_args_t, baseline), AT(stereo_invalid_args_t, nearest),
    AT(stereo_invalid_args_t, t), AT(stereo_invalid_args_t, forward),
    AT(stereo_invalid_args_t, left_inst), AT(stereo_invalid_args_t, left_prim),
    AT(stereo_invalid_args_t, right_iz), AT(stereo_invalid_args_t, right_inst),
    AT(stereo_invalid_args_t, right_prim), AT(stereo_invalid_args_t, scratch),
    AT(stereo_invalid_args_t, bad), AT(stereo_invalid_args_t, row0),
    AT(stereo_invalid_args_t, row1),

    SIZE(finish_depth_args_t), AT(finish_depth_args_t, i0), AT(finish_depth_args_t, i1),
    AT(finish_depth_args_t, t), AT(finish_depth_args_t, forward),
    AT(finish_depth_args_t, noise_tables), AT(finish_depth_args_t, noise_key),
    AT(finish_depth_args_t, k_sigma), AT(finish_depth_args_t, min_range),
    AT(finish_depth_args_t, max_range), AT(finish_depth_args_t, bad),
    AT(finish_depth_args_t, depth), AT(finish_depth_args_t, label),
    AT(finish_depth_args_t, plant),

    SIZE(pixel_normals_args_t), AT(pixel_normals_args_t, tables), AT(pixel_normals_args_t, key),
    AT(pixel_normals_args_t, i0), AT(pixel_normals_args_t, i1), AT(pixel_normals_args_t, out),

    SIZE(refine_rays_args_t), AT(refine_rays_args_t, geom), AT(refine_rays_args_t, n),
    AT(refine_rays_args_t, origin), AT(refine_rays_args_t, dirs), AT(refine_rays_args_t, t),
    AT(refine_rays_args_t, ground),

    SIZE(shade_view_args_t), AT(shade_view_args_t, cam), AT(shade_view_args_t, geom),
    AT(shade_view_args_t, materials), AT(shade_view_args_t, shading),
    AT(shade_view_args_t, forward), AT(shade_view_args_t, t), AT(shade_view_args_t, label),
    AT(shade_view_args_t, vis_inst), AT(shade_view_args_t, proto), AT(shade_view_args_t, prim),
    AT(shade_view_args_t, robot_rot), AT(shade_view_args_t, robot_rgb),
    AT(shade_view_args_t, robot_normal), AT(shade_view_args_t, rgb),
    AT(shade_view_args_t, row0), AT(shade_view_args_t, row1),

    SIZE(embree_packets_args_t), AT(embree_packets_args_t, fn), AT(embree_packets_args_t, valid),
    AT(embree_packets_args_t, scene), AT(embree_packets_args_t, first),
    AT(embree_packets_args_t, count), AT(embree_packets_args_t, stride),

    SIZE(tyre_ground_t), AT(tyre_ground_t, heights), AT(tyre_ground_t, heights0),
    AT(tyre_ground_t, nx),
    AT(tyre_ground_t, ny), AT(tyre_ground_t, x0), AT(tyre_ground_t, y0),
    AT(tyre_ground_t, spacing), AT(tyre_ground_t, radius), AT(tyre_ground_t, dt),
    AT(tyre_ground_t, kz), AT(tyre_ground_t, cz), AT(tyre_ground_t, friction),
    AT(tyre_ground_t, shear_modulus), AT(tyre_ground_t, contact_length),
    AT(tyre_ground_t, rolling_resistance), AT(tyre_ground_t, shear_damping),
    AT(tyre_ground_t, contact_width), AT(tyre_ground_t, slices), AT(tyre_ground_t, bearing),
    AT(tyre_ground_t, bear_cohesive), AT(tyre_ground_t, bear_weight),
    AT(tyre_ground_t, bear_k3),

    SIZE(tyre_forces_args_t), AT(tyre_forces_args_t, ground), AT(tyre_forces_args_t, n),
    AT(tyre_forces_args_t, wheels), AT(tyre_forces_args_t, shear),
    AT(tyre_forces_args_t, normal), AT(tyre_forces_args_t, out),

    SIZE(ekf_config_t), AT(ekf_config_t, chi), AT(ekf_config_t, phi_b), AT(ekf_config_t, q_bias),
    AT(ekf_config_t, pose_noise), AT(ekf_config_t, yaw_noise), AT(ekf_config_t, velocity_noise),
    AT(ekf_config_t, yaw_accel_noise), AT(ekf_config_t, accel_noise),
    AT(ekf_config_t, odom_scale_noise), AT(ekf_config_t, tau), AT(ekf_config_t, r_step),
    AT(ekf_config_t, odom_speed_rel), AT(ekf_config_t, odom_yaw_rel),
    AT(ekf_config_t, odom_floor), AT(ekf_config_t, gnss_white), AT(ekf_config_t, history_s),
    AT(ekf_config_t, use_accel),

    SIZE(ekf_filter_t), AT(ekf_filter_t, s), AT(ekf_filter_t, P), AT(ekf_filter_t, mode),
    AT(ekf_filter_t, gnss_var), AT(ekf_filter_t, k), AT(ekf_filter_t, capacity),
    AT(ekf_filter_t, count), AT(ekf_filter_t, head), AT(ekf_filter_t, hist_s),
    AT(ekf_filter_t, hist_P), AT(ekf_filter_t, hist_r), AT(ekf_filter_t, hist_var),
    AT(ekf_filter_t, hist_mode),

    SIZE(ekf_update_args_t), AT(ekf_update_args_t, config), AT(ekf_update_args_t, filter),
    AT(ekf_update_args_t, dt), AT(ekf_update_args_t, reading), AT(ekf_update_args_t, gnss),

    SIZE(rl_config_t), AT(rl_config_t, chi), AT(rl_config_t, dt), AT(rl_config_t, q),
    AT(rl_config_t, odom_var), AT(rl_config_t, yaw_var), AT(rl_config_t, rate_var),
    AT(rl_config_t, accel_var), AT(rl_config_t, odom_threshold), AT(rl_config_t, imu_threshold),
    AT(rl_config_t, accel_threshold), AT(rl_config_t, gps_threshold),
    AT(rl_config_t, history_s), AT(rl_config_t, smooth), AT(rl_config_t, fuse_rate),
    AT(rl_config_t, fuse_accel), AT(rl_config_t, lever_arm),

    SIZE(rl_measurement_t), AT(rl_measurement_t, time), AT(rl_measurement_t, order),
    AT(rl_measurement_t, m), AT(rl_measurement_t, index), AT(rl_measurement_t, z),
    AT(rl_measurement_t, var), AT(rl_measurement_t, threshold),

    SIZE(rl_filter_t), AT(rl_filter_t, s), AT(rl_filter_t, P), AT(rl_filter_t, t_last),
    AT(rl_filter_t, k), AT(rl_filter_t, anchored), AT(rl_filter_t, rejected),
    AT(rl_filter_t, capacity), AT(rl_filter_t, count), AT(rl_filter_t, head),
    AT(rl_filter_t, hist_t), AT(rl_filter_t, hist_s), AT(rl_filter_t, hist_P),
    AT(rl_filter_t, done_capacity), AT(rl_filter_t, done_count), AT(rl_filter_t, done_head),
    AT(rl_filter_t, done), AT(rl_filter_t, queue_capacity), AT(rl_filter_t, queue),

    SIZE(rl_update_args_t), AT(rl_update_args_t, config), AT(rl_update_args_t, filter),
    AT(rl_update_args_t, reading),

    SIZE(route_t), AT(route_t, xy), AT(route_t, arc), AT(route_t, n), AT(route_t, table),
    AT(route_t, tags), AT(route_t, m), AT(route_t, table_step), AT(route_t, end),
    AT(route_t, direction), AT(route_t, length), AT(route_t, furrow_last),

    SIZE(route_track_args_t), AT(route_track_args_t, route), AT(route_track_args_t, x),
    AT(route_track_args_t, y), AT(route_track_args_t, k), AT(route_track_args_t, cte),
    AT(route_track_args_t, s),

    SIZE(route_points_args_t), AT(route_points_args_t, route), AT(route_points_args_t, s),
    AT(route_points_args_t, n), AT(route_points_args_t, offsets), AT(route_points_args_t, x),
    AT(route_points_args_t, y), AT(route_points_args_t, cos_yaw), AT(route_points_args_t, sin_yaw),
    AT(route_points_args_t, lo), AT(route_points_args_t, hi), AT(route_points_args_t, out),

    SIZE(route_grid_t), AT(route_grid_t, n), AT(route_grid_t, segs), AT(route_grid_t, seg_len),
    AT(route_grid_t, arc), AT(route_grid_t, half), AT(route_grid_t, cell), AT(route_grid_t, cx0),
    AT(route_grid_t, cy0), AT(route_grid_t, ncx), AT(route_grid_t, ncy),
    AT(route_grid_t, cell_start), AT(route_grid_t, cell_items), AT(route_grid_t, xy),

    SIZE(route_nearest_args_t), AT(route_nearest_args_t, grid), AT(route_nearest_args_t, x),
    AT(route_nearest_args_t, y), AT(route_nearest_args_t, bound), AT(route_nearest_args_t, d),
    AT(route_nearest_args_t, s), AT(route_nearest_args_t, k),

    SIZE(sky_t), AT(sky_t, n), AT(sky_t, xy), AT(sky_t, radius), AT(sky_t, bottom),
    AT(sky_t, top), AT(sky_t, share), AT(sky_t, n_az), AT(sky_t, n_el), AT(sky_t, cos_az),
    AT(sky_t, sin_az), AT(sky_t, tan_el), AT(sky_t, sec_el), AT(sky_t, stalk),
    AT(sky_t, db_per_m), AT(sky_t, cell), AT(sky_t, cx0), AT(sky_t, cy0), AT(sky_t, ncx),
    AT(sky_t, ncy), AT(sky_t, cell_start), AT(sky_t, cell_items),

    SIZE(sky_attenuation_args_t), AT(sky_attenuation_args_t, sky),
    AT(sky_attenuation_args_t, x), AT(sky_attenuation_args_t, y),
    AT(sky_attenuation_args_t, z), AT(sky_attenuation_args_t, reach),
    AT(sky_attenuation_args_t, out), AT(sky_attenuation_args_t, n_found),
};

/* the offset of ``field`` in struct ``type`` (field "": its size); -1 where there is none */
EXPORT int64_t agrinav_layout(const char *type, const char *field) {
    for (size_t k = 0; k < sizeof LAYOUT / sizeof LAYOUT[0]; k++)
        if (!strcmp(LAYOUT[k].type, type) && !strcmp(LAYOUT[k].field, field))
            return (int64_t)LAYOUT[k].value;
    return -1;
}
