"""Receiver faults under canopy: multipath position jumps and wrong-integer (false) RTK fixes.

Both are off by default (``GnssFixConfig.faults``); docs/localisation.md "GNSS faults" gives
each parameter's source or says it is assumed, with the range swept.

**Multipath jumps.** In RTK float and standalone the position solution follows reflected and
diffracted signals: at each fix epoch without a fault, a jump starts with probability
``1 − exp(−epoch · jump_rate_hz · (1 − q_carrier))`` — the rate grows with the share of the sky
whose signals reach the antenna through foliage. A jump is a horizontal offset, normal in east
and north with RMS size ``jump_float_m`` or ``jump_standalone_m``, held until it ends (mean
``jump_duration_s``, a constant hazard) or the fix mode changes. The receiver's reported
accuracy does not change.

**False fixes.** When the receiver climbs from float to fixed, the integer ambiguities it fixes
are wrong with probability ``false_fix_prob · (1 − q_carrier) / (1 − fixed_sky)`` (the full
probability where the clean sky is just enough to fix, none under open sky). A wrong fix is
reported as RTK fixed with the fixed mode's accuracy, but its position is off by a horizontal
offset of RMS ``false_fix_m``; the receiver detects it after a mean ``false_fix_duration_s``
and drops to float (then re-fixes as usual), or loses it earlier when the sky stops
supporting fixed.

Every draw comes from a stream of its own, spawned from the episode's generator at reset only
when a fault is switched on: with the faults off the receiver draws exactly as before.
"""

from __future__ import annotations

import math

import numpy as np

from scenario_gen.arrays import FloatArray

from ..config import GnssFixConfig
from .fixmode import FixModeChain

FLOAT, FIXED = 2, 3  # chain levels (interface.FIX_LEVELS: none, standalone, float, fixed)
JUMP, FALSE_FIX = "jump", "false_fix"


class ReceiverFaults:
    """The fault the receiver is in (none, a multipath jump or a false fix) and its offset."""

    def __init__(self, cfg: GnssFixConfig, epoch_s: float) -> None:
        self.cfg = cfg
        self.epoch_s = epoch_s
        self.p_end = {
            JUMP: 1.0 - math.exp(-epoch_s / cfg.jump_duration_s),
            FALSE_FIX: 1.0 - math.exp(-epoch_s / cfg.false_fix_duration_s),
        }
        self.rng = np.random.default_rng(0)
        self.kind: str | None = None
        self.level = 0  # the chain level the fault belongs to
        self.offset = np.zeros(3)
        #: counts since reset, for statistics: faults started, by kind; epochs in each
        self.started = {JUMP: 0, FALSE_FIX: 0}
        self.fixes = 0  # float -> fixed transitions (ambiguity fixes), right or wrong

    def reset(self, rng: np.random.Generator) -> None:
        self.rng = rng.spawn(1)[0]
        self._clear()
        self.started = {JUMP: 0, FALSE_FIX: 0}
        self.fixes = 0

    def _clear(self) -> None:
        self.kind = None
        self.offset = np.zeros(3)

    def step(self, before: int, chain: FixModeChain, q_carrier: float) -> FloatArray:
        """The offset of this epoch's fix after the chain stepped from level ``before``; a
        detected false fix drops ``chain`` to float."""
        c = self.cfg
        level = chain.level
        if self.kind is not None:
            if level != self.level:  # the solution changed: the fault goes with it
                self._clear()
            elif self.rng.random() < self.p_end[self.kind]:
                if self.kind == FALSE_FIX:  # detected: the receiver drops the wrong integers
                    chain.level = FLOAT
                self._clear()
                return self.offset
            else:
                return self.offset
        covered = min(1.0, max(0.0, 1.0 - q_carrier))
        if before == FLOAT and level == FIXED:
            self.fixes += 1
            if c.false_fix_prob > 0.0:
                p = c.false_fix_prob * min(1.0, covered / max(1.0 - c.fixed_sky, 1e-9))
                if self.rng.random() < p:
                    self._start(FALSE_FIX, level, c.false_fix_m)
        elif level in (1, FLOAT) and c.jump_rate_hz > 0.0:
            p = 1.0 - math.exp(-self.epoch_s * c.jump_rate_hz * covered)
            if self.rng.random() < p:
                self._start(JUMP, level, c.jump_float_m if level == FLOAT else c.jump_standalone_m)
        return self.offset

    def _start(self, kind: str, level: int, rms: float) -> None:
        self.kind, self.level = kind, level
        self.started[kind] += 1
        # east and north each N(0, rms²/2): the horizontal offset's RMS is ``rms``
        e, n = self.rng.standard_normal(2) * (rms / math.sqrt(2.0))
        self.offset = np.array([e, n, 0.0])
