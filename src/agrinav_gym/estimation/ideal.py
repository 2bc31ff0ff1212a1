"""Ground truth as the estimate: for debugging only — no real robot knows its pose exactly."""

from __future__ import annotations

import numpy as np

from .readings import FloatArray, Readings


class IdealEstimator:
    """Returns ``Readings.truth``: labelled ``ideal`` everywhere it is used."""

    name = "ideal"

    def __init__(self) -> None:
        self._pose = (0.0, 0.0, 0.0)

    def reset(self, x: float, y: float, yaw: float, rng: np.random.Generator) -> None:
        self._pose = (x, y, yaw)

    def update(self, r: Readings, dt: float) -> None:
        if r.truth is None:
            raise ValueError("the ideal estimator needs Readings.truth (ground truth)")
        self._pose = (float(r.truth[0]), float(r.truth[1]), float(r.truth[2]))

    @property
    def pose(self) -> tuple[float, float, float]:
        return self._pose

    @property
    def covariance(self) -> FloatArray:
        return np.zeros((3, 3))
