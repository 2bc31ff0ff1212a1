"""pybullet world built from a Scenario: terrain, robot, plants."""

import sys

from .quiet import quiet

with quiet(sys.stderr):  # the first import prints pybullet's build time from C
    import pybullet  # noqa: F401
