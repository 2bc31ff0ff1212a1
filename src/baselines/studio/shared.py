"""What every studio tab shares (``Studio``): the start-up choices, the terrain layers, the site
cache and the images served to the page."""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import layers
from .actions import MODELS_DIR
from .preview import SiteCache
from .session import Session, Terrain

#: The layer images kept for the page to fetch, newest first, up to this many bytes: a map
#: shows two (overview and detail), and a drawing session that moves the field about renders a
#: new detail layer each time, which must not grow the server without end.
IMAGE_BYTES = 64 * 1024 * 1024
#: Terrains kept open (a DEM is read whole: a 4,000-pixel square is 128 MB of heights).
ELEVATIONS = 3


@dataclass
class Studio:
    """What every tab shares: the start-up choices, the terrain layers and the site cache."""

    preset: str
    terrain: Terrain
    workspace: Path
    sites: SiteCache = field(default_factory=SiteCache)
    images: OrderedDict[str, bytes] = field(default_factory=OrderedDict)
    elevations: OrderedDict[Any, layers.Elevation] = field(default_factory=OrderedDict)

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
            while len(self.elevations) > ELEVATIONS:
                self.elevations.popitem(last=False)
        self.elevations.move_to_end(key)
        return self.elevations[key]

    def image_url(self, layer: layers.Layer) -> str:
        key = hashlib.sha1(layer.png).hexdigest()[:16]
        self.images[key] = layer.png
        self.images.move_to_end(key)
        total = sum(len(png) for png in self.images.values())
        while total > IMAGE_BYTES and len(self.images) > 2:
            total -= len(self.images.popitem(last=False)[1])
        return f"/studio/layer/{key}.png"

    @property
    def models_dir(self) -> Path:
        return self.workspace / MODELS_DIR
