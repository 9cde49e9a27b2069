"""Gains chosen on the user's log, without truth: forward validation of the velocity.

A causal estimate qd_hat_k uses the samples up to k. The samples after k were not seen by it:
the velocity they imply at t_k,

    P_k = d/dt of the least-squares cubic through q_k+1 .. q_k+m (at their times), at t = t_k,

is an independent, noisy but (up to the cubic's bias) unbiased measurement of qd(t_k). So

    J = mean_k ||qd_hat_k - P_k||^2 = mean_k ||qd_hat_k - qd_k||^2 + mean_k ||P_k - qd_k||^2 + o(1)

(the cross term vanishes: P's noise is the future samples', independent of everything qd_hat_k
saw) ranks estimators exactly as their true mean-square error does, and J - C, C the second term
(P's noise sigma^2 sum_i w_i^2 through its weights w, plus its bias), estimates that error
itself: a prediction-error criterion in the sense of Ljung (System Identification, 1999, §7),
scored on held-out (future) samples rather than on the one-step innovation. The window m is
chosen on the log: the m whose P has the least predicted error, sigma^2 sum w_i^2 (the measured
noise) plus its bias on the measured spectrum of q, integral |H_m(f) - 2 pi i f|^2 S_q(f) df
(H_m the transfer function of P's weights).

Each family's gains scale with one bandwidth s (``TUNE`` in the family's module: parameter ->
exponent, e.g. nicosia_tomei's kd ~ s, kp ~ s^2), searched in log(s) from its designed value
(a coarse grid, then golden sections around the best), each candidate a run of the compiled
observer over the log; a family with a model and a model-free variant (kalman_model) tunes both
and keeps the better one (the model is used only where it lowers J). The baselines' own
parameters are searched the same way.

The candidates run unchecked; the chosen one must pass the stability check over the declared step
range. When the best candidates are refused, the best accepted one is moved toward the nearest
refused scale by bisection in log(s) (``BOUNDARY`` steps, each midpoint kept when it is stable and
scores better): the constrained optimum then sits at the stability bound, which the coarse grid
(steps of 2.4x) can miss by half an octave (nicosia_tomei on an 8 s ur5 log: 1.67x its best
admissible error without the bisection).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

DEGREE = 3
WINDOWS = tuple(sorted({int(round(4 * 2 ** (k / 2))) for k in range(0, 15)}))   # 4 .. 512 rows, x sqrt 2
GRID = 9                    # coarse candidates of a bandwidth search
RANGE = 32.0                # searched within [s0 / RANGE, s0 * RANGE] of the first guess s0
GOLDEN = 8                  # golden-section steps after the coarse grid
BOUNDARY = 6                # bisections toward the stability bound when better candidates are refused


def _forward_weights(t, idx, inside, tk):
    """Weights (M, m) of the derivative at tk of the LS cubic through q at t[idx] (masked by
    ``inside``)."""
    dt = t[idx] - tk[:, None]
    scale = np.maximum(np.max(np.abs(dt) * inside, axis=1), 1e-300)[:, None]
    u = dt / scale
    V = np.stack([u ** p for p in range(DEGREE + 1)], axis=2) * inside[:, :, None]     # (M, m, 4)
    A = np.einsum("mki,mkj->mij", V, V) + 1e-12 * np.eye(DEGREE + 1)
    e1 = np.zeros(DEGREE + 1)
    e1[1] = 1.0
    c = np.linalg.solve(A, np.broadcast_to(e1, (len(tk), DEGREE + 1))[..., None])[..., 0]   # (M, 4)
    return np.einsum("mki,mi->mk", V, c) / scale


def window_error(m, h, sigma, psd):
    """Predicted mean-square error (n,) of P with window m on a uniform grid h (s): the noise
    sigma^2 sum w^2 plus the bias integral |H(f) - 2 pi i f|^2 S(f) df over the motion's PSD
    ``psd`` = (f (F,), S (F, n)) (q's, less its noise floor; codegen.logs.noise.motion_psd)."""
    k = np.arange(1, m + 1)
    w = _forward_weights(k * h, k[None, :] - 1, np.ones((1, m), bool), np.zeros(1))[0]
    f, S = psd
    H = np.exp(2j * np.pi * np.outer(f, k * h)) @ w
    bias = np.trapezoid(np.abs(H - 2j * np.pi * f)[:, None] ** 2 * S, f, axis=0)
    return np.asarray(sigma) ** 2 * float(w @ w) + bias


@dataclass
class Validation:
    """Forward validation of velocity estimates on one log (module docstring).

    Attributes
    ----------
    t : (N,) array
        The log's sample times (s, its clock).
    P : (N, n) array
        The velocity the next m samples imply at each row (rad/s).
    valid : (N,) bool
        Rows with m following samples within reach (no gap in them), after ``t_from``.
    constant : float
        Predicted mean of ||P - qd||^2 (rad^2/s^2): P's own noise and bias.
    window : int
        m.
    """

    t: np.ndarray
    P: np.ndarray
    valid: np.ndarray
    constant: float
    window: int
    details: dict = field(default_factory=dict)

    def score(self, est, t_from=None):
        """J: mean over the valid rows (t >= t_from) of ||est - P||^2 ((rad/s)^2); inf when the
        estimate is not finite there."""
        v = self.valid if t_from is None else self.valid & (self.t >= t_from)
        e = np.asarray(est, dtype=float)[v] - self.P[v]
        if not np.all(np.isfinite(e)):
            return math.inf
        return float(np.mean(np.sum(e * e, axis=1)))

    def rms(self, est, t_from=None):
        """The estimate's RMS error ||est - qd|| implied by J: sqrt(max(J - constant, 0)) (rad/s);
        ``est`` (N, n), rows from ``t_from`` (s) as ``score``."""
        J = self.score(est, t_from)
        return math.sqrt(max(J - self.constant, 0.0)) if math.isfinite(J) else math.inf


def validation(t, q, sigma, psd=None, window=None, t_from=None):
    """The forward Validation of a log.

    Parameters
    ----------
    t : (N,) array
        Sample times (s), increasing (the log's clock).
    q : (N, n) array
        Positions (rad).
    sigma : (n,) array
        Position noise std per joint (rad) (codegen.logs.noise).
    psd : (f (F,), S (F, n)), optional
        One-sided PSD of q, for the choice of the window; None: the window minimising the noise
        term alone among those whose cubic bias on the motion band is ... (``window`` given).
    window : int, optional
        m; default chosen from ``psd`` and ``sigma`` (module docstring).
    t_from : float, optional
        Rows before this time (s) are not scored.
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    N, n = q.shape
    h = float(np.median(np.diff(t)))
    if window is None:
        if psd is None:
            raise ValueError("validation: give the window or the PSD of q to choose it")
        errs = {m: float(np.sum(window_error(m, h, sigma, psd))) for m in WINDOWS if m < N // 4}
        window = min(errs, key=errs.get)
    m = int(window)
    idx = np.arange(N)[:, None] + np.arange(1, m + 1)[None, :]
    inside = idx < N
    idx = np.minimum(idx, N - 1)
    reach = (t[idx[:, -1]] - t) <= 2.0 * m * h                  # no gap within the window
    valid = inside.all(axis=1) & reach
    w = _forward_weights(t, idx, inside, t)
    P = np.einsum("mk,mkn->mn", w, q[idx])
    if t_from is not None:
        valid &= t >= t_from
    noise = float(np.sum(np.asarray(sigma) ** 2)) * float(np.mean(np.sum(w[valid] ** 2, axis=1)))
    bias = float(np.sum(window_error(m, h, np.zeros(n), psd))) if psd is not None else 0.0
    return Validation(t, P, valid, noise + bias, m, {"noise": noise, "bias": bias})


@dataclass
class Search:
    """A bandwidth search: the best scale, its J, and every (scale, J) tried."""

    best: float
    score: float
    tried: list


def search(score, s0, lo=None, hi=None, grid=GRID, golden=GOLDEN, extend=None):
    """Minimise ``score(s)`` over s > 0 in log(s): ``grid`` log-spaced candidates over [lo, hi]
    (default s0 / RANGE .. s0 * RANGE); while the best is at an end of the range, the range is
    extended past it by the grid's step (at most ``extend`` times, default 4 ``grid``, and never
    past a given ``lo``/``hi``); then ``golden`` golden-section steps in the bracket around the
    best (a score that is not finite counts as worse than any finite one).

    Returns
    -------
    Search
    """
    fixed = (lo is not None, hi is not None)
    lo = s0 / RANGE if lo is None else lo
    hi = s0 * RANGE if hi is None else hi
    tried = {}

    def f(s):
        s = float(s)
        if s not in tried:
            v = score(s)
            tried[s] = v if math.isfinite(v) else math.inf
        return tried[s]

    xs = list(np.exp(np.linspace(math.log(lo), math.log(hi), grid)))
    step = (math.log(hi) - math.log(lo)) / (grid - 1)
    vals = [f(x) for x in xs]
    for _ in range(4 * grid if extend is None else extend):
        k = int(np.argmin(vals))
        if not math.isfinite(vals[k]):
            break
        if k == len(xs) - 1 and not fixed[1] and math.isfinite(vals[-1]):
            xs.append(xs[-1] * math.exp(step))
            vals.append(f(xs[-1]))
        elif k == 0 and not fixed[0]:
            xs.insert(0, xs[0] / math.exp(step))
            vals.insert(0, f(xs[0]))
        else:
            break
    k = int(np.argmin(vals))
    if not math.isfinite(vals[k]):
        return Search(float(s0), math.inf, sorted(tried.items()))
    a = math.log(xs[max(k - 1, 0)])
    b = math.log(xs[min(k + 1, len(xs) - 1)])
    g = (math.sqrt(5) - 1) / 2
    c, d = b - g * (b - a), a + g * (b - a)
    for _ in range(golden):
        if f(math.exp(c)) <= f(math.exp(d)):
            b, d = d, c
            c = b - g * (b - a)
        else:
            a, c = c, d
            d = a + g * (b - a)
    best = min(tried, key=tried.get)
    return Search(float(best), tried[best], sorted(tried.items()))


def scaled(p_names, p_default, tune, s):
    """Parameters (np,) with each tuned one scaled: p_i = p_default_i s^e_i for ``tune`` = {name:
    e}; ``p_names`` the parameters' names, ``p_default`` (np,) their values."""
    p = np.array(p_default, dtype=float)
    for name, e in tune.items():
        p[p_names.index(name)] *= s ** e
    return p


def segments(t, limit):
    """Indices [0, k_1, ..., N] cutting the stamps ``t`` (N,) (s) before each sample that follows
    an interval longer than ``limit`` (s): the runs an observer or a filter crosses without a
    restart."""
    return [0, *(np.flatnonzero(np.diff(t) > limit) + 1).tolist(), len(t)]


def run_over(obs, Y, U, t, limit):
    """``obs`` (reset/run: a compiled observer, the reference or a baseline) over the samples
    Y (N, ny), U (N, nu) at times t (N,), reset from the first sample after every interval
    longer than ``limit`` s; returns (estimate (N, nest), number of resets)."""
    cuts = segments(t, limit)
    out = None
    for a, b in zip(cuts[:-1], cuts[1:]):
        obs.reset(Y[a])
        e = obs.run(Y[a:b], None if U is None else U[a:b], t=t[a:b])
        if out is None:
            out = np.empty((len(Y), e.shape[1]))
        out[a:b] = e
    return out, len(cuts) - 2


@dataclass
class Tuned:
    """The outcome of tuning one estimator on a log."""

    name: str
    params: dict
    scale: float
    score: float
    rms: float
    tried: list
    note: str = ""

    def line(self):
        """One line: the tuned values and the criterion."""
        par = ", ".join(f"{k} = {v:.4g}" for k, v in self.params.items())
        return (f"{self.name}: {par}  (forward-validation error {math.sqrt(self.score):.3g} rad/s, "
                f"estimated RMS error {self.rms:.3g} rad/s; {len(self.tried)} runs)"
                + (f"; {self.note}" if self.note else ""))


def bandwidth(family, p_names):
    """{parameter: exponent} of the family's bandwidth scale (its module's ``TUNE``: a dict, or a
    function of the parameter names), only those among ``p_names``; {} when it declares none."""
    import importlib
    try:
        module = importlib.import_module(f"codegen.families.observers.{family}")
    except ImportError:
        return {}
    tune = getattr(module, "TUNE", None)
    tune = tune(list(p_names)) if callable(tune) else dict(tune or {})
    return {k: float(e) for k, e in tune.items() if k in p_names}


def start_of_steady(spec, p, t):
    """The first time (s) the tuning scores: after twice the family's start-up phase
    (``t_switch``, when the ``spec`` has one, its value in the parameters ``p``) and after the first
    5 % of the log's times ``t`` (N,) (s)."""
    names = list(spec.p_names)
    start = 2.0 * float(p[names.index("t_switch")]) if "t_switch" in names else 0.0
    return float(t[0] + max(start, 0.05 * (t[-1] - t[0])))


def too_short(val, t, t_from, spec, p):
    """Why the log of times ``t`` (N,) (s) is too short to score from ``t_from`` (s) with the
    Validation ``val`` (a scored row needs its ``val.window`` following samples), or "" when it is
    not: the log must score at least as long as it skips, T >= 2 (t_from - t_0) + m h. ``spec``
    and its parameters ``p`` (np,) say why scoring starts late (a ``t_switch``)."""
    t0, T = float(t[0]), float(t[-1] - t[0])
    h = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    need = 2.0 * (t_from - t0) + val.window * h
    if T >= need and np.any(val.valid & (t >= t_from)):
        return ""
    names = list(spec.p_names)
    why = (f"twice its start-up t_switch = {float(p[names.index('t_switch')]):.3g} s"
           if "t_switch" in names else "after the first 5 % of the log")
    return (f"the log is too short: {T:.3g} s, and scoring starts at {t_from - t0:.3g} s ({why}) with "
            f"{val.window} samples ahead of each scored one; record at least {need:.3g} s")


def _with_params(obs, p):
    """Set ``p`` on a freshly reset observer: the C's set_params without the stability check
    (a candidate; the chosen one is checked), or the reference's own setter."""
    if hasattr(obs, "c_set_params"):
        obs.c_set_params(p)
    else:
        obs.params = p


def run_with(obs, p, Y, U, t, limit):
    """``run_over`` of the observer ``obs`` with the parameters ``p`` set after every reset, over
    Y (N, ny), U (N, nu) at times ``t`` (N,) (s), reset after intervals longer than ``limit`` (s);
    NaN estimates when the observer fails (a non-finite state: a candidate beyond its stable range)."""
    cuts = segments(t, limit)
    out = np.full((len(Y), obs.nest), np.nan)
    try:
        for a, b in zip(cuts[:-1], cuts[1:]):
            obs.reset(Y[a])
            _with_params(obs, p)
            out[a:b] = obs.run(Y[a:b], U[a:b], t=t[a:b])
    except (ArithmeticError, ValueError, RuntimeError):
        out[:] = np.nan
    return out


def check_candidate(obs, spec, tune, p):
    """The stability check of a candidate ``p`` (np,) of ``obs`` (built from ``spec``; ``tune`` its
    bandwidth's {parameter: exponent}): one tuned gain moved alone, against its recorded bound
    (codegen.discrete.stability, in the target's metadata: the largest value stable with the others
    at their defaults); several, the full check (``obs.check_params``). ValueError when unstable."""
    recorded = ((getattr(obs, "meta", None) or {}).get("stability") or {}).get("gains") or {}
    if len(tune) == 1:
        (name,) = tune
        for g in recorded.values():
            if list(g.get("slots", [])) == [name] and g.get("max_stable") is not None:
                value = float(p[list(spec.p_names).index(name)])
                if value < 0:
                    raise ValueError(f"{name} = {value:.6g} is negative")
                if value <= g["max_stable"]:
                    return                  # within the checked range (beyond it: the full check)
                if g.get("limit_found"):
                    raise ValueError(f"{name} = {value:.6g} is above its recorded stable bound "
                                     f"{g['max_stable']:.6g}")
    obs.check_params(p, explain=False)      # a refused candidate needs no stable ranges


def tune_observer(obs, spec, family, Y, U, t, val, limit, slots, progress=None, t_from=None):
    """The bandwidth of an observer chosen on the log (module docstring).

    Parameters
    ----------
    obs : compiled observer or reference (reset, run, c_set_params or params, check_params)
    spec : codegen.core.spec.ObserverSpec
        Its spec (names, default parameters).
    family : str
    Y, U : (N, ny), (N, nu) arrays
        The log's measurements and inputs; ``t`` (N,) its clock (s).
    val : Validation
    limit : float
        Longest interval an observer crosses without a reset (s).
    slots : list of int
        The estimate's velocity slots.
    progress : callable, optional
        Called with each candidate's text.
    t_from : float, optional
        Rows scored from this time (s) on; default after the family's start-up
        (``start_of_steady``).

    Returns
    -------
    (Tuned or None, p (np,)): None and the designed parameters when the family declares no
    bandwidth
    """
    p0 = np.array(spec.p_default, dtype=float)
    tune = bandwidth(family, spec.p_names)
    if not tune:
        return None, p0
    start = start_of_steady(spec, p0, t)
    t_from = max(start, t_from if t_from is not None else -math.inf)
    # the log scores at least as long as the start-up skips (a window the caller chose later, such
    # as compare's t_ss in the middle, only needs scored rows)
    short = too_short(val, t, start, spec, p0) or ("" if np.any(val.valid & (t >= t_from)) else
                                                   too_short(val, t, t_from, spec, p0))
    if short:
        return Tuned(family, {}, 1.0, math.inf, math.inf, [], short), p0

    def score(s):
        p = scaled(spec.p_names, p0, tune, s)
        est = run_with(obs, p, Y, U, t, limit)
        if progress:
            progress(f"{family} x {s:.3g}")
        return val.score(est[:, slots], t_from)

    found = search(score, 1.0)
    tried = list(found.tried)

    def stable(s):
        try:
            check_candidate(obs, spec, tune, scaled(spec.p_names, p0, tune, s))
            return None
        except ValueError as e:
            return str(e)
    # the best candidate the stability check accepts (a candidate ran unchecked)
    note, refused = "", []
    for s, J in sorted(found.tried, key=lambda item: item[1]):
        if not math.isfinite(J):
            break
        why = stable(s)
        if why is not None:
            note = f"x {s:.3g} refused by the stability check ({why[:80]}...)"
            refused.append(s)
            continue
        if refused:                     # toward the nearest better scale refused: the bound
            bad = min(refused, key=lambda r: abs(math.log(r / s)))
            for _ in range(BOUNDARY):
                m = math.sqrt(s * bad)
                Jm = score(m)
                tried.append((m, Jm))
                if math.isfinite(Jm) and Jm < J and stable(m) is None:
                    s, J = m, Jm
                else:
                    bad = m
            note += f"; x {s:.3g} at the stability bound"
        p = scaled(spec.p_names, p0, tune, s)
        est = run_with(obs, p, Y, U, t, limit)
        params = {k: float(p[spec.p_names.index(k)]) for k in tune}
        return Tuned(family, params, float(s), J, val.rms(est[:, slots], t_from), sorted(tried), note), p
    return Tuned(family, {}, 1.0, math.inf, math.inf, found.tried, "no candidate ran finite and stable"), p0
