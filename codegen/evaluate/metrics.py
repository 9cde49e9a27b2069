"""How good a velocity estimate is: the measures ``compare``, the scenarios and sweeps share.

All take the sample times t (N,), the estimate and the truth (N, n) (or (N,) for one joint),
and work on the error norm ||est_k - qd_k|| (rad/s) per sample unless said otherwise.

    rms_after(t, err, t0)              RMS of ||err|| over t >= t0
    convergence_time(t, err, level)    first time after which ||err|| stays below level
    settling_time(t, err, level)       first time after which the RMS of ||err|| over the last
                                       WINDOW s stays below level (a noisy estimate's own time)
    max_error(t, err, t0)              max ||err|| over t >= t0
    diverged(est, truth)               non-finite, or ||err|| beyond BLOWUP x (1 + max ||qd||)
    gain_lag(t, est, truth, t0)        least squares of est(t) = g qd(t - lag) over t >= t0
    summarize(...)                     all of them as one dict (a row of the compare table)
"""
from __future__ import annotations

import numpy as np

BLOWUP = 1e3
WINDOW = 0.1            # s: the window of settling_time's moving RMS


def _rows(a):
    a = np.asarray(a, dtype=float)
    return a[:, None] if a.ndim == 1 else a


def error_norm(err):
    """||err_k|| per sample (N,) of an (N, n) or (N,) error ``err``."""
    return np.linalg.norm(_rows(err), axis=1)


def _after(t, t0):
    t = np.asarray(t, dtype=float)
    mask = t >= t0
    if not mask.any():
        raise ValueError(f"t0 = {t0:g} s is after the last sample t = {t[-1]:g} s")
    return mask


def rms_after(t, err, t0=0.0):
    """sqrt(mean_k ||err_k||^2) over the samples with t_k >= t0 (rad/s); ``t`` (N,) sample times
    (s), ``err`` (N, n) or (N,) error."""
    e = _rows(err)[_after(t, t0)]
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


def max_error(t, err, t0=0.0):
    """max_k ||err_k|| over the samples with t_k >= t0 (rad/s); ``t`` (N,) sample times (s),
    ``err`` (N, n) or (N,) error."""
    return float(np.max(error_norm(_rows(err)[_after(t, t0)])))


def convergence_time(t, err, level):
    """First t_k after which ||err|| stays below ``level`` to the end (s); t_0 if always below,
    inf if the last sample is not. ``t`` (N,) sample times (s), ``err`` (N, n) or (N,) error."""
    t = np.asarray(t, dtype=float)
    above = np.nonzero(~(error_norm(err) < level))[0]          # NaN counts as above
    if len(above) == 0:
        return float(t[0])
    return float(t[above[-1] + 1]) if above[-1] + 1 < len(t) else float("inf")


def settling_time(t, err, level, window=WINDOW):
    """First t_k after which the moving RMS r_k = sqrt(mean ||err_j||^2 over t_k - window < t_j
    <= t_k) stays below ``level`` to the end (s); inf if the last one is not.

    Unlike ``convergence_time`` (every sample below the level), a noisy estimate whose samples
    cross the level now and then but whose RMS is below it has settled: the time measures the
    transient, not the noise's last excursion. ``t`` (N,) s, ``err`` (N, n) or (N,) rad/s,
    ``window`` s."""
    t = np.asarray(t, dtype=float)
    sq = np.concatenate([[0.0], np.cumsum(error_norm(err) ** 2)])
    first = np.searchsorted(t, t - window, side="right")          # oldest sample in the window
    k = np.arange(len(t))
    r = np.sqrt((sq[k + 1] - sq[first]) / (k + 1 - first))
    return convergence_time(t, r, level)


def diverged(est, truth):
    """True when the estimate ``est`` is non-finite somewhere, or its error to ``truth`` (both
    (N, n) or (N,), rad/s) exceeds ``BLOWUP`` x (1 + max ||qd||): it has left the scale of the
    motion."""
    est, truth = _rows(est), _rows(truth)
    if not np.all(np.isfinite(est)):
        return True
    return bool(np.max(error_norm(est - truth)) > BLOWUP * (1.0 + np.max(error_norm(truth))))


def gain_lag(t, est, truth, t0=0.0, max_lag=0.1):
    """Fit est(t) = g qd(t - lag) by least squares over t >= t0, all joints pooled.

    For each trial lag, qd(t - lag) is interpolated linearly between samples and g has a
    closed form; the lag minimising the residual is found on [-max_lag, max_lag] s
    (``scipy.optimize.minimize_scalar``, bounded), starting from the first-order estimate
    est ~ g qd - g lag qdd.

    Parameters
    ----------
    t : (N,) array
        Uniform sample times (s).
    est, truth : (N, n) or (N,) arrays
        Estimate and true velocity (rad/s).
    t0 : float
        Start of the fitted window (s).
    max_lag : float
        Largest |lag| considered (s).

    Returns
    -------
    (float, float)
        Gain g (1 is unbiased) and lag (s; > 0: the estimate is late).
    """
    from scipy.optimize import minimize_scalar

    t = np.asarray(t, dtype=float)
    est, truth = _rows(est), _rows(truth)
    m = _after(t, t0)
    E = est[m]
    if not np.all(np.isfinite(E)):
        return float("nan"), float("nan")

    def gain_and_residual(lag):
        S = np.column_stack([np.interp(t[m] - lag, t, truth[:, i]) for i in range(truth.shape[1])])
        ss = float(np.sum(S * S))
        g = float(np.sum(S * E)) / ss if ss > 0 else float("nan")
        return g, float(np.sum((E - g * S) ** 2))

    qdd = np.gradient(truth, t, axis=0)[m]
    X = np.column_stack([truth[m].ravel(), -qdd.ravel()])
    (g1, glag), *_ = np.linalg.lstsq(X, E.ravel(), rcond=None)
    lag1 = float(np.clip(glag / g1, -max_lag, max_lag)) if g1 else 0.0
    width = max(10 * (t[1] - t[0]), 2 * abs(lag1))
    lo, hi = max(-max_lag, lag1 - width), min(max_lag, lag1 + width)
    res = minimize_scalar(lambda lag: gain_and_residual(lag)[1], bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-7})
    lag = float(res.x)
    return gain_and_residual(lag)[0], lag


def summarize(t, est, truth, t_ss, level=1e-2):
    """The row of the compare table for one estimate.

    Parameters
    ----------
    t : (N,) array
        Sample times (s).
    est, truth : (N, n) arrays
        Estimate and true velocity (rad/s).
    t_ss : float
        Start of the steady-state window (s) for the RMS, max error and gain/lag fit.
    level : float
        Convergence threshold on ||err|| (rad/s).

    Returns
    -------
    dict
        rms, max (over t >= t_ss), t_conv and t_settle (s; ``convergence_time`` and
        ``settling_time`` at ``level``), gain, lag (s), diverged (bool).
    """
    est, truth = _rows(est), _rows(truth)
    err = est - truth
    bad = diverged(est, truth)
    g, lag = (float("nan"), float("nan")) if bad else gain_lag(t, est, truth, t_ss)
    return {"rms": rms_after(t, err, t_ss), "max": max_error(t, err, t_ss),
            "t_conv": convergence_time(t, err, level), "t_settle": settling_time(t, err, level), "gain": g, "lag": lag, "diverged": bad}
