"""Sensor models: sample rate (zero-order hold), seeded Gaussian noise, quantisation.

    y_k = Delta round((q(t_k) + n_k) / Delta),  n_k ~ N(0, sigma^2)    [S000 Example 1a]

sampled every ``every`` simulation steps and held in between.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Sensor:
    noise_std: float | np.ndarray = 0.0   # sigma per channel (rad), 0: no noise
    quantum: float = 0.0                  # Delta (rad), 0: no quantisation
    every: int = 1                        # sample period in simulation steps
    seed: int = 0
    _rng: np.random.Generator = field(init=False, repr=False)
    _held: np.ndarray | None = field(init=False, repr=False, default=None)

    def __post_init__(self):
        if self.every < 1 or self.quantum < 0 or np.any(np.asarray(self.noise_std) < 0):
            raise ValueError(f"bad sensor settings: {self}")
        self.reset()

    def reset(self):
        self._rng = np.random.default_rng(self.seed)
        self._held = None

    def __call__(self, k, q):
        """Measurement at simulation step k of the true value q."""
        if self._held is None or k % self.every == 0:
            y = np.asarray(q, dtype=float).copy()
            if np.any(np.asarray(self.noise_std) > 0):
                y = y + self._rng.normal(size=y.shape) * self.noise_std
            if self.quantum > 0:
                y = self.quantum * np.round(y / self.quantum)
            self._held = y
        return self._held.copy()
