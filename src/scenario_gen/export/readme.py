"""The README.md each export carries: what is in the folder and how to open it."""

from __future__ import annotations

from typing import Any

from ..model import Scenario
from ..vertical import of_scenario
from .gazebo import GazeboSummary


def _head(scn: Scenario, what: str) -> str:
    g = scn.geo
    return (
        f"# {scn.spec.name} (seed {scn.seed}) — {what}\n\n"
        f"Written by `agrinav export`. Datum (ENU origin): lat {g.lat:.8f}, lon {g.lon:.8f}, "
        f"alt {g.alt:.3f} m; x east, y north, z up, metres. {len(scn.plants)} plants, "
        f"route {scn.route.length:.1f} m.\n\n"
        f"Heights (the datum's alt and every altitude written here): "
        f"{of_scenario(scn.info).label()}.\n\n![layout](preview.png)\n\n"
    )


def gazebo_section(g: GazeboSummary) -> str:
    plants = (
        f"{g.plants} plants merged into {g.tiles} static tiles (`models/agrinav_tile_*`: real "
        "plant meshes at exact pose and size as per-colour binary STL; the crops' stem proxies "
        "as one collision mesh of 8-sided prisms per tile)"
        if g.mode == "tiles"
        else f"{g.plants} plants, one `<include>` each with the scenario's pose "
        "(x y z roll pitch yaw, R = Rz·Ry·Rx); one model per species/growth holds the mesh "
        "and texture, size variants 2 % apart reuse it (height within 1 %)"
    )
    hm = (
        "- `worlds/field_heightmap.sdf` — Gazebo Sim only: the terrain as a 16-bit heightmap "
        "resampled to a (2^n+1)² grid (Gazebo Classic reads heightmap images as 8-bit).\n"
        if len(g.worlds) > 2
        else ""
    )
    return f"""## Gazebo

- `worlds/field.sdf` — Gazebo Sim (Fortress, Garden, Harmonic; system plugins use the
  Fortress names, which Harmonic still accepts; for Ionic and later replace
  `ignition-gazebo-` by `gz-sim-` and `ignition::gazebo` by `gz::sim`).
- `worlds/field_classic.world` — Gazebo Classic 11 (`heading_deg` 180 compensates Classic's
  rotated GPS frame, gazebo-classic bug report 2022; the poses are identical).
{hm}- `models/` — `agrinav_terrain` (textured COLLADA mesh, also the collision) and {plants}.
  Triangles in the plants: {g.triangles:,}.

```bash
. setup.bash                       # sets GAZEBO_MODEL_PATH and the Gazebo Sim resource paths
gz sim worlds/field.sdf            # Garden and later  (Fortress: ign gazebo worlds/field.sdf)
gazebo worlds/field_classic.world  # Gazebo Classic 11
```

A NavSat/GPS sensor in either world reports the lat/lon of `plants.csv`/`route.csv` for the
same ENU position (checked with libsdformat and ignition-math's SphericalCoordinates).
"""


def gazebo_readme(scn: Scenario, g: GazeboSummary) -> str:
    return _head(scn, "Gazebo world") + gazebo_section(g)


def nav2_readme(scn: Scenario, g: GazeboSummary, info: dict[str, Any]) -> str:
    lat, lon = scn.geo.lat, scn.geo.lon
    return (
        _head(scn, "ROS 2 / Nav2 bundle")
        + f"""## Run it (ROS 2 Humble)

```bash
. setup.bash
ros2 launch launch/agrinav_field.launch.py              # Gazebo Sim via ros_gz_sim
ros2 launch launch/agrinav_field.launch.py sim:=classic # Gazebo Classic 11 via gazebo_ros
```

The launch file starts Gazebo with the world, publishes `robot/summit_xl.urdf` through
`robot_state_publisher` and spawns the Summit-XL at the route start
(x {info["spawn"][0]:.3f}, y {info["spawn"][1]:.3f}, z {info["spawn"][2]:.3f} m,
yaw {info["spawn"][3]:.4f} rad). Gazebo sensors and a drive plugin are yours to add to the URDF
(`robot/` is the plain kinematic model agrinav_gym simulates).

## Waypoints

- `config/gps_waypoints.yaml` — {info["waypoints"]} sparse GPS waypoints in the format of Nav2's
  GPS waypoint follower demo (`waypoints: [{{latitude, longitude, yaw}}]`, yaw in radians,
  ENU: 0 = east, counter-clockwise): every lane entry and exit, the apex of every headland
  turn, and the end of the lead-out. Follow them with the demo's
  `logged_waypoint_follower config/gps_waypoints.yaml` (Iron and later:
  `BasicNavigator.followGpsWaypoints`).
- `config/waypoints_enu.yaml` — the same poses as x, y, yaw in the ENU frame, for Humble's
  `FollowWaypoints` in a map frame at the datum.
- `config/navsat_transform.yaml` — robot_localization settings that make its map frame this
  ENU frame: `use_local_cartesian: true`, `wait_for_datum: true`,
  `datum: [{lat:.10f}, {lon:.10f}, 0.0]`.
- `reference_path.csv` — the dense reference path ({len(scn.route)} points, ≤ 0.1 m apart; x, y, z
  ENU, lat, lon, alt, yaw, segment furrow/headland, lane, arc length s, turn type, direction
  +1 forward / -1 reverse) for cross-track evaluation of a recorded run.

"""
        + gazebo_section(g)
    )


def gis_readme(scn: Scenario, info: dict[str, Any]) -> str:
    utm = (
        f"- `{info['utm_tif']}` — the same terrain resampled (bilinear) into the datum's UTM "
        f"zone, {info['utm_crs']}, for tools that need an EPSG code; at the plants it departs "
        f"from the terrain by up to {info['utm_error_mm']:.1f} mm (resampling: terrain.tif is "
        "the exact one).\n"
        if info.get("utm_tif")
        else "- No UTM copy: the datum lies outside UTM's latitudes (-80° to 84°).\n"
    )
    dem = (
        f"- `{info['dem_tif']}` — the same terrain resampled (bilinear) into the source DEM's "
        f"CRS {info['dem_crs']}, to overlay on the DEM.\n"
        if info.get("dem_tif")
        else ""
    )
    return (
        _head(scn, "GIS layers")
        + f"""## Files

- `terrain.tif` — elevation (float32, metres, the heights above), one pixel per
  terrain node, in a local CRS whose x/y are the scenario's ENU x/y: {info["crs_name"]}
  (`crs_local.wkt`). Over this field it matches ENU to {info["crs_error_mm"]:.2f} mm. NoData
  is -9999 in every GeoTIFF here, so a reprojection (`gdalwarp -t_srs EPSG:...`) leaves NoData,
  not 0 m, outside the terrain.
{utm}{dem}- `layers.gpkg` — layers `field` (polygon), `rows` (planted rows), `plants` (points with
  species, stage, height, roll/pitch/yaw and ENU x/y/z) and `route` (furrow/headland
  segments), WGS84 lon/lat (EPSG:4326) with the heights above.
- `field.geojson`, `rows.geojson`, `plants.geojson`, `route.geojson` — the same layers as
  RFC 7946 GeoJSON, one geometry type per file, so `ogr2ogr` converts each to GeoPackage or
  Shapefile.

Open in QGIS: drag `terrain.tif` and `layers.gpkg` into the map (QGIS reprojects on the fly);
Raster ▸ Analysis ▸ Hillshade on `terrain.tif` gives the relief of `preview.png`.
"""
    )


def mesh_readme(scn: Scenario, files: list[str]) -> str:
    listing = "\n".join(f"- `{f}`" for f in files)
    return (
        _head(scn, "meshes")
        + f"""Terrain (and, if asked, the plants merged) in the scenario's ENU frame, metres.
glTF/GLB files are Y-up as the format requires (x east, y up, z south); the others are Z-up
(x east, y north, z up; COLLADA files say so: `<up_axis>Z_UP</up_axis>`).

{listing}
"""
    )
