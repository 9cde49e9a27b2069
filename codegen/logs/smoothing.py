"""Zero-phase (offline) derivatives of a sampled position: the velocity a log has no column for.

A real log has jittered time stamps and dropped samples and no true velocity. Offline, the whole
record is known, so the position can be smoothed without lag:

  1. q is interpolated (cubic, through every sample) onto a uniform grid of the median step h;
  2. a Butterworth low-pass of order 4 at ``cutoff`` Hz is run forward and backward
     (``scipy.signal.sosfiltfilt``: zero phase, the magnitude response squared, so -6 dB at the
     cut-off), with odd-extension padding against start-up transients;
  3. velocity and acceleration are central differences of the smoothed grid (``numpy.gradient``,
     second order), interpolated back (cubic) to the log's own time stamps.

What it cannot see: motion above the cut-off (attenuated) and noise below it (passed). Both
shrink as the cut-off moves toward the motion's bandwidth, so ``spread`` measures the reference's
own uncertainty as the difference between the velocities at cutoff/sqrt(2) and cutoff*sqrt(2).
The first and last EDGE/cutoff seconds (0.4 s at 10 Hz) hold the filter's edge transient (the odd
padding keeps value and slope, not curvature) and are marked False in ``valid``: the transient
falls about ten times per 1/cutoff from the end and reaches the interior's error after about four
(measured on a multi-sine of 0.1-1.5 Hz at 3, 5 and 10 Hz: 9e-3 to 3e-2 rad/s within 1/cutoff of
the end, 7e-5 to 2.5e-4 in the third 1/cutoff, 7e-6 to 4e-5 in the fourth, 1.4e-6 to 2e-5 inside).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ORDER = 4
EDGE = 4.0          # 1/cutoff seconds at each end left out of ``valid`` (module docstring)


@dataclass(frozen=True)
class Derivatives:
    """Smoothed position, velocity and acceleration at the log's time stamps.

    Attributes
    ----------
    t : (N,) s
    q, qd, qdd : (N, n) rad, rad/s, rad/s^2
    cutoff : float
        Hz, of the zero-phase low-pass.
    valid : (N,) bool
        False in the first and last ``EDGE/cutoff`` s (the filter's edges).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    cutoff: float
    valid: np.ndarray


def _check(t, q):
    t = np.asarray(t, dtype=float).ravel()
    q = np.asarray(q, dtype=float)
    q = q[:, None] if q.ndim == 1 else q
    if q.ndim != 2 or len(q) != len(t):
        raise ValueError(f"q: expected shape ({len(t)}, n) to match t, got {np.shape(q)}")
    if len(t) < 8:
        raise ValueError(f"t: need at least 8 samples to smooth, got {len(t)}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
        raise ValueError("t, q: NaN or Inf")
    if np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0))
        raise ValueError(f"t: time stamps must increase; t[{k + 1}] = {t[k + 1]:.9g} <= t[{k}] = {t[k]:.9g}")
    return t, q


def derivatives(t, q, cutoff):
    """Zero-phase smoothed q and its first two derivatives at the time stamps ``t``.

    Parameters
    ----------
    t : (N,) array
        Increasing time stamps (s), jitter and gaps allowed.
    q : (N, n) or (N,) array
        Positions (rad or m).
    cutoff : float
        Cut-off of the zero-phase Butterworth low-pass (Hz); below the Nyquist frequency of the
        median step.

    Returns
    -------
    Derivatives
    """
    from scipy.interpolate import CubicSpline
    from scipy.signal import butter, sosfiltfilt

    t, q = _check(t, q)
    h = float(np.median(np.diff(t)))
    nyquist = 0.5 / h
    cutoff = float(cutoff)
    if not (0 < cutoff < nyquist):
        raise ValueError(f"cutoff: {cutoff:g} Hz must lie in (0, {nyquist:g}) Hz, the Nyquist "
                         f"frequency of the median step {h:g} s")
    grid = t[0] + h * np.arange(int(np.floor((t[-1] - t[0]) / h)) + 1)
    Q = CubicSpline(t, q, axis=0)(grid)
    sos = butter(ORDER, cutoff / nyquist, output="sos")
    pad = min(len(grid) - 1, int(3 * nyquist / cutoff) * ORDER)
    Qs = sosfiltfilt(sos, Q, axis=0, padtype="odd", padlen=pad)
    V = np.gradient(Qs, h, axis=0, edge_order=2)
    A = np.gradient(V, h, axis=0, edge_order=2)
    back = lambda G: CubicSpline(grid, G, axis=0)(t)  # noqa: E731
    edge = EDGE / cutoff
    valid = (t >= t[0] + edge) & (t <= t[-1] - edge)
    return Derivatives(t=t, q=back(Qs), qd=back(V), qdd=back(A), cutoff=cutoff, valid=valid)


def reference_velocity(t, q, cutoff):
    """(qd, spread, valid): the offline reference velocity (N, n) at ``cutoff`` Hz, its
    uncertainty (N, n) = |qd(cutoff/sqrt 2) - qd(cutoff sqrt 2)| (rad/s), and the samples away
    from the filter's edges (N,) bool. ``t`` (N,) s and ``q`` (N, n) as in ``derivatives``."""
    mid = derivatives(t, q, cutoff)
    lo = derivatives(t, q, cutoff / np.sqrt(2))
    hi_cut = min(cutoff * np.sqrt(2), 0.45 / float(np.median(np.diff(mid.t))))
    hi = derivatives(t, q, hi_cut)
    return mid.qd, np.abs(hi.qd - lo.qd), mid.valid
