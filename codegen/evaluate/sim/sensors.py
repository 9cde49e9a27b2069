"""Sensor models: sample rate (zero-order hold), seeded Gaussian noise, quantisation.

    y_k = Delta round((q(t_k) + n_k) / Delta),  n_k ~ N(0, sigma^2)    [S000 Example 1a]

sampled every ``every`` simulation steps and held in between. The noise of sample j is the
j-th row of one table drawn from the seeded generator, so a run is reproducible and the
per-step cost is one add and one round.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Sensor:
    """Joint-position sensor (module docstring): sample-and-hold, seeded Gaussian noise, quantiser.

    Parameters
    ----------
    noise_std : float or (n,) array
        sigma per channel (rad); 0: no noise.
    quantum : float
        Quantisation step Delta (rad); 0: no quantisation.
    every : int
        Sample period in simulation steps (>= 1).
    seed : int
        Seed of the noise stream.
    """
    noise_std: float | np.ndarray = 0.0   # sigma per channel (rad), 0: no noise
    quantum: float = 0.0                  # Delta (rad), 0: no quantisation
    every: int = 1                        # sample period in simulation steps
    seed: int = 0
    _rng: np.random.Generator = field(init=False, repr=False)
    _held: np.ndarray | None = field(init=False, repr=False, default=None)
    _noise: np.ndarray | None = field(init=False, repr=False, default=None)

    def __post_init__(self):
        if self.every < 1 or self.quantum < 0 or np.any(np.asarray(self.noise_std) < 0):
            raise ValueError(f"bad sensor settings: {self}")
        self.reset()

    @property
    def noisy(self):
        return bool(np.any(np.asarray(self.noise_std) > 0))

    def reset(self):
        """Restart the noise stream from ``seed`` and forget the held sample."""
        self._rng = np.random.default_rng(self.seed)
        self._held = None
        self._noise = None

    def _noise_row(self, j, n):
        """Noise of sample j; the table grows (doubling) from the same seeded stream."""
        if self._noise is None or j >= len(self._noise):
            have = 0 if self._noise is None else len(self._noise)
            more = self._rng.normal(size=(max(1024, have, j + 1 - have), n)) * self.noise_std
            self._noise = more if self._noise is None else np.vstack([self._noise, more])
        return self._noise[j]

    def measure(self, k, q, out):
        """Measurement at simulation step k of the true value q, written into ``out``
        (left untouched between samples: the zero-order hold)."""
        if self._held is not None and k % self.every:
            return out
        out[:] = q
        if self.noisy:
            out += self._noise_row(k // self.every, len(out))
        if self.quantum > 0:
            np.round(out / self.quantum, out=out)
            out *= self.quantum
        self._held = out
        return out

    def __call__(self, k, q):
        """Measurement at simulation step k of the true value q (a new array)."""
        if self._held is None or k % self.every == 0:
            self.measure(k, q, np.empty(len(q)))
        return self._held.copy()


def measured(rec, quantization=0.0, noise=0.0, seed=0):
    """A recording as the sensor gives it: q of ``rec`` (the truth) sampled every sample with
    seeded Gaussian noise ``noise`` (rad) and quantised to ``quantization`` (rad); t, tau and
    the true qd kept.

    Parameters
    ----------
    rec : codegen.logs.recording.Recording
        The true run.
    quantization, noise : float
        Encoder step and Gaussian standard deviation (rad); 0: none.
    seed : int
        Seed of the noise.

    Returns
    -------
    codegen.logs.recording.Recording
    """
    from ...logs.recording import Recording
    sensor = Sensor(noise_std=noise, quantum=quantization, seed=seed)
    Y = np.empty_like(rec.q)
    for k, q in enumerate(rec.q):
        sensor.measure(k, q, Y[k])
    return Recording(t=rec.t, q=Y, tau=rec.tau, qd=rec.qd, joint_names=rec.joint_names)
