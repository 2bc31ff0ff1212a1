"""The AgriNav environments."""

from ..env import AgriNavEnv
from .field_route import FieldRouteEnv
from .furrow_follow import FurrowFollowDepthEnv, FurrowFollowEnv

__all__ = ["AgriNavEnv", "FieldRouteEnv", "FurrowFollowDepthEnv", "FurrowFollowEnv"]
