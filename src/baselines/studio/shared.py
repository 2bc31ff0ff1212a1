"""What every studio tab shares (``Studio``): the start-up choices, the terrain layers, the site
cache and the images served to the page."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import layers
from .actions import MODELS_DIR
from .preview import SiteCache
from .session import Session, Terrain


@dataclass
class Studio:
    """What every tab shares: the start-up choices, the terrain layers and the site cache."""

    preset: str
    terrain: Terrain
    workspace: Path
    sites: SiteCache = field(default_factory=SiteCache)
    images: dict[str, bytes] = field(default_factory=dict)
    elevations: dict[Any, layers.Elevation] = field(default_factory=dict)

    def new_session(self) -> Session:
        return Session(preset=self.preset, terrain=self.terrain)

    def elevation(self, s: Session) -> layers.Elevation:
        t = s.spec().terrain
        key = (
            t.source,
            t.path,
            t.datum,
            t.up_axis,
            t.slope_deg,
            t.aspect_deg,
            t.fill_max_pixels,
            t.vertical_unit,
        )
        if key not in self.elevations:
            self.elevations[key] = layers.elevation_source(t)
        return self.elevations[key]

    def image_url(self, layer: layers.Layer) -> str:
        key = hashlib.sha1(layer.png).hexdigest()[:16]
        self.images[key] = layer.png
        return f"/studio/layer/{key}.png"

    @property
    def models_dir(self) -> Path:
        return self.workspace / MODELS_DIR
