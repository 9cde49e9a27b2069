"""What the estimates of a log are measured against when it has no true velocity: the offline
zero-phase reference (codegen.logs.smoothing.reference_velocity) with its own uncertainty, or the
true velocity of a simulation's log.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import smoothing


@dataclass
class Reference:
    """The velocity the estimates are measured against.

    Attributes
    ----------
    qd : (N, n) array
        The true velocity, or the zero-phase reference (rad/s).
    valid : (N,) bool array
        The samples measured on (all for the truth; away from the filter's edges otherwise).
    spread : (N, n) array or None
        The reference's spread |qd(fc/sqrt 2) - qd(fc sqrt 2)| (rad/s); None for the truth.
    cutoff : float or None
        Cut-off of the zero-phase reference (Hz); None for the truth.
    label : str
        What it is, for the table.
    """

    qd: np.ndarray
    valid: np.ndarray
    spread: np.ndarray | None
    cutoff: float | None
    label: str

    @property
    def is_truth(self):
        """True when the reference is the true velocity."""
        return self.spread is None

    def uncertainty(self, t, t0):
        """u = sqrt(mean_k ||spread_k||^2) over the valid samples with t_k >= t0 (rad/s); 0 for
        the truth. ``t`` (N,) sample times (s)."""
        if self.spread is None:
            return 0.0
        after = t[self.valid] >= t0
        if not after.any():
            raise ValueError(f"t0 = {t0:g} s is after the last valid sample t = {t[self.valid][-1]:g} s")
        s = self.spread[self.valid][after]
        return float(np.sqrt(np.mean(np.sum(s * s, axis=1))))


def reference_of(rec, cutoff=None, limit=None):
    """The Reference of a recording: its true velocity when it has one, else the zero-phase
    reference of ``smoothing.reference_velocity`` at ``cutoff`` Hz.

    A log with a pause (an interval longer than ``limit``: the methods restart after it,
    codegen.logs.tune.run_over) is smoothed one stretch at a time, each with its own edges left
    out of ``valid``: a spline through the pause would invent the motion during it.

    Parameters
    ----------
    rec : codegen.logs.recording.Recording
        On its sample clock (codegen.logs.clock).
    cutoff : float or (n,) array, optional
        Cut-off of the zero-phase reference (Hz), one for all joints or one per joint, used when
        ``rec.qd`` is None; default each joint's cut-off that balances the motion it loses against
        the noise it passes, on the spectrum measured on the log (codegen.logs.noise.reference_cutoff); kept below 0.45 / sqrt 2 of the sample
        rate and above 4 EDGE / the longest stretch's span (the reference keeps at least half of it).
    limit : float, optional
        The longest interval (s) smoothed across; default ``SPLIT_MAX`` x 2 x the median step,
        the interval after which the observers and the baselines restart.

    Returns
    -------
    Reference
    """
    from ..core.target import SPLIT_MAX
    from .tune import segments
    if rec.qd is not None:
        return Reference(rec.qd, np.ones(len(rec.t), bool), None, None,
                         "the true velocity (qd_<joint> columns)")
    limit = SPLIT_MAX * 2.0 * rec.dt if limit is None else float(limit)
    cuts_at = segments(rec.t, limit)
    parts = [(a, b) for a, b in zip(cuts_at[:-1], cuts_at[1:]) if b - a >= 8]     # smoothing's minimum
    span = max([rec.t[b - 1] - rec.t[a] for a, b in parts] or [0.0])
    if cutoff is None:
        from .noise import measure, reference_cutoff
        cutoff = reference_cutoff(measure(rec.t, rec.q))
    cuts = np.broadcast_to(np.asarray(cutoff, dtype=float), (rec.n,)).copy()
    if span > 0:
        cuts = np.clip(cuts, 4 * smoothing.EDGE / span, 0.45 / np.sqrt(2) / rec.dt)
    qd = np.zeros_like(rec.q)
    spread = np.zeros_like(rec.q)
    valid = np.zeros(len(rec.t), bool)
    for a, b in parts:
        inside = np.ones(b - a, bool)
        for c in np.unique(cuts):
            j = cuts == c
            qd[a:b, j], spread[a:b, j], v = smoothing.reference_velocity(rec.t[a:b], rec.q[a:b][:, j], float(c))
            inside &= v
        valid[a:b] = inside
    if not valid.any():
        raise ValueError(f"rec: {span:g} s is too short for the zero-phase reference at {cuts.min():g} Hz "
                         f"(it drops {smoothing.EDGE / cuts.min():g} s at each end)")
    at = (f"{cuts[0]:g} Hz" if np.all(cuts == cuts[0]) else
          f"{', '.join(f'{c:.3g}' for c in cuts)} Hz per joint")
    pauses = len(cuts_at) - 2
    label = (f"zero-phase Butterworth (order {smoothing.ORDER}, forward and backward) at {at} of q "
             f"resampled at the median step (no qd_<joint> columns); uncertainty: RMS of "
             f"|qd(fc / sqrt 2) - qd(fc sqrt 2)|; measured on t in [{rec.t[valid][0]:.6g}, "
             f"{rec.t[valid][-1]:.6g}] s"
             + (f", each of the {pauses + 1} stretches between pauses longer than {limit:.3g} s smoothed "
                f"on its own (its edges left out)" if pauses else ""))
    return Reference(qd, valid, spread, float(np.median(cuts)), label)
