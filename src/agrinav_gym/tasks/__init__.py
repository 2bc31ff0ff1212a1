"""Tasks: route, start pose and termination of an episode (see ``base``)."""

from .base import TASKS, TERMINATION_CHECKS, Task, task, termination_check
from .field_route import FieldRouteTask
from .furrow import FurrowFollowTask

__all__ = [
    "TASKS",
    "TERMINATION_CHECKS",
    "FieldRouteTask",
    "FurrowFollowTask",
    "Task",
    "task",
    "termination_check",
]
