"""The sample intervals a robot's own velocity signal measures (``qdm``), for codegen.logs.clock.

Between two consecutive samples the positions move by the integral of the velocity, so with the
trapezoid rule (v_j the mean of the two rows' velocity signals)

    dq_j = v_j h_j + e_j          (n joints; e_j the positions' and the signal's error)

and the interval's least-squares estimate and its standard error are

    h^_j = v_j . dq_j / |v_j|^2,      s_j = sigma / |v_j|,

sigma^2 the variance of e per joint, from the residuals dq_j - v_j h^_j across the joints (their
median over rows, n - 1 degrees of freedom a row). The time column's step d_j is a second
measurement of the same interval, wrong by its own error of variance S^2 (0 for sample times; a
logger's receive delays; a counter that is not the sample clock); S^2 is what the two disagree by
beyond s_j^2 (robust: the median of (h^_j - d_j)^2 / 0.455 less the median s_j^2). Each interval is
their precision-weighted mean,

    h_j = (d_j / S^2 + h^_j / s_j^2) / (1 / S^2 + 1 / s_j^2),

and where the two disagree grossly (beyond 4 joint standard deviations and by more than a quarter
of a step) with the measurement near another whole number of periods than the step (a sample the
log skipped, or two it bunched), the velocity's measurement alone, when it is precise (s_j below a
tenth of the step). Stamps that are sample times (S ~ 0) are kept as they are;
intervals on a lattice of whole ticks are left to the tick fit (``lattice``). Where the steps are
further off the intervals than the measurement's own error (a counter that is not the sample clock),
the steps say nothing more than the period: each interval is then its posterior mean under the
intervals' own distribution, learned from the log (``_posterior``).
"""
from __future__ import annotations

import numpy as np

PRECISE = 0.1           # an interval is measured when its standard error is below this part of a step
GROSS = 0.25            # ... and disagrees grossly with the step when by more than this part of it


def measured(Q, V):
    """(h^ (M-1,), s (M-1,)): the intervals between consecutive rows of positions ``Q`` (M, n)
    that the velocity signal ``V`` (M, n) measures, and their standard errors (inf where the
    signal is zero, or for a single joint: no residual to tell the error by)."""
    dQ = np.diff(Q, axis=0)
    v = 0.5 * (V[1:] + V[:-1])
    vv = np.sum(v * v, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(vv > 0, np.sum(dQ * v, axis=1) / np.where(vv > 0, vv, 1.0), np.nan)
    n = Q.shape[1]
    if n < 2 or not np.any(vv > 0):
        return h, np.full(len(h), np.inf)
    r = dQ - v * np.nan_to_num(h)[:, None]
    sigma2 = float(np.median(np.sum(r * r, axis=1)[vv > 0])) / (n - 1)
    with np.errstate(divide="ignore"):
        s = np.where(vv > 0, np.sqrt(max(sigma2, 1e-300) / np.where(vv > 0, vv, 1.0)), np.inf)
    return h, s


def lattice(h, s, step):
    """(period, z_lattice, z_stamps): the measured intervals ``h`` (standard errors ``s``) against
    whole multiples of one period (the median of h / k over the precise ones, k the nearest whole
    number of ``step``) and against the steps themselves: the median standardized distance of each
    (inf when too few intervals are precise)."""
    step = np.asarray(step, float)
    P = np.isfinite(h) & (s < PRECISE * step)
    if np.count_nonzero(P) < 16:
        return None, np.inf, np.inf
    T0 = float(np.median(step))
    k = np.maximum(1.0, np.rint(h[P] / T0))
    T = float(np.median(h[P] / k))
    k = np.maximum(1.0, np.rint(h[P] / T))
    z90 = lambda d: float(np.quantile(np.abs(d) / s[P], 0.9))       # noqa: E731
    return T, z90(h[P] - k * T), z90(h[P] - step[P])


def combine(h, s, step):
    """(intervals (M-1,), stamps' error S, corrected: (M-1,) bool, gross: (M-1,) bool): each
    interval the precision-weighted mean of the stamps' ``step`` and the velocity's measurement ``h``
    (standard error ``s``; module docstring)."""
    step = np.asarray(step, float)
    ok = np.isfinite(h) & np.isfinite(s)
    P = ok & (s < PRECISE * step)
    d = np.where(ok, h - step, 0.0)
    S2 = max(float(np.median(d[P] ** 2)) / 0.455 - float(np.median(s[P] ** 2)), 0.0) if P.any() else 0.0
    S2 = max(S2, (1e-9 * float(np.median(step))) ** 2)
    if P.any() and S2 > float(np.median(s[P] ** 2)):
        out = _posterior(h, s, step, P)         # the stamps are not the sample clock
        return out, float(np.sqrt(S2)), np.abs(out - step) > 1e-12 * step, np.zeros(len(h), bool)
    w = np.where(ok, S2 / (S2 + np.where(ok, s, 1.0) ** 2), 0.0)     # the velocity's weight
    out = step + w * d
    # a skipped sample (or two bunched): the measurement near another whole number of periods than the step
    T = float(np.median(h[P])) if P.any() else float(np.median(step))
    k = np.rint(np.where(ok, h, 0.0) / T)
    tol = 4.0 * np.sqrt(S2 + np.where(ok, s, 0.0) ** 2)
    gross = (P & (np.abs(d) > tol) & (np.abs(d) > GROSS * step) & (k != np.rint(step / T))
             & (np.abs(np.where(ok, h, 0.0) - k * T) < tol))
    out[gross] = h[gross]
    return out, float(np.sqrt(S2)), ok & (np.abs(out - step) > 1e-12 * step), gross


def _posterior(h, s, step, P):
    """Each interval's posterior mean under the intervals' own distribution (empirical Bayes: a
    histogram of the sharper half of the measured intervals, bins of their median standard error)
    times the measurement's likelihood N(h_j; x, s_j^2); an interval the signal cannot measure
    (s_j = inf) gets the distribution's mean within half a period of its step."""
    sharp = P & (s <= np.median(s[P]))
    T = float(np.median(h[sharp]))
    width = max(float(np.median(s[sharp])), 1e-3 * T)
    x = np.arange(0.0, 3.0 * T + width, width)
    counts = np.histogram(h[sharp], bins=np.append(x - width / 2, x[-1] + width / 2))[0].astype(float)
    prior = np.convolve(counts, [0.25, 0.5, 0.25], mode="same") + 1e-3 * counts.sum() / len(x)
    prior[0] = 0.0                              # no interval is empty
    out = np.empty(len(h))
    for a in range(0, len(h), 2048):            # (rows, grid) in blocks
        b = min(a + 2048, len(h))
        hj, sj, st = h[a:b, None], s[a:b, None], step[a:b, None]
        known = np.isfinite(hj) & np.isfinite(sj)
        with np.errstate(invalid="ignore", over="ignore"):
            ll = np.where(known, -0.5 * ((np.nan_to_num(hj) - x) / np.where(known, sj, 1.0)) ** 2,
                          np.where(np.abs(x - st) < 0.5 * T, 0.0, -np.inf))
        ll -= ll.max(axis=1, keepdims=True)
        w = prior * np.exp(ll)
        out[a:b] = (w @ x) / w.sum(axis=1)
    return out
