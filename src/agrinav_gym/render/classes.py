"""The semantic classes every image and label file uses, named once.

The values are what segmentation images, the dataset's label files and the renderers store per
pixel; ``OTHER`` is sky or nothing within range. New classes are appended: a stored value never
changes meaning (datasets written before a class existed stay readable).
"""

from __future__ import annotations

from enum import IntEnum


class SemanticClass(IntEnum):
    OTHER = 0
    SOIL = 1
    CROP = 2
    WEED = 3
    ROBOT = 4
    OBSTACLE = 5  # stones, litter, fallen stalks (scenario_gen.obstacles)


OTHER, SOIL, CROP, WEED, ROBOT, OBSTACLE = (int(c) for c in SemanticClass)
CLASS_NAMES: dict[int, str] = {int(c): c.name.lower() for c in SemanticClass}
