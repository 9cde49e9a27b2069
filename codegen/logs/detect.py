"""Collision thresholds set on a user's own collision-free log, for a stated false-alarm rate.

The momentum residual r_j of a contact-free log is noise and model error, its spread growing with
the joint's speed. Per joint the scale is fitted as s_j(v) = a_j + b_j |v| (non-negative least
squares of |r_j| on [1, |qd_hat_j|]; b_j = 0 for a joint the log does not move, the 95th percentile
of |qd_hat_j| below V_MOVING: its speed term would be extrapolated from noise); the normalised residual u = max_j |r_j| / s_j(qd_hat_j)
raises an alarm when it crosses a common level L, so the thresholds are

    th0_j = L a_j,   th1_j = L b_j        (alarm_j: |r_j| > th0_j + th1_j |qd_hat_j|)

L is where the episodes of u above L (an upcrossing and what follows until u falls back, episodes
closer than ``merge`` seconds one) happen at the rate R asked for (per hour of the log's time).
A log is too short to count one false alarm an hour, so the tail is extrapolated: the episodes'
peaks above a base level u0 (the highest of a few high quantiles of u with at least
``MIN_EPISODES`` episodes) follow a generalized Pareto law (Pickands' theorem; Coles, "An
Introduction to Statistical Modeling of Extreme Values", 2001, §4), rate(L) = nu0 (1 + xi (L - u0)
/ sigma)^(-1 / xi), nu0 the episode rate at u0. A residual of model error wanders slowly (a
friction torque held at rest, an inertia error along a move), so a log of a minute holds a few
dozen episodes, too few to fix xi (its standard error ~0.2 at 30 peaks): the level uses the
exponential tail xi = 0 (the Gumbel domain of Gaussian, exponential and gamma residuals), sigma the
mean excess, and reports the maximum-likelihood xi beside it:

    L = u0 + sigma ln(nu0 / R).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

FALSE_ALARMS = 1.0          # per hour of the log's time
MERGE = 0.05                # s: alarms closer than this are one episode
MIN_EPISODES = 30
V_MOVING = 0.05             # rad/s
QUANTILES = (0.999, 0.995, 0.99, 0.98, 0.95, 0.9, 0.8, 0.7, 0.6, 0.5)

__all__ = ["Thresholds", "calibrate", "episodes", "FALSE_ALARMS"]


@dataclass
class Thresholds:
    """Thresholds fitted on a collision-free log (module docstring): th0 (n,) N m, th1 (n,)
    N m s/rad, the level L, the tail fit (u0, nu0 per hour, xi as fitted and as used, sigma),
    the rate asked for, the log's duration (s), the largest u of the log and its episodes above L
    (about the rate times the duration)."""

    th0: list
    th1: list
    level: float
    u0: float
    nu0_per_hour: float
    xi_fit: float
    xi: float
    sigma: float
    false_alarms_per_hour: float
    duration: float
    u_max: float
    episodes_above_level: int
    scale_a: list
    scale_b: list

    def as_dict(self):
        """The fields as a JSON-able dict."""
        return asdict(self)


def episodes(t, above, merge=MERGE):
    """[(start, end)] index pairs (end inclusive) of the runs of ``above`` (N,) bools, runs whose
    gap is below ``merge`` seconds of the stamps ``t`` (N,) joined."""
    above = np.asarray(above, bool)
    if not above.any():
        return []
    d = np.diff(np.concatenate([[0], above.astype(int), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    out = [[starts[0], ends[0]]]
    for s, e in zip(starts[1:], ends[1:]):
        if t[s] - t[out[-1][1]] < merge:
            out[-1][1] = e
        else:
            out.append([s, e])
    return [(int(s), int(e)) for s, e in out]


def _scale(r, v):
    """(a, b) >= 0 of |r| ~ a + b |v| (non-negative least squares), a > 0; b = 0 when |v|'s 95th
    percentile is below V_MOVING."""
    from scipy.optimize import nnls
    if np.quantile(np.abs(v), 0.95) < V_MOVING:
        return max(float(np.mean(np.abs(r))), 1e-12), 0.0
    A = np.column_stack([np.ones(len(r)), np.abs(v)])
    (a, b), _ = nnls(A, np.abs(r))
    if not a > 0:
        a = max(float(np.mean(np.abs(r))), 1e-12)
    return float(a), float(b)


def _gpd(excess):
    """(xi, sigma): maximum-likelihood generalized Pareto fit of the excesses (> 0)."""
    from scipy.stats import genpareto
    xi, _, sigma = genpareto.fit(excess, floc=0.0)
    return float(xi), float(sigma)


def calibrate(t, r, qd_hat, false_alarms=FALSE_ALARMS, merge=MERGE):
    """Thresholds for the residuals of a collision-free log (module docstring).

    Parameters
    ----------
    t : (N,) array
        Time stamps (s).
    r, qd_hat : (N, n) arrays
        The residual (N m) and the velocity estimate (rad/s) of the momentum observer.
    false_alarms : float
        False alarms per hour allowed, > 0.
    merge : float
        Alarms closer than this (s) count as one.

    Returns
    -------
    Thresholds
    """
    t, r, v = np.asarray(t, float), np.atleast_2d(np.asarray(r, float)), np.atleast_2d(np.asarray(qd_hat, float))
    if not (np.isfinite(false_alarms) and false_alarms > 0):
        raise ValueError(f"false_alarms must be a positive rate per hour, got {false_alarms!r}")
    if r.shape != v.shape or r.shape[0] != len(t) or len(t) < 100:
        raise ValueError(f"calibrate: t (N,), r and qd_hat (N, n) of one log of at least 100 samples expected, "
                         f"got {t.shape}, {r.shape}, {v.shape}")
    ok = np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(v), axis=1)
    if ok.sum() < 100:
        raise ValueError("calibrate: fewer than 100 samples with a finite residual (the observer failed on the log)")
    t, r, v = t[ok], r[ok], v[ok]
    ab = [_scale(r[:, j], v[:, j]) for j in range(r.shape[1])]
    a, b = np.array([x[0] for x in ab]), np.array([x[1] for x in ab])
    u = np.max(np.abs(r) / (a + b * np.abs(v)), axis=1)
    hours = (t[-1] - t[0]) / 3600.0
    for q in QUANTILES:
        u0 = float(np.quantile(u, q))
        peaks = np.array([u[s:e + 1].max() for s, e in episodes(t, u > u0, merge)])
        if len(peaks) >= MIN_EPISODES:
            break
    if len(peaks) < 5:
        raise ValueError(f"calibrate: the log has {len(peaks)} excursions of the residual above its "
                         f"{QUANTILES[-1]:.0%} quantile; a longer collision-free log is needed")
    nu0 = len(peaks) / hours
    xi_fit, _ = _gpd(peaks - u0)
    xi, sigma = 0.0, float(np.mean(peaks - u0))          # the exponential tail's own fit
    L = float(u0 + sigma * np.log(nu0 / false_alarms))
    return Thresholds(th0=(L * a).tolist(), th1=(L * b).tolist(), level=L, u0=u0, nu0_per_hour=float(nu0),
                      xi_fit=xi_fit, xi=xi, sigma=float(sigma), false_alarms_per_hour=float(false_alarms),
                      duration=float(t[-1] - t[0]), u_max=float(u.max()),
                      episodes_above_level=len(episodes(t, u > L, merge)),
                      scale_a=a.tolist(), scale_b=b.tolist())
