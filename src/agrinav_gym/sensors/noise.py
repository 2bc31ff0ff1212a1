"""First-order Gauss-Markov processes: time-correlated errors with a chosen stationary std."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


class GaussMarkov:
    """x_{k+1} = φ·x_k + σ·√(1−φ²)·w_k, φ = exp(−Δt/τ): stationary std σ, correlation time τ."""

    def __init__(
        self,
        sigma: NDArray[np.float64] | float,
        tau: NDArray[np.float64] | float,
        dt: float,
        size: int,
    ) -> None:
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=np.float64), (size,)).copy()
        tau_a = np.broadcast_to(np.asarray(tau, dtype=np.float64), (size,))
        self.phi = np.exp(-dt / tau_a)
        self.drive = self.sigma * np.sqrt(1.0 - self.phi * self.phi)
        self.x = np.zeros(size)
        self._phi, self._drive = self.phi.tolist(), self.drive.tolist()

    def reset(self, rng: np.random.Generator) -> NDArray[np.float64]:
        self.x = rng.standard_normal(len(self.x)) * self.sigma  # start in steady state
        return self.x

    def step(self, rng: np.random.Generator) -> NDArray[np.float64]:
        self.x = np.array(self.step_list(rng))
        return self.x

    def step_list(self, rng: np.random.Generator) -> list[float]:
        """``step`` as Python floats (a few elements cost less so than in numpy; the same
        arithmetic, element by element); ``x`` is updated too."""
        w = rng.standard_normal(len(self._phi)).tolist()
        x = [
            p * a + d * b
            for p, a, d, b in zip(self._phi, self.x.tolist(), self._drive, w, strict=True)
        ]
        self.x = np.array(x)
        return x
