"""The dataset card: README.md and a mosaic of frames with their labels drawn (rows, stems,
obstacles, the lane offset).

The card opens with the YAML front matter the Hugging Face Hub reads (licence, task
categories, size, and one ``data_files`` entry per split, so ``datasets.load_dataset`` with the
WebDataset builder finds the train, validation and test shards), then the spec, seeds, counts
and label statistics.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from scenario_gen.atomic import atomic_write
from scenario_gen.obstacles import OBSTACLE_KINDS

from ..report import mean_pm
from .loader import PerceptionDataset
from .run import MANIFEST

#: The data's licence: the project's own (pyproject.toml), an SPDX id the Hub understands.
LICENSE = "mit"


def _size_category(n: int) -> str:
    for hi, name in ((1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K")):
        if n < hi:
            return name
    return "100K<n<1M"


def front_matter(man: dict[str, Any], frames: int) -> list[str]:
    """The card's YAML front matter (Hugging Face dataset card metadata)."""
    import yaml

    meta = {
        "license": LICENSE,
        "pretty_name": "AgriNav perception dataset",
        "task_categories": ["depth-estimation", "image-segmentation"],
        "tags": ["agriculture", "robotics", "synthetic", "webdataset", "row-following"],
        "size_categories": [_size_category(frames)],
        "configs": [
            {
                "config_name": "default",
                "data_files": [
                    {"split": name, "path": list(s["shards"])}
                    for name, s in man.get("splits", {}).items()
                    if s["shards"]
                ],
            }
        ],
    }
    return ["---", yaml.safe_dump(meta, sort_keys=False).rstrip(), "---", ""]


def mosaic(ds: PerceptionDataset, path: Path, n: int = 6) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    picks = np.linspace(0, len(ds) - 1, min(n, len(ds))).round().astype(int)
    cols = 3
    rows = -(-len(picks) // cols)
    fig = Figure(figsize=(4.2 * cols, 2.6 * rows * 2), dpi=90)
    FigureCanvasAgg(fig)
    for k, i in enumerate(picks):
        s = ds[int(i)]
        lab = s["labels"]
        ax = fig.add_subplot(rows * 2, cols, (k // cols) * 2 * cols + k % cols + 1)
        ax.imshow(s["rgb"])
        for row in lab["rows"]:
            pts = np.array([p for p in row["points_2d_rgb"] if p is not None])
            if len(pts):
                ax.plot(pts[:, 0], pts[:, 1], "-", color="yellow", lw=1)
        for p in lab["plants"]:
            if p["base_2d_rgb"] is not None and p["visible_pixels"] > 0:
                colour = "magenta" if p["weed"] else "cyan"
                ax.plot(*p["base_2d_rgb"], "+", color=colour, ms=5)
        for o in lab.get("obstacles", []):  # schema 3
            box = o["bbox_2d_rgb"]
            if box is not None:
                u0, v0, u1, v1 = box
                ax.plot([u0, u1, u1, u0, u0], [v0, v0, v1, v1, v0], "-", color="red", lw=0.8)
        lane = lab["lane"]
        off = lane["lateral_offset"]
        ax.set_title(
            f"{lab['scenario']['species']} st.{lab['scenario']['stage']}  "
            + (f"lateral {off:+.2f} m" if off is not None else "no lane"),
            fontsize=8,
        )
        ax.axis("off")
        ax2 = fig.add_subplot(rows * 2, cols, (k // cols) * 2 * cols + cols + k % cols + 1)
        ax2.imshow(s["depth"], cmap="viridis", vmin=0, vmax=6)
        ax2.contour(s["instance"] >= 0, levels=[0.5], colors="white", linewidths=0.4)
        ax2.axis("off")
    fig.suptitle(
        "RGB with crop rows (yellow), stems (cyan; weeds magenta) and obstacles (red boxes) · "
        "depth with plant and obstacle outlines"
    )
    fig.tight_layout()
    fig.savefig(path, format="png")


def write_card(out: Path) -> None:
    """README.md and mosaic.png for the dataset in ``out``."""
    man = json.loads((out / MANIFEST).read_text())
    ds = PerceptionDataset(out, parse_labels=True)
    lateral: list[float] = []
    heading: list[float] = []
    plants: list[int] = []
    visible: list[int] = []
    species: dict[str, int] = {}
    # obstacles by kind: labelled (in view) and visible (pixels in the instance image)
    obstacles = {k: [0, 0] for k in OBSTACLE_KINDS}
    for i in range(len(ds)):
        j = ds.labels(i)
        for o in j.get("obstacles", []):
            seen = obstacles.setdefault(o["kind"], [0, 0])
            seen[0] += 1
            seen[1] += o["visible_pixels"] > 0
        if j["lane"]["lateral_offset"] is not None:
            lateral.append(j["lane"]["lateral_offset"])
            heading.append(j["lane"]["heading_offset"])
        plants.append(len(j["plants"]))
        visible.append(sum(p["visible_pixels"] > 0 for p in j["plants"]))
        sp = j["scenario"]["species"]
        species[sp] = species.get(sp, 0) + 1
    if len(ds):
        atomic_write(out / "mosaic.png", lambda tmp: mosaic(ds, tmp))

    spec = man["spec"]
    lines = [
        *front_matter(man, len(ds)),
        "# AgriNav perception dataset",
        "",
        f"Schema version {man['schema']} (docs/datasets.md), seed {man['seed']}, spec digest "
        f"`{man['digest']}`: {len(ds)} frames in {man['shards']} shards of "
        f"{man['frames_per_shard']}, {spec['width']}×{spec['height']} from `{spec['env']}` "
        f"driven by `{spec['policy']}` with a {spec['steer_noise']} rad/s steering perturbation.",
        "",
        "![frames](mosaic.png)",
        "",
        "| label | value |",
        "|---|---|",
        f"| frames per species | {', '.join(f'{k}: {v}' for k, v in sorted(species.items()))} |",
        f"| lateral offset to the lane centre, m | {mean_pm(lateral)} |",
        f"| heading offset to the rows, rad | {mean_pm(heading)} |",
        f"| plants labelled per frame | {mean_pm(plants)} |",
        f"| plants visible per frame | {mean_pm(visible)} |",
        "| obstacles labelled (visible) in all frames | "
        + ", ".join(f"{k}: {n} ({v})" for k, (n, v) in obstacles.items())
        + " |",
        "",
        "Spec:",
        "",
        "```json",
        json.dumps(spec, indent=1, default=list),
        "```",
        "",
        "## Splits",
        "",
        "Fields of each split come from their own scenario seed range, so validation and test",
        "frames show fields no training frame shows:",
        "",
        "| split | scenario seeds | shards |",
        "|---|---|---|",
        *(
            f"| {name} | [{s['scenario_seeds'][0]}, {s['scenario_seeds'][1]}) | "
            f"{len(s['shards'])} |"
            for name, s in man.get("splits", {}).items()
        ),
        "",
        "## Load it",
        "",
        "```python",
        "from baselines.dataset import PerceptionDataset",
        'train = PerceptionDataset(DIR, split="train")  # PyTorch default collation works',
        "```",
        "",
        "or, without this package, with the Hugging Face `datasets` WebDataset builder:",
        "`datasets.load_dataset(DIR)` (the splits are this card's `configs`).",
        "",
        f"Licence: {LICENSE.upper()} (the generated data, as the code that made it).",
        "",
    ]
    text = "\n".join(lines)
    atomic_write(out / "README.md", lambda tmp: tmp.write_text(text))
