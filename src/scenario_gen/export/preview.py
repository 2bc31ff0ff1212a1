"""preview.png of an export: what was written, drawn over the terrain's hillshade.

GIS: the hillshade of the GeoTIFF as read back from disk (so a misplaced raster shows), and
the plants and obstacles of the GeoPackage as read back. Gazebo: the merged tiles or the plants
by size variant. Nav2: the waypoints with their yaw and the robot's spawn footprint. Every
export: the obstacles by kind, when the field has any.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..model import Scenario
from ..preview import draw_obstacles
from ..terrain import hillshade

#: Summit-XL footprint (nav config), m: drawn at the spawn pose.
FOOTPRINT = (0.724, 0.616)


Extent = tuple[float, float, float, float]


def _background(scn: Scenario, geotiff: Path | None) -> tuple[np.ndarray, Extent, str]:
    t = scn.terrain
    if geotiff is not None:
        import rasterio

        with rasterio.open(geotiff) as ds:
            z = ds.read(1)[::-1].astype(np.float64)  # rows south to north
            b = ds.bounds
            extent = (b.left, b.right, b.bottom, b.top)
        return z, extent, f"hillshade of {geotiff.name} (read back)"
    s = t.spacing / 2
    xmin, ymin, xmax, ymax = t.bounds
    return t.heights, (xmin - s, xmax + s, ymin - s, ymax + s), "terrain hillshade"


def _gpkg_plants(scn: Scenario, gpkg: Path) -> tuple[np.ndarray, np.ndarray]:
    """Plant points of a written GeoPackage in the GeoTIFF's CRS (its x/y are ENU x/y)."""
    return _gpkg_points(scn, gpkg, "plants")


def _gpkg_points(scn: Scenario, gpkg: Path, layer: str) -> tuple[np.ndarray, np.ndarray]:
    """A layer's points (polygons: their centroids) in the GeoTIFF's CRS."""
    import shapely
    from pyproj import Transformer

    from .crs import local_crs
    from .gpkg import read_geometries

    geoms = np.array(read_geometries(gpkg, layer), dtype=object)
    if layer != "plants":  # the footprints' centres (lon/lat: flat enough over a footprint)
        geoms = shapely.centroid(geoms)
    lonlat = shapely.get_coordinates(geoms)
    to_local = Transformer.from_crs("EPSG:4326", local_crs(scn.geo), always_xy=True)
    x, y = to_local.transform(lonlat[:, 0], lonlat[:, 1])
    return np.asarray(x), np.asarray(y)


def render_export_preview(
    scn: Scenario,
    path: Path,
    gazebo: Any = None,
    waypoints: tuple[np.ndarray, np.ndarray] | None = None,
    spawn: tuple[float, float, float, float] | None = None,
    geotiff: Path | None = None,
    opts: Any = None,
    dpi: int = 110,
) -> None:
    export_preview_figure(scn, gazebo, waypoints, spawn, geotiff, opts, dpi).savefig(path)


def export_preview_figure(
    scn: Scenario,
    gazebo: Any = None,
    waypoints: tuple[np.ndarray, np.ndarray] | None = None,
    spawn: tuple[float, float, float, float] | None = None,
    geotiff: Path | None = None,
    opts: Any = None,
    dpi: int = 110,
) -> Any:
    """The export's preview as a matplotlib ``Figure`` (no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon as MplPolygon
    from matplotlib.patches import Rectangle

    z, extent, bg = _background(scn, geotiff)
    aspect = (extent[3] - extent[2]) / max(extent[1] - extent[0], 1e-9)
    fig = Figure(figsize=(10.0, float(np.clip(7.5 * aspect, 4.5, 11.0))), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    dx = (extent[1] - extent[0]) / z.shape[1]
    shade = hillshade(z, dx, dx)  # drawn with origin='lower': row 0 south
    ax.imshow(shade, cmap="gray", origin="lower", extent=extent, vmin=0, vmax=1, alpha=0.9)
    for poly in getattr(scn.field, "geoms", [scn.field]):
        ax.plot(*poly.exterior.xy, color="white", lw=1.5)
    p = scn.plants
    title = f"{scn.spec.name} (seed {scn.seed}): {len(p)} plants; {bg}"
    # markers a quarter metre across on paper, so rows read as rows at any field size
    fig.canvas.draw()
    per_m = ax.get_window_extent().width * 72.0 / dpi / (extent[1] - extent[0])
    dot = float(np.clip(0.25 * per_m, 1.0, 8.0)) ** 2
    if gazebo is not None and gazebo.mode == "tiles":
        from .tiles import make_tiles

        tiles = make_tiles(scn, opts.tile_plants)
        for t in tiles:  # the extent of what each tile holds
            x0, y0 = p.x[t.plants].min(), p.y[t.plants].min()
            w, h = p.x[t.plants].max() - x0, p.y[t.plants].max() - y0
            ax.add_patch(Rectangle((x0, y0), w, h, fill=False, ec="orange", lw=1.0, alpha=0.9))
        ax.scatter(p.x, p.y, s=dot, c="limegreen", linewidths=0)
        title += f"\nGazebo: {gazebo.tiles} merged static tiles (orange), {gazebo.triangles:,} tri"
    elif geotiff is not None and (geotiff.parent / "layers.gpkg").is_file():
        px, py = _gpkg_plants(scn, geotiff.parent / "layers.gpkg")
        sc = ax.scatter(px, py, s=dot, c=p.height, cmap="viridis", linewidths=0)
        fig.colorbar(sc, ax=ax, shrink=0.7, label="plant height (m)")
        title += "\nplants: layers.gpkg read back, projected into the GeoTIFF's CRS"
    else:
        sc = ax.scatter(p.x, p.y, s=dot, c=p.height, cmap="viridis", linewidths=0)
        fig.colorbar(sc, ax=ax, shrink=0.7, label="plant height (m)")
        if gazebo is not None:
            title += f"\nGazebo: one <include> per plant, {gazebo.models} models"
    if len(scn.obstacles):
        gpkg = geotiff.parent / "layers.gpkg" if geotiff is not None else None
        centres = None
        if gpkg is not None and gpkg.is_file():  # the GIS export: its own layer, read back
            centres = np.column_stack(_gpkg_points(scn, gpkg, "obstacles"))
        draw_obstacles(ax, scn.obstacles, per_m, centres)
    r = scn.route
    ax.plot(r.xy[:, 0], r.xy[:, 1], color="deepskyblue", lw=1.2, label="reference path")
    if waypoints is not None:
        idx, yaw = waypoints
        wx, wy = r.xy[idx, 0], r.xy[idx, 1]
        ax.quiver(wx, wy, np.cos(yaw), np.sin(yaw), color="red", scale=25, width=0.004)
        ax.scatter(wx, wy, color="red", s=18, zorder=3, label="GPS waypoints")
        for k, (x, y) in enumerate(zip(wx, wy, strict=True)):
            ax.annotate(
                str(k), (x, y), xytext=(3, 3), textcoords="offset points", color="red", fontsize=7
            )
    if spawn is not None:
        sx, sy, _, syaw = spawn
        c, s = np.cos(syaw), np.sin(syaw)
        hl, hw = FOOTPRINT[0] / 2, FOOTPRINT[1] / 2
        corners = [
            (sx + c * a - s * b, sy + s * a + c * b)
            for a, b in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))
        ]
        ax.add_patch(
            MplPolygon(corners, closed=True, fc="magenta", ec="k", lw=0.8, label="Summit-XL spawn")
        )
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x east (m, ENU at the datum)")
    ax.set_ylabel("y north (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
    fig.tight_layout()
    return fig
