"""RTK GNSS receiver (u-blox ZED-F9P-like) on the rear mast.

Error model per fix mode (datasheet: RTK 0.01 m + 1 ppm CEP horizontal and vertical;
standalone 1.5 m CEP): a time-correlated Gauss-Markov error per ENU axis whose horizontal CEP
equals the datasheet figure (σ per axis = CEP / 1.1774 for a circular normal), held between
updates at ``rate_hz``. The mode itself changes with the canopy over the antenna and multipath
(``sensors.fixmode``); on entering a mode its error starts from that mode's steady state.
Multipath jumps and wrong-integer fixes (``sensors.gnss_faults``) are opt-in.
A fix reaches the robot ``latency_s`` after its epoch (a fixed whole number of control steps)
and carries its age. Readings are real WGS84 coordinates through the scenario's geodesy.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..config import GnssConfig
from ..interface import GNSS_NONE, GNSS_RTK_FIXED, GNSS_RTK_FLOAT, GNSS_STANDALONE
from .fixmode import LEVELS, Canopy, FixModeChain, SkyModel
from .gnss_faults import ReceiverFaults
from .noise import GaussMarkov

CEP_TO_SIGMA = 1.0 / 1.1774  # CEP = 1.1774 σ for a circular bivariate normal


@dataclass(frozen=True)
class FixMode:
    cep: float  # horizontal CEP, m (before the ppm term)
    vertical: float  # vertical error, same convention
    tau: float  # correlation time, s


MODES = {
    GNSS_RTK_FIXED: FixMode(0.01, 0.01, 5.0),
    GNSS_RTK_FLOAT: FixMode(0.25, 0.5, 30.0),
    GNSS_STANDALONE: FixMode(1.5, 2.5, 60.0),
}


def error_sigma(cfg: GnssConfig, mode: str | None = None) -> NDArray[np.float64]:
    """Per-axis (east, north, up) error std of ``mode`` (default: the configured best mode)."""
    mode = cfg.mode if mode is None else mode
    m = MODES[mode]
    ppm = 1e-6 * cfg.baseline_km * 1000.0 if mode != GNSS_STANDALONE else 0.0
    h = (m.cep + ppm) * CEP_TO_SIGMA
    v = (m.vertical + ppm) * CEP_TO_SIGMA
    return np.array([h, h, v])


class Gnss:
    """Fixes every ``1/rate_hz``, delivered ``latency_s`` later, in the mode the sky allows.

    After ``step``: ``reading`` is the last delivered antenna fix (held between fixes),
    ``updated`` says whether one arrived this step, ``mode`` is the receiver status delivered
    with it ("none" while it has no fix), ``sigma`` the accuracy it reports, ``age`` the time
    since the reading's epoch.
    """

    def __init__(self, cfg: GnssConfig, control_dt: float) -> None:
        self.cfg = cfg
        self.dt = control_dt
        self.every = max(1, round(1.0 / (cfg.rate_hz * control_dt)))
        self.delay = round(cfg.latency_s / control_dt)
        epoch = self.every * control_dt
        self.errors = {m: GaussMarkov(error_sigma(cfg, m), MODES[m].tau, epoch, 3) for m in MODES}
        self.sigmas = {m: error_sigma(cfg, m) for m in MODES}
        self.chain = FixModeChain(cfg.fix, cfg.mode, epoch)
        self.faults = ReceiverFaults(cfg.fix, epoch) if cfg.fix.faults else None
        self.sky: SkyModel | None = None
        self._sky_at = np.full(3, np.inf)
        self._q = (1.0, 1.0)
        self._queue: deque[tuple[int, int, str, NDArray[np.float64] | None]] = deque()
        self.reading = np.zeros(3)
        self.sigma = self.sigmas[cfg.mode]
        self.mode = cfg.mode
        self.age = 0.0
        self.updated = False
        self._k = 0
        self._taken = 0

    def set_canopy(self, canopy: Canopy | None) -> None:
        """The crop the fix-mode model looks through (None or ``fix.model`` constant: open sky)."""
        use = canopy is not None and len(canopy) and self.cfg.fix.model == "canopy"
        self.sky = SkyModel(self.cfg.fix, canopy) if use and canopy is not None else None
        self._sky_at = np.full(3, np.inf)
        self._q = (1.0, 1.0)

    def usable_sky(self, antenna: NDArray[np.float64]) -> tuple[float, float]:
        """(q_carrier, q_code) at the antenna, recomputed when it moved ``fix.update_m``."""
        if self.sky is None:
            return 1.0, 1.0
        (ax, ay, az), (sx, sy, sz) = antenna.tolist(), self._sky_at.tolist()
        dx, dy = ax - sx, ay - sy
        moved = max(abs(dx), abs(dy), abs(az - sz)) > self.cfg.fix.update_m
        across = self.cfg.fix.across_row_update_m
        if not moved and across is not None:
            n = self.sky.canopy.across
            moved = abs(dx * float(n[0]) + dy * float(n[1])) > across
        if moved:
            self._q = self.sky.usable(antenna)
            self._sky_at = antenna.copy()
        return self._q

    def reset(self, true_enu: NDArray[np.float64], rng: np.random.Generator) -> None:
        self._sky_at = np.full(3, np.inf)
        self.mode = self.chain.reset(*self.usable_sky(true_enu))
        if self.faults is not None:
            self.faults.reset(rng)
        self._queue.clear()
        # the receiver was running before the episode, the robot at rest: its last fix (taken
        # one latency ago) is the start position
        self._k, self._taken = 0, -self.delay
        self.age = self.delay * self.dt
        if self.mode == GNSS_NONE:  # no fix yet: the reading is unknown (held at the origin)
            self.reading = np.zeros(3)
            self.sigma = np.full(3, np.inf)
            self.updated = False
            return
        self.reading = true_enu + self.errors[self.mode].reset(rng)
        self.sigma = self.sigmas[self.mode]
        self.updated = True

    def step(self, true_enu: NDArray[np.float64], rng: np.random.Generator, dt: float) -> None:
        self._k += 1
        if self._k % self.every == 0:
            self._epoch(true_enu, rng)
        self.updated = False
        while self._queue and self._queue[0][0] <= self._k:
            _, taken, mode, fix = self._queue.popleft()
            self.mode = mode
            if fix is not None:
                self.reading, self.sigma, self._taken = fix, self.sigmas[mode], taken
                self.updated = True
        self.age = (self._k - self._taken) * self.dt

    def _epoch(self, true_enu: NDArray[np.float64], rng: np.random.Generator) -> None:
        before = self.chain.level
        q = self.usable_sky(true_enu)
        mode = self.chain.step(*q, rng)
        offset = None
        if self.faults is not None:
            offset = self.faults.step(before, self.chain, q[0])
            mode = LEVELS[self.chain.level]
        fix = None
        if mode != GNSS_NONE:
            gm = self.errors[mode]
            err = gm.reset(rng) if self.chain.level != before else gm.step(rng)
            fix = true_enu + err if offset is None else true_enu + err + offset
        self._queue.append((self._k + self.delay, self._k, mode, fix))
