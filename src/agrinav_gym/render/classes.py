"""The semantic classes every image and label file uses, named once.

The values are what segmentation images, the dataset's label files and the renderers store per
pixel; ``OTHER`` is sky or nothing within range.
"""

from __future__ import annotations

from enum import IntEnum


class SemanticClass(IntEnum):
    OTHER = 0
    SOIL = 1
    CROP = 2
    WEED = 3
    ROBOT = 4


OTHER, SOIL, CROP, WEED, ROBOT = (int(c) for c in SemanticClass)
CLASS_NAMES: dict[int, str] = {int(c): c.name.lower() for c in SemanticClass}
