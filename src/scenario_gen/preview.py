"""preview.png: hillshaded terrain, field, plants coloured by species and stage, obstacles by
kind, the route."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .arrays import FloatArray
from .model import Scenario
from .obstacles import LITTER, OBSTACLE_KINDS, STALK, STONE, Obstacles

#: Colour of each obstacle kind (sRGB 0-255) in the previews and the exports' materials:
#: weathered grey stone, bright blue plastic litter (which no crop or soil is, so it reads at a
#: glance), dry straw for a fallen stalk.
OBSTACLE_RGB: dict[str, tuple[int, int, int]] = {
    STONE: (132, 126, 118),
    LITTER: (40, 120, 220),
    STALK: (200, 172, 96),
}
#: plural labels for legends and counts (litter is its own plural)
OBSTACLE_LABELS = {STONE: "stones", LITTER: LITTER, STALK: "fallen stalks"}
assert set(OBSTACLE_RGB) == set(OBSTACLE_KINDS) == set(OBSTACLE_LABELS)


def render_preview(scn: Scenario, path: str | Path, dpi: int = 110) -> None:
    """Write preview.png."""
    preview_figure(scn, dpi).savefig(path, metadata={"Software": None})


def preview_figure(scn: Scenario, dpi: int = 110) -> Any:
    """The preview as a matplotlib ``Figure`` (no pyplot, no global state)."""
    import matplotlib as mpl
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import LightSource, Normalize
    from matplotlib.figure import Figure

    t = scn.terrain
    xmin, ymin, xmax, ymax = t.bounds
    aspect = (ymax - ymin) / max(xmax - xmin, 1e-9)
    model = scn.crop_model is not None
    fig = Figure(
        figsize=(12.0 if model else 10.0, float(np.clip(7.5 * aspect, 4.5, 11.0))), dpi=dpi
    )
    FigureCanvasAgg(fig)  # no pyplot: no global backend, no figure registry
    if model:  # a side panel for the user's plant model
        grid = fig.add_gridspec(1, 2, width_ratios=(5.0, 1.0))
        ax = fig.add_subplot(grid[0])
        _model_panel(fig.add_subplot(grid[1]), scn)
    else:
        ax = fig.add_subplot()
    ls = LightSource(azdeg=315, altdeg=45)
    rgb = ls.shade(
        t.heights,
        cmap=mpl.colormaps["gist_earth"],
        vert_exag=1.0,
        blend_mode="soft",
        dx=t.spacing,
        dy=t.spacing,
        fraction=0.6,
    )
    ax.imshow(rgb, origin="lower", extent=(xmin, xmax, ymin, ymax), interpolation="bilinear")
    sm = mpl.cm.ScalarMappable(
        cmap="gist_earth",
        norm=Normalize(scn.geo.alt + t.heights.min(), scn.geo.alt + t.heights.max()),
    )
    fig.colorbar(sm, ax=ax, shrink=0.7, label="elevation (m)")

    polys = getattr(scn.field, "geoms", [scn.field])
    first_hole = True
    for i, poly in enumerate(polys):  # every part of a MultiPolygon, with its holes
        fx, fy = poly.exterior.xy
        ax.plot(fx, fy, color="white", lw=1.5, label="field" if i == 0 else None)
        for ring in poly.interiors:
            hx, hy = ring.xy
            ax.fill(
                hx,
                hy,
                facecolor="none",
                edgecolor="white",
                hatch="xx",
                lw=1.0,
                label="hole (unplanted)" if first_hole else None,
            )
            first_hole = False
    p = scn.plants
    crop = ~p.is_weed
    # Markers sized like the canopy on paper, so the rows read as rows at any field size.
    fig.canvas.draw()
    points_per_m = ax.get_window_extent().width * 72.0 / dpi / (xmax - xmin)
    canopy = min(
        0.3 * float(np.median(p.height[crop])) if crop.any() else 0.3, 0.4 * scn.rows.spacing
    )
    size = float(np.clip(canopy * points_per_m, 1.0, 14.0)) ** 2
    if crop.any():
        sc = ax.scatter(
            p.x[crop],
            p.y[crop],
            c=p.height[crop],
            cmap="viridis",
            s=size,
            linewidths=0,
            alpha=0.9,
            label=f"{p.species[crop][0]} (colour: height)",
        )
        fig.colorbar(sc, ax=ax, shrink=0.7, label="plant height (m)")
    if (~crop).any():
        ax.scatter(
            p.x[~crop],
            p.y[~crop],
            color="orangered",
            s=size,
            marker="x",
            linewidths=0.6,
            label="weeds",
        )
    if len(scn.obstacles):
        draw_obstacles(ax, scn.obstacles, points_per_m)
    r = scn.route
    furrow = r.segment == "furrow"
    xy = r.xy.copy()
    ax.plot(
        *np.where(furrow[:, None], xy, np.nan).T,
        color="red",
        lw=1.8,
        label="route: furrow",
        zorder=4,
    )
    ax.plot(
        *np.where(~furrow[:, None], xy, np.nan).T,
        color="magenta",
        lw=1.6,
        label="route: headland",
        zorder=4,
    )
    ax.plot(*xy[0], "o", color="red", ms=6, zorder=5)
    ax.annotate("start", xy[0], color="white", xytext=(4, 4), textcoords="offset points")

    span = xmax - xmin
    bar = float(10 ** np.floor(np.log10(span / 4)))
    bx, by = xmin + 0.05 * span, ymin + 0.05 * (ymax - ymin)
    ax.plot([bx, bx + bar], [by, by], color="white", lw=3)
    ax.text(bx + bar / 2, by + 0.015 * span, f"{bar:g} m", color="white", ha="center")
    ax.annotate(
        "N",
        xy=(0.95, 0.93),
        xytext=(0.95, 0.83),
        xycoords="axes fraction",
        ha="center",
        color="white",
        fontweight="bold",
        arrowprops={"arrowstyle": "-|>", "color": "white"},
    )
    s = scn.summary()
    ax.set_title(
        f"{scn.spec.name} (seed {scn.seed}): {s['plants']} plants, {s['rows']} rows, "
        f"relief {s['relief_m']} m"
        + (
            f", slope {s['slope_deg']['median']}° (p90 {s['slope_deg']['p90']}°)"
            if "slope_deg" in s
            else ""
        )
        + f"\n datum {s['datum']} · {s['grid']}",
        fontsize=9,
    )
    ax.set_xlabel("east (m, ENU)")
    ax.set_ylabel("north (m, ENU)")
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize=7, framealpha=0.6)
    fig.tight_layout()
    return fig


def draw_obstacles(
    ax: Any, obs: Obstacles, points_per_m: float, centres: FloatArray | None = None
) -> None:
    """Obstacles on a plan view, each kind in the legend with its count: stones as grey discs,
    litter as blue squares, both their size on paper but at least 3 points across (a 10 cm
    stone is a fraction of a pixel over a whole field); fallen stalks as straw lines their
    horizontal reach long. ``centres`` (n, 2) replaces the obstacles' x, y (an export's
    preview drawing what it read back)."""
    from matplotlib import patheffects
    from matplotlib.collections import LineCollection

    xy = np.column_stack([obs.x, obs.y]) if centres is None else np.asarray(centres)
    for kind in OBSTACLE_KINDS:
        sel = obs.kind == kind
        n = int(sel.sum())
        if n == 0:
            continue
        rgb = np.array(OBSTACLE_RGB[kind]) / 255.0
        label = f"{OBSTACLE_LABELS[kind]} ({n})"
        if kind == STALK:
            half = 0.5 * obs.length[sel] * np.cos(obs.pitch[sel])
            d = np.column_stack([np.cos(obs.yaw[sel]), np.sin(obs.yaw[sel])]) * half[:, None]
            seg = np.stack([xy[sel] - d, xy[sel] + d], axis=1)
            lines = LineCollection(list(seg), colors=[rgb], linewidths=1.6, label=label, zorder=3.5)
            lines.set_path_effects([patheffects.withStroke(linewidth=2.8, foreground="0.15")])
            ax.add_collection(lines)
            continue
        across = np.clip(obs.length[sel] * points_per_m, 3.0, 12.0)
        ax.scatter(
            xy[sel, 0],
            xy[sel, 1],
            s=across**2,
            color=rgb,
            marker="o" if kind == STONE else "s",
            edgecolors="black" if kind == STONE else "white",
            linewidths=0.5,
            label=label,
            zorder=3.5,
        )


def _model_panel(panel: Any, scn: Scenario) -> None:
    """Side view of the user's plant model at the plants' median height, with its name and
    native size."""
    from matplotlib.collections import PolyCollection

    from .models import load_model

    um = scn.crop_model
    assert um is not None
    crop = ~scn.plants.is_weed
    height = float(np.median(scn.plants.height[crop])) if crop.any() else 1.0
    mesh = load_model(um.path, height, um.up_axis)
    faces = np.asarray(mesh.faces)
    step = max(1, len(faces) // 20000)  # a preview needs the silhouette, not every face
    v = np.asarray(mesh.vertices)
    tri = v[faces[::step]][:, :, [0, 2]]  # x (east) against z (up)
    panel.add_collection(
        PolyCollection(tri, facecolors="forestgreen", edgecolors="darkgreen", linewidths=0.1)
    )
    lo, hi = mesh.bounds
    half = max(hi[0] - lo[0], 0.5 * hi[2]) / 2 + 0.05 * height
    panel.set_xlim(-half, half)
    panel.set_ylim(0, hi[2] * 1.05)
    panel.set_aspect("equal")
    panel.set_xlabel("m", fontsize=7)
    panel.set_ylabel("height (m)", fontsize=7)
    panel.tick_params(labelsize=6)
    sx, sy, sz = um.size
    panel.set_title(
        f"crop.model\n{um.name}\nnative {sx:.3g} x {sy:.3g} x {sz:.3g}\nshown at {height:.2f} m",
        fontsize=7,
    )
