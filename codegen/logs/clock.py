"""A log's sample clock, found from the data: the stamps a logger wrote, or the fixed tick the robot
sampled on.

A time column is not always the sampling time. A fixed-rate sampler (a robot's 1 kHz loop) read
by a non-realtime logger gets, in each row, the time the logger *received* it: the tick plus a
delay that jitters (and sometimes bunches rows that arrived together), rounded to the logger's
resolution; a row written before a new state arrived repeats the previous one. Differencing those
stamps as if they were sample times turns their jitter into velocity noise (a 0.4 ms error at
1 rad/s is 4e-4 rad, forty times a 1e-5 encoder noise). This module finds out which kind of log it
is and, for a fixed-rate sampler, rebuilds the sample clock from q itself.

**Repeated rows.** A row whose positions equal the previous row's bit for bit carries no new
sample, whatever its other columns say (a torque sensor read apart from the encoders, a counter or
a temperature change every row): with receive-time stamps it is dropped (a fixed-rate sampler of a
noisy or moving arm does not repeat itself to the last bit).

**A velocity signal.** When the log carries the robot's own velocity (``qdm``), it measures each
interval (codegen.logs.intervals): on a lattice of whole ticks the tick fit below takes over; a
counter that is not the sample clock gets each row's interval; sample-time stamps are kept.

**The tick model.** The kept rows j (stamps s_j) carry samples at ticks n_j (integers, strictly
increasing): s_j = c + n_j T + d_j with a delay d_j >= 0. Unknown: the period T, the offset c, the
ticks and the delays' distribution. The ticks are the most probable sequence (Viterbi) of a
hidden Markov model whose states are each row's candidate ticks (every n with d_j in the plausible
range of delays), with three terms per row:

    -log p(d_j)               the delays' distribution (a histogram of the current delays)
    -log P(n_j - n_j-1)       the increments' distribution (1 for every tick logged, 2 for one lost...)
    ||q_j - q^_j(c + n_j T)||^2 / (2 sigma^2)   (per joint, a Huber cost)

where q^_j is a cubic fitted, by least squares, to the neighbouring rows j-w..j+w without row j at
their current times (a leave-one-out prediction: exact for cubic motion, so only where the row
sits in time decides it). Starting from the stamps, the ticks, T (least-squares slope of s on n),
c (the zero-delay line under the stamps), sigma, both distributions and the neighbours' times are
re-estimated until the ticks no longer change (a few passes). The forward-backward posterior of
each row's tick says how sure the clock is (rows whose tick has posterior >= 0.99).

**Which clock.** The same leave-one-out residual, on the stamps and on the rebuilt ticks, decides:
the ticks are taken when they explain q better than the stamps by more than chance (the ratio of
the residuals' mean squares beyond 1 + 4 sqrt(2 / rows)) and most rows are certain; otherwise the
stamps are kept (a sampler that really jitters, or a log without motion to tell). A log whose
stamps are already uniform keeps them. A log with a robot-time column (``t_robot``) is read on it.

**The period** comes from q's whole-tick runs; the stamps' phase only sharpens it within that
estimate's own standard error (a logger polling at its own rate spreads the phase over a whole tick,
and a chance peak of it elsewhere is no period).

``rebuild(t, Q, ...)`` returns a ``Clock``: which rows are kept, their times, the ticks, and the
lines `describe` and `compare` print.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import intervals

MODES = ("auto", "stamps", "ticks")
ROBOT_TIME = "t_robot"          # a log's own sample-time column, when it has one
CERTAIN = 0.99                  # a row's tick is certain when its posterior is at least this
PASSES = 6                      # most passes of the tick re-estimation
_WINDOW = 12                    # neighbours on each side of the leave-one-out cubic
_MAX_CANDIDATES = 24            # ticks tried per row
_ROWS = 4096                    # rows per block of the local fits and the transitions: memory stays
                                # (rows x neighbours x joints), whatever the log's length


@dataclass
class Clock:
    """A log's sample clock.

    Attributes
    ----------
    kind : str
        "stamps" (the time column as written), "ticks" (rebuilt on a fixed tick) or "robot" (the
        log's robot-time column).
    kept : (M,) int array
        Indices of the log's rows that are samples (repeated rows dropped), increasing.
    t : (M,) array
        Their sample times (s): the stamps, or c + n T on the rebuilt tick.
    period : float or None
        The tick T (s) when rebuilt (or given).
    ticks : (M,) int array or None
        Tick of each kept row (from 0 at the first), when rebuilt.
    certain : float or None
        Fraction of the kept rows whose tick has posterior >= CERTAIN.
    delay : dict
        Of the stamps behind the ticks (s): mean, std, max, and the period's standard error
        ``period_std`` (the least-squares slope's: std / sqrt(sum (n - mean n)^2)) (rebuilt clock only).
    residual : dict
        RMS leave-one-out residual of q (rad, summed over joints) on the stamps and on the ticks.
    repeated : int
        Rows dropped as repeats of the previous row.
    reason : str
        Why this clock (one sentence).
    """

    kind: str
    kept: np.ndarray
    t: np.ndarray
    period: float | None = None
    ticks: np.ndarray | None = None
    certain: float | None = None
    delay: dict = field(default_factory=dict)
    residual: dict = field(default_factory=dict)
    repeated: int = 0
    rows: int = 0
    reason: str = ""
    stamps: np.ndarray | None = None        # the log's time column, every row
    glitches: list = field(default_factory=list)    # rows dropped as bad samples (``glitches``)
    unwrapped: list = field(default_factory=list)   # joints whose turns were unwrapped (recording)

    def row_of(self):
        """(rows,) int: for every row of the log, the kept row (index into ``kept``) whose sample
        it carries: itself, or for a dropped repeat the last kept row before it."""
        return np.searchsorted(self.kept, np.arange(self.rows), side="right") - 1

    @property
    def rebuilt(self):
        """True when the times are not the log's stamps."""
        return self.kind != "stamps"

    def describe(self):
        """One line: what the time column is and what was done with it."""
        wrap = f"; joint{'s' * (len(self.unwrapped) > 1)} {', '.join(self.unwrapped)} unwrapped (jumps of whole turns)"
        return self._describe() + wrap * bool(self.unwrapped) + (f"; {len(self.glitches)} row{'s' * (len(self.glitches) != 1)} dropped as "
                                   f"glitches (a jump off the neighbours and back: row "
                                   f"{', '.join(str(j + 1) for j in self.glitches[:5])}"
                                   f"{' ...' * (len(self.glitches) > 5)} of the data)" if self.glitches else "")

    def _describe(self):
        rep = (f"{self.repeated} repeated row{'s' * (self.repeated != 1)} "
               f"({100 * self.repeated / max(self.rows, 1):.1f} %) dropped, " if self.repeated else "")
        if self.kind == "ticks":
            d = self.delay
            return (f"clock: receive-time stamps: {1e3 * d['std']:.2g} ms std (mean {1e3 * d['mean']:.2g}, max "
                    f"{1e3 * d['max']:.2g} ms) behind a {1e3 * self.period:.4g} ms tick (+-{d['period_std'] / self.period:.1g} "
                    f"relative); {rep}clock rebuilt "
                    f"on the tick (ticks certain on {100 * self.certain:.1f} % of the rows; q's leave-one-out "
                    f"residual {self.residual.get('stamps', float('nan')):.3g} rad on the stamps, "
                    f"{self.residual.get('ticks', float('nan')):.3g} on the ticks)")
        if self.kind == "velocity":
            d = self.delay
            return (f"clock: the intervals the velocity signal qdm measures: the stamps' steps "
                    f"{1e6 * d['stamps_error']:.3g} us std off them; {rep}{d['corrected']} of "
                    f"{len(self.kept) - 1} intervals corrected ({1e6 * d['rms_change']:.3g} us RMS), "
                    f"{d['gross']} of them samples the stamps skipped or bunched")
        if self.kind == "robot":
            return f"clock: the robot-time column {ROBOT_TIME}; {rep}its stamps are the sample times"
        return f"clock: the stamps as written ({self.reason})"

    def to_dict(self):
        """JSON-ready summary (no per-row arrays)."""
        return {"kind": self.kind, "period": self.period, "certain": self.certain, "delay": self.delay,
                "residual": self.residual, "repeated": self.repeated, "rows": self.rows,
                "kept": len(self.kept), "reason": self.reason, "glitches": self.glitches, "unwrapped": self.unwrapped,
                "text": self.describe()}


def parse_mode(text):
    """``--clock`` text -> (mode, period or None): "auto", "stamps", "ticks" or "ticks=PERIOD" (s).

    >>> parse_mode("ticks=0.001")
    ('ticks', 0.001)
    """
    mode, eq, value = str(text).partition("=")
    mode = mode.strip()
    if mode not in MODES or (eq and mode != "ticks"):
        raise ValueError(f"clock: expected auto, stamps, ticks or ticks=PERIOD (s), got {text!r}")
    if not eq:
        return mode, None
    try:
        period = float(value)
    except ValueError:
        period = float("nan")
    if not (math.isfinite(period) and period > 0):
        raise ValueError(f"clock: ticks=PERIOD needs a positive period in seconds, got {value!r}")
    return mode, period


def repeated_rows(values):
    """(N,) bool: rows equal, bit for bit, to the previous row in every column of ``values``
    (N, k) (the first row never)."""
    v = np.asarray(values, dtype=float)
    out = np.zeros(len(v), bool)
    out[1:] = np.all(v[1:] == v[:-1], axis=1)
    return out


def rebuild(t, Q, qdm=None, mode="auto", period=None, t_robot=None):
    """The sample clock of a log (module docstring).

    Parameters
    ----------
    t : (N,) array
        The time column (s), non-decreasing (stamps may tie).
    Q : (N, n) array
        Positions (rad or m).
    qdm : (N, n) array, optional
        The robot's own velocity signal (rad/s): it measures each interval (codegen.logs.intervals),
        and a repeated row repeats it too. The other columns (torques, counters, temperatures) say
        nothing of whether a row carries a new sample: a torque sensor is read apart from the
        encoders, a counter changes every row.
    mode : {"auto", "stamps", "ticks"}
        auto: find out; stamps: the time column as written (stamps must increase strictly);
        ticks: rebuild on a fixed tick (``period`` given, or estimated).
    period : float, optional
        The tick (s) for mode "ticks".
    t_robot : (N,) array, optional
        The log's robot-time column: used as the clock (rows repeating a robot time dropped).

    Returns
    -------
    Clock
    """
    t = np.asarray(t, dtype=float).ravel()
    Q = np.asarray(Q, dtype=float)
    Q = Q[:, None] if Q.ndim == 1 else Q
    N = len(t)
    if mode not in MODES:
        raise ValueError(f"clock: expected one of {', '.join(MODES)}, got {mode!r}")
    if Q.shape[0] != N or N < 2:
        raise ValueError(f"Q: expected ({N}, n) positions for {N} stamps, got {Q.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(Q))):
        raise ValueError("t, Q: NaN or Inf")
    back = np.flatnonzero(np.diff(t) < 0)
    if len(back):
        k = back[0]
        raise ValueError(f"t: time stamps go back at sample {k + 1} (row {k + 3} of a file with a header): "
                         f"{t[k + 1]:.9g} after {t[k]:.9g} s")
    _check_unit(t)
    if qdm is not None:
        qdm = np.asarray(qdm, dtype=float).reshape(N, -1)
        if qdm.shape != Q.shape or not np.all(np.isfinite(qdm)):
            raise ValueError(f"qdm: expected {Q.shape} finite velocities, got {qdm.shape}")
    clock = _rebuild(t, Q, qdm, mode, period, t_robot, N)
    clock.stamps = t
    return clock


SLOWEST = 0.1           # s: a joint-state log's step is below this (a log at 10 Hz or less is not one)


def _check_unit(t):
    """ValueError when the time column's median step is SLOWEST or more: seconds it is not (a log in
    ms read as seconds is "a 1 Hz log", and every rate after it 1000 x off); the message names the
    unit that gives a rate between 10 Hz and 100 kHz."""
    steps = np.diff(t)
    step = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    if step < SLOWEST:
        return
    units = [(u, f) for u, f in (("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9)) if 1e-5 <= step * f <= 0.1]
    looks = (f"it looks like {units[0][0]} (a {1.0 / (step * units[0][1]):.4g} Hz log)" if units
             else "no unit gives a joint-state log's rate")
    raise ValueError(f"t: the median step is {step:.6g}, a {1.0 / step:.3g} Hz log if the time column is in "
                     f"seconds; {looks}: state the time column's unit (t_unit in the column mapping) or "
                     f"write it in seconds")


def _rebuild(t, Q, qdm, mode, period, t_robot, N):
    if t_robot is not None:
        return _robot_clock(np.asarray(t_robot, dtype=float).ravel(), N)
    bad = glitches(Q)
    clock = _clock(t, Q, qdm, mode, period, N, repeated_rows(Q), bad)
    clock.glitches = [int(j) for j in np.flatnonzero(bad)]
    return clock


def glitches(Q):
    """(N,) bool: rows of the positions ``Q`` (N, n) whose position jumps off their neighbours' and back, by more than ten times
    the log's own fastest step (the 99th percentile of |dq| a row, the largest over the joints: a
    still joint's is no scale) and twenty robust standard deviations: a bad sample no motion produces, dropped as one row (the rest of the log
    read as if it were not there). The neighbours' estimate is the median of the two rows on each
    side (a one-row glitch does not move it)."""
    N = len(Q)
    out = np.zeros(N, bool)
    if N < 5:
        return out
    nb = np.stack([Q[:-4], Q[1:-3], Q[3:-1], Q[4:]])                 # rows j-2, j-1, j+1, j+2
    r = np.zeros_like(Q)
    r[2:-2] = Q[2:-2] - np.median(nb, axis=0)
    fastest = float(np.max(np.quantile(np.abs(np.diff(Q, axis=0)), 0.99, axis=0)))
    sigma = 1.4826 * np.median(np.abs(r[2:-2]), axis=0)
    out = np.any((np.abs(r) > 10.0 * fastest) & (np.abs(r) > 20.0 * sigma), axis=1)
    return out


def _clock(t, Q, qdm, mode, period, N, rep, bad):
    if mode == "stamps":
        return _stamps(t, np.flatnonzero(~bad), "asked for (--clock stamps)", N)
    steps = np.diff(t)
    uniform = steps.min() > 0 and np.all(np.abs(steps - np.median(steps)) <= 1e-6 * np.median(steps))
    rep = rep & ~bad
    kept = np.flatnonzero(~rep & ~bad)
    lattice = False
    if mode == "auto" and qdm is not None and len(kept) >= 4 * _WINDOW and np.all(np.diff(t[kept]) > 0):
        clock, lattice = _velocity_clock(t, Q, qdm, kept, N, rep, uniform)
        if clock is not None:
            return clock
    if mode == "auto" and not lattice and uniform:
        return _stamps(t, np.flatnonzero(~bad), "uniform: every step the median step to 1e-6", N)
    if len(kept) < 4 * _WINDOW:
        if mode == "ticks":
            raise ValueError(f"clock: {len(kept)} distinct rows are too few to rebuild a tick clock "
                             f"(at least {4 * _WINDOW})")
        return _stamps(t, np.flatnonzero(~bad), f"too few distinct rows ({len(kept)}) to rebuild a tick", N)
    fit = _fit_ticks(t[kept], Q[kept], period, np.diff(kept) - 1)
    clock = Clock("ticks", kept, fit["c"] + fit["ticks"] * fit["T"], period=fit["T"],
                  ticks=fit["ticks"] - fit["ticks"][0], certain=fit["certain"], delay=fit["delay"],
                  residual={"stamps": fit["res_stamps"], "ticks": fit["res_ticks"]},
                  repeated=int(rep.sum()), rows=N)
    if mode == "ticks":
        clock.reason = "asked for (--clock ticks)"
        return clock
    M = len(kept)
    ratio = fit["res_stamps"] ** 2 / max(fit["res_ticks"] ** 2, 1e-300)
    needed = 1.0 + 4.0 * math.sqrt(2.0 / M)
    if ratio > needed and fit["certain"] >= 0.5:
        clock.reason = (f"q is {ratio:.3g} x smoother (mean square) on the ticks than on the stamps")
        return clock
    why = (f"q is no smoother on a fixed tick than on the stamps (mean-square ratio {ratio:.3g}, "
           f"chance allows {needed:.3g}): a sampler that jitters, or too little motion to tell")
    return _stamps(t, np.flatnonzero(~bad), why, N)


def _velocity_clock(t, Q, V, kept, N, rep, uniform):
    """(Clock or None, lattice): the intervals the velocity signal measures between the kept rows
    (codegen.logs.intervals), for a uniform time column (a counter need not be the sample clock;
    stamps that vary are the sampler's own times, or a logger's, rebuilt on the ticks), taken when q
    is smoother on them than on the stamps by more than chance (as for the ticks). On a lattice of
    whole ticks (9 in 10 of them within 3 standard errors of one, and twice as close as to the
    stamps' steps) the tick fit does better: (None, True). A signal whose intervals are not the stamps' scale
    (another unit), too few measured, or q no smoother: (None, False), the log read as without it."""
    s = t[kept]
    step = np.diff(s)
    h, se = intervals.measured(Q[kept], V[kept])
    T, z_lattice, z_stamps = intervals.lattice(h, se, step)
    if T is None or not 0.5 <= T / float(np.median(step)) <= 2.0:
        return None, False
    if z_lattice < min(3.0, 0.5 * z_stamps):
        return None, True
    if not uniform:
        return None, False              # stamps that vary are the sampler's own times (or a logger's: the ticks)
    dt, S, corrected, gross = intervals.combine(h, se, step)
    if not np.all(dt > 0):
        return None, False
    times = s[0] + np.concatenate([[0.0], np.cumsum(dt)])
    span = 4 * _WINDOW * float(np.median(step))
    res = {"stamps": _loo_residual(s, Q[kept], span)[0], "velocity": _loo_residual(times, Q[kept], span)[0]}
    ratio = res["stamps"] ** 2 / max(res["velocity"] ** 2, 1e-300)
    if S > 1e-6 * float(np.median(step)) and ratio <= 1.0 + 4.0 * math.sqrt(2.0 / len(kept)):
        return None, False              # q no smoother on them: a signal that lags or leads q
    rms = float(np.sqrt(np.mean((dt - step) ** 2)))
    clock = Clock("velocity", kept, times, repeated=int(rep.sum()), rows=N, residual=res,
                  delay={"stamps_error": S, "corrected": int(corrected.sum()), "gross": int(gross.sum()),
                         "rms_change": rms},
                  reason=(f"the velocity signal qdm measures the intervals: the stamps' steps are "
                          f"{1e6 * S:.3g} us off (std) where it tells"))
    if S <= 1e-6 * float(np.median(step)):
        return _stamps(t, np.union1d(kept, np.flatnonzero(rep)),
                       f"they agree with the intervals the velocity signal qdm measures", N), False
    return clock, False


def _stamps(t, kept, reason, N):
    if np.any(np.diff(t[kept]) <= 0):
        k = int(np.flatnonzero(np.diff(t[kept]) <= 0)[0])
        raise ValueError(f"t: time stamp repeats or goes back at row {k + 1} ({t[k + 1]:.9g} after "
                         f"{t[k]:.9g} s): as sample times the stamps must increase strictly; a logger's "
                         f"receive times may tie (--clock auto or ticks rebuilds the sample clock)")
    return Clock("stamps", kept, t[kept].copy(), rows=N, reason=reason)


def _robot_clock(tr, N):
    if len(tr) != N or not np.all(np.isfinite(tr)):
        raise ValueError(f"{ROBOT_TIME}: expected {N} finite robot times")
    rep = np.zeros(N, bool)
    rep[1:] = tr[1:] == tr[:-1]
    kept = np.flatnonzero(~rep)
    back = np.flatnonzero(np.diff(tr[kept]) < 0)
    if len(back):
        k = kept[back[0] + 1]
        raise ValueError(f"{ROBOT_TIME}: robot time goes back at row {k}: {tr[k]:.9g} s")
    return Clock("robot", kept, tr[kept].copy(), repeated=int(rep.sum()), rows=N,
                 reason=f"the log's robot-time column {ROBOT_TIME}")


# ------------------------------------------------------------------------------ the tick fit
def _by_rows(M, block):
    """``block(a, b)`` (a tuple of arrays over rows a..b-1) over the rows 0..M-1 in blocks of
    _ROWS, each array concatenated along its first axis."""
    parts = [block(a, min(a + _ROWS, M)) for a in range(0, max(M, 1), _ROWS)]
    return tuple(np.concatenate(p) for p in zip(*parts))


def _local_cubics(tau, Q, rows, at, offs, span, scale):
    """Least-squares cubics in time, one per row of ``rows``: through the rows ``rows + offs``
    (those inside the log and within ``span`` s of ``at``), centred at the times ``at`` and
    scaled by ``scale`` s. Returns (coefficients (len(rows), 4, n), ok: at least 6 rows)."""
    M = len(tau)
    idx = rows[:, None] + offs[None, :]
    inside = (idx >= 0) & (idx < M)
    idx = np.clip(idx, 0, M - 1)
    dtau = tau[idx] - at[:, None]
    if span is not None:
        inside &= np.abs(dtau) <= span
    u = dtau / scale
    V = np.stack([np.ones_like(u), u, u * u, u * u * u], axis=2) * inside[:, :, None]   # (rows, k, 4)
    A = np.einsum("mki,mkj->mij", V, V) + 1e-12 * np.eye(4)
    B = np.einsum("mki,mkn->min", V, Q[idx])
    ok = inside.sum(axis=1) >= 6
    A[~ok] = np.eye(4)
    return np.linalg.solve(A, B), ok


def _loo_cubic(tau, Q, w=_WINDOW, span=None):
    """Leave-one-out local cubics: for each row j, the least-squares cubic through rows j-w..j+w
    without j (times ``tau``, within ``span`` s of tau_j), as (centre, scale, coefficients
    (M, 4, n), ok (M,) bool: at least 6 neighbours)."""
    M = len(tau)
    offs = np.concatenate([np.arange(-w, 0), np.arange(1, w + 1)])
    scale = w * np.median(np.diff(tau)) if M > 1 else 1.0
    rows = np.arange(M)
    coef, ok = _by_rows(M, lambda a, b: _local_cubics(tau, Q, rows[a:b], tau[a:b], offs, span, scale))
    return tau, scale, coef, ok


def _predict(model, times):
    """The leave-one-out cubic of each row at ``times`` (M, K) -> (M, K, n)."""
    tau, scale, coef, _ = model
    u = (times - tau[:, None]) / scale
    P = np.stack([np.ones_like(u), u, u * u, u * u * u], axis=2)       # (M, K, 4)
    return np.einsum("mki,min->mkn", P, coef)


def _huber(z2, k=3.0):
    """Huber's cost of squared standardised residuals z2: z2/2 inside k, linear beyond."""
    z = np.sqrt(z2)
    return np.where(z <= k, 0.5 * z2, k * z - 0.5 * k * k)


def _sigma(res):
    """Robust scale per joint of residuals (M, n): 1.4826 MAD, at least a tiny floor."""
    med = np.median(res, axis=0)
    s = 1.4826 * np.median(np.abs(res - med), axis=0)
    return np.maximum(s, 1e-12 + 1e-9 * np.max(np.abs(res), axis=0))


def _loo_residual(tau, Q, span):
    """RMS over rows of ||q_j - loo cubic_j(tau_j)|| (rad): how well ``tau`` explains q."""
    model = _loo_cubic(tau, Q, span=span)
    r = Q - _predict(model, tau[:, None])[:, 0, :]
    ok = model[3]
    return float(np.sqrt(np.mean(np.sum(r[ok] ** 2, axis=1)))), r, ok


def _coherence(x, grid):
    """|mean_j exp(2 pi i x_j / T)| for each T of ``grid`` (summed in blocks of x and the grid:
    at most 2^20 terms at once)."""
    out = np.empty(len(grid))
    rows = max(1, min(len(x), 2 ** 20 // 256))
    for k in range(0, len(grid), 256):
        g = grid[k:k + 256]
        total = np.zeros(len(g), complex)
        for a in range(0, len(x), rows):
            total += np.exp(2j * np.pi * x[None, a:a + rows] / g[:, None]).sum(axis=1)
        out[k:k + 256] = np.abs(total / len(x))
    return out


def _period(s, Q, T0, span):
    """The tick T (s) of stamps ``s`` (M,) and positions ``Q`` (M, n), T0 the median step.

    First from q: the time between two rows that q implies, dt_j = v.dq_j / v.v (v the velocity of
    the cubic through their 4 x _WINDOW neighbours on each side, at the stamps), is a whole number
    of ticks; the most common value (the peak of dt_j's histogram over the faster half of the
    pairs, then the median within 20 % of it) is a first T. Over runs of at least 50 rows whose
    every dt_j is within a quarter tick of a whole number of ticks, the ticks are known: the
    least-squares slope of the stamps on them, pooled over the runs, is T. Then, when the stamps' phase is coherent enough to tell (|mean_j exp(2 pi i s_j /
    T)| above 4 / sqrt(rows): the delays spread the phase, they do not move its peak), T is
    refined to the coherence's peak, coarse to fine over growing parts of the log. Returns (T,
    True when the coherence gave it: precise to its peak's width over the whole log)."""
    v, ok = _pair_slopes(s, Q, w=4 * _WINDOW, span=4 * span)     # wide: the stamps' jitter averages out
    vv = np.sum(v * v, axis=1)
    dt = np.sum(v * np.diff(Q, axis=0), axis=1) / np.where(vv > 0, vv, np.inf)
    fast = ok & (vv > 0) & (vv >= np.median(vv[ok])) if np.any(ok) else ok
    T = T0
    width = None
    if np.count_nonzero(fast) >= 16:
        h, edges = np.histogram(dt[fast], bins=np.arange(0.2 * T0, 2.5 * T0, T0 / 50))
        peak = 0.5 * (edges[np.argmax(h)] + edges[np.argmax(h) + 1])
        near = dt[fast][np.abs(dt[fast] - peak) <= 0.2 * peak]
        T = float(np.median(near)) if len(near) else T0
        # whole ticks between the rows of runs of fast pairs: the stamps' slope on them is T
        inc = np.rint(dt / T)
        sure = fast & (inc >= 1) & (np.abs(dt / T - inc) < 0.25)
        num = den = 0.0
        runs = []
        j = 0
        while j < len(sure):
            if not sure[j]:
                j += 1
                continue
            k = j
            while k < len(sure) and sure[k]:
                k += 1
            if k - j >= 50:                 # rows j..k: ticks within the run, stamps s[j..k]
                n = np.concatenate([[0.0], np.cumsum(inc[j:k])])
                y = s[j:k + 1]
                nc = n - n.mean()
                num += float(nc @ (y - y.mean()))
                den += float(nc @ nc)
                runs.append((nc, y - y.mean()))
            j = k
        if den > 0:
            T = num / den
            # its standard error, from the stamps' scatter about each run's line
            res = np.concatenate([y - T * nc for nc, y in runs])
            width = 4.0 * float(np.std(res)) / math.sqrt(den)
    x = s - s[0]
    rows = min(len(x), 4000)
    lo, hi = 0.97 * T, 1.03 * T
    if width is not None:               # the stamps' phase only sharpens what q's ticks say
        lo, hi = T - width, T + width
        rows = len(x)
    while True:
        step = T * T / max(x[rows - 1], T) / 4
        grid = np.arange(lo, hi + step, step) if hi - lo > step else np.array([T])
        c = _coherence(x[:rows], grid)
        k = int(np.argmax(c))
        if c[k] <= 4.0 / np.sqrt(rows):
            return T, False
        if rows == len(x):
            return float(grid[k]), True
        lo, hi = grid[k] - 8 * step, grid[k] + 8 * step
        rows = min(len(x), 4 * rows)


def _pair_slopes(tau, Q, w=_WINDOW, span=None):
    """For each pair of consecutive rows (j-1, j): the velocity (M-1, n) at their midpoint of the
    least-squares cubic through rows j-1-w..j+w without the pair (times ``tau``, within ``span`` s
    of the midpoint), and ok (M-1,) (at least 6 neighbours)."""
    M = len(tau)
    offs = np.concatenate([np.arange(-w - 1, -1), np.arange(1, w + 1)])
    mid = 0.5 * (tau[1:] + tau[:-1])
    scale = w * float(np.median(np.diff(tau)))
    rows = np.arange(1, M)

    def block(a, b):
        coef, ok = _local_cubics(tau, Q, rows[a:b], mid[a:b], offs, span, scale)
        return coef[:, 1, :] / scale, ok
    return _by_rows(M - 1, block)


def _fit_ticks(s, Q, period=None, skipped=None):
    """The tick fit of the kept rows' stamps ``s`` (M,) and positions ``Q`` (M, n) (module
    docstring); ``skipped`` (M-1,): repeated rows dropped between consecutive kept rows (the
    increments' distribution is learned for 0, 1 and 2 or more of them apart: a repeat often
    stands for a tick that never reached the log). Returns a dict: ticks (M,) int, T, c,
    certain, delay, res_stamps, res_ticks."""
    M = len(s)
    steps = np.diff(s)
    T0 = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    if not T0 > 0:
        raise ValueError("clock: the stamps do not advance")
    span = 4 * _WINDOW * T0
    T, fixed = (float(period), True) if period is not None else _period(s, Q, T0, span)
    # the zero-delay line under the stamps, and a first assignment: the tick below each stamp
    phase = np.angle(np.sum(np.exp(2j * np.pi * (s - s[0]) / T))) / (2 * np.pi) * T
    c = s[0] + phase
    c = c + float(np.quantile(s - c - np.floor((s - c) / T) * T, 0.001)) - 0.05 * T
    n = np.floor((s - c) / T).astype(np.int64)
    for j in range(1, M):
        if n[j] <= n[j - 1]:
            n[j] = n[j - 1] + 1
    res_stamps = _loo_residual(s, Q, span)[0]
    dq = np.diff(Q, axis=0)                                               # (M-1, n)
    tau = s.copy()                      # the neighbours' times: the stamps in the first pass
    post = np.zeros(M)
    for it in range(PASSES):
        d = s - c - n * T
        hist = _histogram(d, T)
        d_hi = float(np.quantile(d, 0.999)) + 2 * T
        lo = np.floor((s - c - d_hi) / T).astype(np.int64)
        hi = np.ceil((s - c + 0.5 * T) / T).astype(np.int64)
        K = int(min(_MAX_CANDIDATES, max(2, np.max(hi - lo) + 1)))
        cand = lo[:, None] + np.arange(K)[None, :]                       # (M, K)
        emit = _delay_cost(s[:, None] - (c + cand * T), hist)
        emit[cand > hi[:, None]] = np.inf
        # the increments q sees: dq_j ~ v_mid,j (n_j - n_j-1) T
        v, ok = _pair_slopes(tau, Q, span=span)
        r = dq - v * (np.diff(n) * T)[:, None]
        sig = _sigma(r[ok])
        tables = _increment_tables(np.diff(n), skipped)

        def trans(a, b, cand=cand, v=v, ok=ok, sig=sig, T=T, tables=tables):
            """The transitions' costs (b-a, K prev, K cur) from rows a..b-1 to the next."""
            delta = cand[a + 1:b + 1, None, :] - cand[a:b, :, None]
            # a row's candidates are consecutive ticks: delta[r, i, j] = delta[r, 0, 0] + j - i takes
            # 2K - 1 values, so the fit is computed on those and spread (the same numbers, K/2 x fewer)
            k = cand.shape[1]
            d = delta[:, :1, :1] + np.arange(1 - k, k)                            # (b-a, 1, 2k-1)
            z2 = ((dq[a:b, None, None, :] - v[a:b, None, None, :] * (d[..., None] * T)) / sig) ** 2
            fit = _huber(z2).sum(axis=3)[:, 0, np.arange(k)[None, :] - np.arange(k)[:, None] + k - 1]
            fit[~ok[a:b]] = 0.0
            return _transitions(delta, tables, None if skipped is None else skipped[a:b]) + fit
        path = _viterbi(emit, trans)
        new = cand[np.arange(M), path]
        changed = int(np.sum(new - new[0] != n - n[0]))
        n = new
        if not fixed:                   # the stamps' slope on the ticks, the line under them
            T, c = (float(v) for v in np.polyfit(n.astype(float), s, 1))
        c += float(np.quantile(s - c - n * T, 0.001)) - 0.05 * T
        tau = c + n * T
        if changed == 0 or it == PASSES - 1:
            post = _posterior(emit, trans, path)
            break
    res_ticks = _loo_residual(tau, Q, span)[0]
    if period is None:                  # the ticks settled: the stamps' least-squares slope on them
        T, c = (float(v) for v in np.polyfit(n.astype(float), s, 1))
    c = c + float(np.min(s - c - n * T))
    d = s - c - n * T
    nc = n - n.mean()
    # the period's standard error: the least-squares slope's (the stamps' scatter about the ticks)
    period_std = 0.0 if period is not None else float(np.std(d) / np.sqrt(max(float(nc @ nc), 1.0)))
    return {"ticks": n, "T": float(T), "c": float(c), "certain": float(np.mean(post >= CERTAIN)),
            "delay": {"mean": float(np.mean(d)), "std": float(np.std(d)), "max": float(np.max(d)),
                      "period_std": period_std},
            "res_stamps": res_stamps, "res_ticks": res_ticks}


def _histogram(d, T):
    """The delays' distribution: (edges, -log density) on bins of T/10, smoothed, with a floor."""
    width = T / 10
    lo, hi = float(np.min(d)) - 2 * T, float(np.max(d)) + 2 * T
    edges = np.arange(lo, hi + width, width)
    h, _ = np.histogram(d, bins=edges)
    p = (h + 0.5) / (h.sum() + 0.5 * len(h)) / width
    p = np.convolve(p, np.array([0.25, 0.5, 0.25]), mode="same")
    return edges, -np.log(p)


def _delay_cost(dly, hist):
    """-log p(delay) per candidate (M, K) from the histogram; beyond it, its worst plus 5."""
    edges, cost = hist
    i = np.clip(np.searchsorted(edges, dly) - 1, 0, len(cost) - 1)
    outside = (dly < edges[0]) | (dly > edges[-1])
    return np.where(outside, cost.max() + 5.0, cost[i])


def _increment_table(inc, D=64):
    """-log P(increment) for increments 0..D (0: impossible, inf), from the current increments'
    histogram (Laplace-smoothed); increments beyond D cost the last entry plus log(increment / D)."""
    inc = np.asarray(inc)
    h = np.bincount(np.clip(inc, 1, D), minlength=D + 1)[1:].astype(float) + 0.5
    return np.concatenate([[np.inf], -np.log(h / h.sum())])


def _classes(skipped, count):
    """The class of each pair of consecutive kept rows: 0, 1 or 2 (2 or more) repeated rows
    ``skipped`` between them (all 0 without)."""
    return np.zeros(count, np.int64) if skipped is None else np.minimum(np.asarray(skipped), 2)


def _increment_tables(inc, skipped=None):
    """{class: -log P(increment)} (``_increment_table``) learned from the current increments
    ``inc`` (M-1,), separately for each class of pairs (``_classes``)."""
    cls = _classes(skipped, len(inc))
    return {int(k): _increment_table(inc[cls == k]) for k in np.unique(cls)}


def _transitions(delta, tables, skipped=None):
    """Transition costs (rows, K, K) of the increments ``delta`` between consecutive rows'
    candidates (prev, cur) by the ``tables`` of their class (``_increment_tables``; ``skipped``:
    the repeated rows between each pair)."""
    cls = _classes(skipped, len(delta))
    out = np.empty(delta.shape)
    for k in np.unique(cls):
        table = tables[int(k)]
        D = len(table) - 1
        d = delta[cls == k]
        o = table[np.clip(d, 0, D)]
        far = d > D
        if far.any():
            o[far] = table[-1] + np.log(d[far] / D)
        out[cls == k] = o
    return out


def _blocks(M, trans, reverse=False):
    """(j, trans(j -> j+1)) for j over 0..M-2 (reversed with ``reverse``), the costs computed
    by ``trans(a, b)`` in blocks of _ROWS transitions."""
    starts = range(0, M - 1, _ROWS)
    for a in (reversed(starts) if reverse else starts):
        tr = trans(a, min(a + _ROWS, M - 1))
        order = range(len(tr) - 1, -1, -1) if reverse else range(len(tr))
        for i in order:
            yield a + i, tr[i]


def _viterbi(emit, trans):
    """Index (M,) of the most probable candidate of each row (min-sum over ``emit`` (M, K) and
    the transitions ``trans(a, b)``: (b-a, K, K) from rows a..b-1 to the next)."""
    M, K = emit.shape
    back = np.zeros((M, K), np.int8 if K <= 127 else np.int64)
    score = emit[0].copy()
    cols = np.arange(K)
    for j, tr in _blocks(M, trans):
        tot = score[:, None] + tr
        back[j + 1] = np.argmin(tot, axis=0)
        score = tot[back[j + 1], cols] + emit[j + 1]
    path = np.empty(M, np.int64)
    path[-1] = int(np.argmin(score))
    for j in range(M - 1, 0, -1):
        path[j - 1] = back[j, path[j]]
    return path


def _posterior(emit, trans, path):
    """Posterior probability (M,) of each row's candidate ``path`` (forward-backward, costs as
    negative log-probabilities)."""
    M, K = emit.shape
    f = np.empty((M, K))
    f[0] = -emit[0]
    for j, tr in _blocks(M, trans):
        f[j + 1] = _lse(f[j][:, None] - tr, 0) - emit[j + 1]
    b = np.zeros((M, K))
    for j, tr in _blocks(M, trans, reverse=True):
        b[j] = _lse(-tr + (b[j + 1] - emit[j + 1])[None, :], 1)
    lp = f + b
    norm = _lse(lp, 1)
    with np.errstate(invalid="ignore"):
        post = np.exp(lp[np.arange(M), path] - norm)
    return np.where(np.isfinite(post), post, 0.0)


def _lse(a, axis):
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.squeeze(m, axis=axis) + np.log(np.sum(np.exp(a - m), axis=axis))
