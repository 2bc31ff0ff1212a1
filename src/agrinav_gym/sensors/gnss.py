"""RTK GNSS receiver (u-blox ZED-F9P-like) on the rear mast.

Error model per fix mode (datasheet: RTK 0.01 m + 1 ppm CEP horizontal and vertical;
standalone 1.5 m CEP): a time-correlated Gauss-Markov error per ENU axis whose horizontal CEP
equals the datasheet figure (σ per axis = CEP / 1.1774 for a circular normal), held between
updates at ``rate_hz``. Readings are real WGS84 coordinates through the scenario's geodesy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..config import GnssConfig
from .noise import GaussMarkov

CEP_TO_SIGMA = 1.0 / 1.1774  # CEP = 1.1774 σ for a circular bivariate normal


@dataclass(frozen=True)
class FixMode:
    code: int
    cep: float  # horizontal CEP, m (before the ppm term)
    vertical: float  # vertical error, same convention
    tau: float  # correlation time, s


MODES = {
    "rtk_fixed": FixMode(2, 0.01, 0.01, 5.0),
    "rtk_float": FixMode(1, 0.25, 0.5, 30.0),
    "standalone": FixMode(0, 1.5, 2.5, 60.0),
}


def error_sigma(cfg: GnssConfig) -> NDArray[np.float64]:
    """Per-axis (east, north, up) error std for the configured mode and baseline."""
    m = MODES[cfg.mode]
    ppm = 1e-6 * cfg.baseline_km * 1000.0 if cfg.mode != "standalone" else 0.0
    h = (m.cep + ppm) * CEP_TO_SIGMA
    v = (m.vertical + ppm) * CEP_TO_SIGMA
    return np.array([h, h, v])


class Gnss:
    def __init__(self, cfg: GnssConfig, control_dt: float) -> None:
        self.cfg = cfg
        self.mode = MODES[cfg.mode]
        self.every = max(1, round(1.0 / (cfg.rate_hz * control_dt)))
        self.error = GaussMarkov(error_sigma(cfg), self.mode.tau, self.every * control_dt, 3)
        self.reading = np.zeros(3)
        self.age = 0.0
        self._k = 0
        self.updated = False

    def reset(self, true_enu: NDArray[np.float64], rng: np.random.Generator) -> None:
        self.reading = true_enu + self.error.reset(rng)
        self.age = 0.0
        self._k = 0
        self.updated = True

    def step(self, true_enu: NDArray[np.float64], rng: np.random.Generator, dt: float) -> None:
        self._k += 1
        self.updated = self._k % self.every == 0
        if self.updated:
            self.reading = true_enu + self.error.step(rng)
            self.age = 0.0
        else:
            self.age += dt
