"""Nav2's DWB local planner (Humble), faithfully, with a depth-camera voxel costmap.

Modules: ``params`` (Nav2's parameter names, validated), ``trajectories`` (XYThetaIterator and
StandardTrajectoryGenerator), ``costmap`` (voxel and inflation layers in a rolling window),
``critics`` (the dwb_critics), ``planner`` (DWBLocalPlanner's plan transform and scoring loop)
and ``policy`` (the controller server's loop on the env's observations). See docs/dwb.md.
"""

from .params import CRITICS, NAV2_CRITICS, DWBParams
from .policy import DWB, config_label

__all__ = ["CRITICS", "DWB", "NAV2_CRITICS", "DWBParams", "config_label"]
