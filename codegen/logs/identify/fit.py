"""Dynamic identification of a URDF robot from a log of q and tau: the fit of (1)
(``codegen.logs.identify.regressor``), in this order:

1. velocity and acceleration by zero-phase smoothing of q (``codegen.logs.smoothing``), tau
   through the same zero-phase filter, so that both sides of (1) see the same band; the Coulomb
   column, not smooth where qd changes sign, is tanh of a wider-band velocity through that filter
   too (parallel filtering);
2. the last ``test_fraction`` of the log held out; the filters' edges dropped; the least squares
   on every D-th training sample (a step of 1/(FIT_RATE cutoff)), weighted sqrt(D): below the
   cut-off nothing is lost, and the covariance is that of all samples. A joint's row is left
   out where its smoothed speed is at most ``v_stick``: stuck by dry friction, a joint holds any
   torque up to its Coulomb friction, which (1) cannot say; and everywhere when its torque column
   is constant (not measured: some real logs carry zeros). The covariance is
   sigma^2 (A^T A)^-1 with sigma the white noise of the unfiltered torque;
3. a physically consistent estimate, the URDF as the prior: each body's parameters as the
   URDF's fixed extras plus the primary link's, in bounded log-Cholesky coordinates
   (``parametrisation.from_bounded``: mass, centre of mass and second moments within the link's
   ``LinkBounds`` by construction), friction ``f_v, f_c >= 0``, by
   ``scipy.optimize.least_squares``, minimising

       |W (A x - tau_f)|^2 + |(x - x_URDF) / (prior s_p)|^2,

   W the torque noise of each joint (from the residual), s_p each parameter's scale (friction:
   the RMS of the joint's measured torque where larger, ``_Arm.friction_prior``): a Gaussian prior of relative std ``prior`` on the URDF's
   values (as Gaz et al., RA-L 2019, keep the Panda's parameters near a feasible reference), the
   URDF projected into the bounds first where it is not inside them. What the log determines is
   identified; what it does not keeps the URDF's value. Only a log that does not move is refused;
4. base parameters (the combinations any log can determine) with their posterior and prior std:
   a combination whose posterior std is at most ``report.FIXED`` x its prior std was fixed by the
   log, one at least ``report.KEPT`` x kept the URDF's value;
5. the held-out residual before (URDF as shipped, no friction) and after.

Why not an SDP: cvxpy is not a dependency, and the log-Cholesky form turns the same
positive-definiteness constraint into an unconstrained smooth least-squares problem.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np

from ..smoothing import derivatives
from .parametrisation import from_bounded, project, to_bounded
from .regressor import _Arm, _tri
from .report import STILL, _report, _still
from .result import Identification

WIDTHS = (0.2, 0.1, 0.05, 0.02, 0.01)   # rad/s: the Coulomb widths coulomb_width="auto" chooses from
CUTOFFS = (2.0, 5.0, 10.0, 20.0, 50.0, 100.0)   # Hz: the cut-offs cutoff=None chooses from (with the
                                # measured identification_cutoff), below 0.45 x the Nyquist frequency
THIN = 1e-2                    # D's diagonal at least this x rho (the second moment's own margin)
SELECT_SAMPLES = 4000           # held-out samples at most that score a (cut-off, width) pair
BAND_MARGIN = 4.0              # the cut-off over the motion's band (identification_cutoff)
DEFAULT_TEST_FRACTION = 0.2
DEFAULT_PRIOR = 1.0             # relative std of the URDF's values (units of each parameter's scale)
DEFAULT_V_STICK = 0.05         # rad/s: a joint slower than this (smoothed) sticks; its rows are left out
WIDE = 4.0                      # the Coulomb column's velocity at WIDE x cutoff before the filter
FTOL = 1e-6                     # relative cost decrease at which the consistent solve stops
MAX_NFEV = 2000
FIT_RATE = 20.0                 # least-squares samples per second per Hz of cut-off
CHUNK = 4096                    # samples per regressor block of a prediction


class IdentificationError(ValueError):
    """A log that does not move. ``remedy``: what would work, as data (``{"excite": {"robot",
    "urdf", "locked_joints"}}``: record an excitation trajectory of that robot), for the caller to
    render (the CLI as flags)."""

    def __init__(self, message, remedy=None):
        super().__init__(message)
        self.remedy = dict(remedy or {})


def _log_arrays(recording, joint_names):
    """(t, q, tau) of a recording in the robot's joint order."""
    names = list(getattr(recording, "joint_names", []) or [])
    missing = [j for j in joint_names if j not in names]
    if missing:
        raise ValueError(f"recording: no columns for joints {', '.join(missing)} of the robot "
                         f"(the recording has {', '.join(names) or 'none'})")
    idx = [names.index(j) for j in joint_names]
    t = np.asarray(recording.t, dtype=float).ravel()
    q = np.asarray(recording.q, dtype=float).reshape(len(t), -1)
    tau = np.asarray(recording.tau, dtype=float).reshape(len(t), -1)
    if q.shape[1] != len(names) or tau.shape[1] != len(names):
        raise ValueError(f"recording: q and tau need {len(names)} columns, got {q.shape[1]} and {tau.shape[1]}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(tau))):
        raise ValueError("recording: NaN or Inf in q or tau")
    return t, q[:, idx], tau[:, idx]


def _progress(progress, desc, total=None):
    from ...core.progress import bar
    return bar(total=total, desc=desc, file=sys.stderr, disable=not progress, leave=False, dynamic_ncols=True)


class _TooShort(ValueError):
    """A log too short for a cut-off's filter edges."""


@dataclass
class _Fit:
    """What the least squares of (1) is made of, on one log: the smoothed states ``d`` (and
    ``dw`` at the Coulomb column's wider band), the unfiltered and filtered torques, the training
    and held-out masks, the rows every D-th training sample gives (``fit`` indices, weight
    ``wD`` = sqrt(D)), and the rigid-body regressor there (``base_rows``, unscaled)."""
    arm: _Arm
    t: np.ndarray
    tau: np.ndarray
    tau_f: np.ndarray
    d: object
    dw: object
    cutoff: float
    sliding: np.ndarray
    train: np.ndarray
    test: np.ndarray
    fit: np.ndarray
    wD: float
    base_rows: np.ndarray

    def rows(self, width):
        """The fit's rows (columns in scaled units x~ = x / s) at Coulomb width ``width``."""
        n = self.arm.n
        i = np.arange(n)
        r = self.base_rows.copy()
        r[:, i, 11 * n + i] = lowpass(self.t, np.tanh(self.dw.qd / width), self.cutoff)[self.fit]
        return r * self.arm.scale

    def predict(self, X, mask, width):
        """(samples of ``mask``, n, k): the torques of (1) with parameters X (p, k) at the
        smoothed states (the regressor in chunks: a long log is never held whole)."""
        idx = np.nonzero(mask)[0]
        out = np.empty((len(idx), self.arm.n, X.shape[1]))
        for k in range(0, len(idx), CHUNK):
            j = idx[k:k + CHUNK]
            out[k:k + CHUNK] = self.arm.regressor(self.d.q[j], self.d.qd[j], self.d.qdd[j], width) @ X
        return out

    def residual(self, X, mask, width):
        """RMS per joint (k, n) of the measured torque less (1) with each column of X (p, k)."""
        return np.sqrt(np.mean((self.tau[mask][..., None] - self.predict(X, mask, width)) ** 2, axis=0)).T

    def noise(self, x, width):
        """RMS per joint of the measured (unfiltered) torque less the model's, training samples."""
        return np.maximum(self.residual(x[:, None], self.train, width)[0], 1e-9 * self.arm.torque_scale)

    def long_run(self, x, width):
        """The long-run std per joint (n,) of the filtered torque's residual on the training
        samples, sqrt(var x kappa), kappa = 1 + 2 sum_k rho(k) its integrated autocorrelation
        (Geyer's initial positive sequence): the std that white noise of the same information
        would have. White torque noise of std sigma gives sigma (the filter passes the band of
        the regressor with gain 1); a model error that is not white (a real arm's) counts as the
        few independent samples it is, not as every row."""
        r = self.tau_f[self.train] - self.predict(x[:, None], self.train, width)[..., 0]
        return np.maximum(_long_run_std(r), 1e-9 * self.arm.torque_scale)

    def compress(self, rows, w):
        """(R, c): sum over all training samples of |diag(w) (A_fit x - tau_f)|^2 (a joint's rows
        where it sticks left out), from every D-th one weighted sqrt(D), = |R x~ - c|^2 + const."""
        p = self.arm.p
        w = w[None, :] * self.wD * self.sliding[self.fit]
        M = np.column_stack([(rows * w[:, :, None]).reshape(-1, p), (self.tau_f[self.fit] * w).ravel()])
        Rb = _tri(M)
        return Rb[:p, :p], Rb[:p, p]

    def ols(self, R, c):
        """x of the unconstrained least squares of the base parameters (dependent ones 0)."""
        arm = self.arm
        x = np.zeros(arm.p)
        x[arm.indep] = np.linalg.lstsq(R[:, arm.indep], c, rcond=None)[0] * arm.scale[arm.indep]
        return x


def _prepare(arm, t, q, tau, cutoff, tf, v_stick):
    """The :class:`_Fit` of a log (module docstring, 1-2)."""
    n, p = arm.n, arm.p
    d = derivatives(t, q, cutoff)
    h = float(np.median(np.diff(t)))
    wide = min(WIDE * cutoff, 0.25 / h)
    dw = derivatives(t, q, wide)
    tau_f = lowpass(t, tau, cutoff)
    # a joint's row of a sample where its smoothed velocity is below v_stick is left out of the
    # fit: a joint at rest under dry friction holds any torque up to its Coulomb friction
    sliding = (np.abs(d.qd) > v_stick).astype(float)
    sliding[:, np.ptp(tau, axis=0) == 0] = 0.0       # a constant torque column: no torque measured
    edge = 2.0 / cutoff + 2.0 / wide
    valid = (t >= t[0] + edge) & (t <= t[-1] - edge)
    t_split = t[0] + (1.0 - tf) * (t[-1] - t[0])
    train = valid & (t < t_split)
    test = valid & (t >= t_split)
    if train.sum() < 2 * p or test.sum() < 10:
        raise _TooShort(f"recording: too short: {train.sum()} training and {test.sum()} test samples "
                         f"away from the filter's edges (need {2 * p} and 10)")
    # the least squares on every D-th training sample: below the cut-off nothing is lost at a
    # step of 1/(FIT_RATE cutoff); weights x sqrt(D) keep the covariance that of all samples
    tr_idx = np.nonzero(train)[0]
    D = max(1, int(1.0 / (FIT_RATE * cutoff * h)))
    fit = tr_idx[::D]
    wD = math.sqrt(len(tr_idx) / len(fit))
    # parallel filtering: the Coulomb column (rows()) is tanh of the wide-band velocity through
    # the same filter as tau; the other columns are smooth functions of the smoothed states
    base_rows = arm.regressor(d.q[fit], d.qd[fit], d.qdd[fit])
    return _Fit(arm, t, tau, tau_f, d, dw, float(cutoff), sliding, train, test, fit, wD, base_rows), \
        {"t_split": t_split, "wide": wide, "decimation": D}


def _long_run_std(r):
    """sqrt(var x kappa) per column of ``r`` (N, n) (:meth:`_Fit.long_run`)."""
    r = r - r.mean(axis=0)
    N = len(r)
    f = np.fft.rfft(r, n=2 * N, axis=0)
    ac = np.fft.irfft(np.abs(f) ** 2, axis=0)[:N] / N
    rho = ac / np.maximum(ac[:1], 1e-300)
    pairs = rho[0:N - 1:2] + rho[1:N:2]                   # Gamma_m = rho(2m) + rho(2m + 1)
    kappa = np.empty(r.shape[1])
    for j in range(r.shape[1]):
        stop = np.flatnonzero(pairs[:, j] <= 0)
        m = stop[0] if len(stop) else len(pairs)
        kappa[j] = max(2.0 * pairs[:m, j].sum() - 1.0, 1.0)
    return np.sqrt(ac[0] * kappa)


def _select(states, widths):
    """((index of the best state, of the best width), held-out RMS (states, widths, n)): each
    pair's unconstrained fit on the training samples, its residual on the held-out samples that
    every state keeps (at most SELECT_SAMPLES of them, evenly spaced), scored by the sum over the
    joints of (RMS / the smallest RMS any pair leaves)^2."""
    arm = states[0][0].arm
    n = arm.n
    common = np.logical_and.reduce([st.test for st, _ in states])
    idx = np.nonzero(common)[0]
    idx = idx[::max(1, len(idx) // SELECT_SAMPLES)]
    i = np.arange(n)
    held = np.empty((len(states), len(widths), n))
    for a, (st, _) in enumerate(states):
        Y = arm.regressor(st.d.q[idx], st.d.qd[idx], st.d.qdd[idx])
        for b, w in enumerate(widths):
            x0 = st.ols(*st.compress(st.rows(w), 1.0 / arm.torque_scale))
            Y[:, i, 11 * n + i] = np.tanh(st.d.qd[idx] / w)
            held[a, b] = np.sqrt(np.mean((st.tau[idx] - Y @ x0) ** 2, axis=0))
    measured = np.ptp(states[0][0].tau, axis=0) > 0
    score = np.sum((held[..., measured] / held.reshape(-1, n)[:, measured].min(axis=0)) ** 2, axis=2)
    return np.unravel_index(int(np.argmin(score)), score.shape), held


def identify(recording, robot, *, cutoff=None, test_fraction=DEFAULT_TEST_FRACTION,
             coulomb_width="auto", prior=DEFAULT_PRIOR, v_stick=DEFAULT_V_STICK, progress=False,
             out=None):
    """Identify the inertial parameters and the friction (1) of a URDF robot from a log.

    Parameters
    ----------
    recording : codegen.logs.recording.Recording
        ``t`` (N,) increasing time stamps (jitter and gaps allowed), ``q`` (N, n) positions,
        ``tau`` (N, n) measured joint torques, ``joint_names`` (all of the robot's; any order).
        ``qd`` is not used.
    robot : models.RobotModel
        A URDF robot (``load_robot(urdf=..., locked_joints=...)``, ``ur5``, ``panda``): the
        starting point and prior; its ``source`` says how pinocchio rebuilds it.
    cutoff : float, optional
        Hz, of the zero-phase low-pass that gives qd, qdd and the filtered tau; default selected
        with the Coulomb width: of ``CUTOFFS`` below 0.45 x the Nyquist frequency and the one
        measured on the log's spectrum (``identification_cutoff``), the one whose unconstrained
        fit leaves the smallest held-out residual (as for ``coulomb_width``): on a real arm's log
        the measured spectrum's band can lie far above the rigid-body motion's (vibration, the
        sensors), where the acceleration's noise biases the inertial parameters.
    test_fraction : float
        The last fraction of the log's duration, held out for the residual (0 < f < 1).
    coulomb_width : float or "auto" or None
        w of tanh(qd/w) (rad/s). "auto" (default): of ``WIDTHS`` and the robot's own, the one
        whose least-squares fit (unconstrained, on the training samples) leaves the smallest
        held-out residual, sum over joints of (RMS / the smallest RMS any width leaves)^2 (a
        real joint's dry friction switches faster than any one width assumes). None: the
        robot's ``coulomb_width`` if it has one, else ``DEFAULT_COULOMB_WIDTH``.
    prior : float
        Relative std of the URDF's values as a prior (in units of each parameter's scale; for
        friction and offset of the joint's RMS measured torque, where larger).
    v_stick : float
        rad/s: a joint's rows where its smoothed velocity is at most this are left out of the fit
        (a joint stuck by dry friction holds an unknown torque); 0 keeps every row.
    progress : bool
        A tqdm bar on stderr over the solver iterations.
    out : path, optional
        Also write the files of :meth:`Identification.write` there.

    Returns
    -------
    Identification

    Raises
    ------
    IdentificationError
        The log does not move (no joint's RMS speed reaches STILL of its velocity limit);
        ``remedy`` says what to record.
    """
    from scipy.optimize import least_squares
    arm = _Arm(robot, coulomb_width)
    n, p, s = arm.n, arm.p, arm.scale
    t, q, tau = _log_arrays(recording, arm.joint_names)
    unmeasured = [j for j, r in zip(arm.joint_names, np.ptp(tau, axis=0)) if r == 0]
    if len(unmeasured) == arm.n:
        raise ValueError("recording: every torque column is constant (no torque was measured): nothing "
                         "to identify the model from")
    tf = float(test_fraction)
    if not 0.0 < tf < 1.0:
        raise ValueError(f"test_fraction: expected a number in (0, 1), got {test_fraction!r}")
    for name, v in (("prior", prior), ("cutoff", 1.0 if cutoff is None else cutoff)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name}: expected a positive number, got {v!r}")
    if not (isinstance(v_stick, (int, float)) and math.isfinite(v_stick) and v_stick >= 0):
        raise ValueError(f"v_stick: expected a velocity >= 0 (rad/s), got {v_stick!r}")
    if isinstance(coulomb_width, str) and coulomb_width != "auto":
        raise ValueError(f"coulomb_width: expected a positive number (rad/s) or 'auto', got {coulomb_width!r}")
    bar = _progress(progress, f"identify {arm.name}")
    bar.set_postfix_str("cut-off and Coulomb width")
    if cutoff is None:
        nyquist = 0.5 / float(np.median(np.diff(t)))
        cutoffs = sorted({*(c for c in CUTOFFS if c < 0.45 * nyquist), identification_cutoff(t, q)})
    else:
        cutoffs = [float(cutoff)]
    widths = (sorted({*WIDTHS, *([float(arm.robot_width)] if arm.robot_width else [])}, reverse=True)
              if coulomb_width == "auto" else [arm.width])
    states, short = [], None
    for c in list(cutoffs):                # a cut-off whose filter edges leave no held-out part is skipped
        try:
            states.append(_prepare(arm, t, q, tau, c, tf, v_stick))
        except _TooShort as e:
            cutoffs.remove(c)
            short = e
    if not states:
        raise short
    # a log that does not move determines nothing: the only refusal
    first = states[0][0]
    speed = np.sqrt(np.mean(first.d.qd[first.train] ** 2, axis=0))
    if not np.any(speed >= STILL * arm.v_limit):
        raise IdentificationError(*_still(arm, speed))
    if len(cutoffs) * len(widths) > 1:
        best, held_out = _select(states, widths)
        (state, log), cutoff, arm.width = states[best[0]], cutoffs[best[0]], widths[best[1]]
        held = {(f"{c:g} Hz", f"{w:g} rad/s"): held_out[i, k] for i, c in enumerate(cutoffs)
                for k, w in enumerate(widths)}
        arm.selection = {"cutoff": "selected" if len(cutoffs) > 1 else "given",
                         "held_out_rms": {f"{c}, {w}": {j: float(r) for j, r in zip(arm.joint_names, v)}
                                          for (c, w), v in held.items()}}
        if coulomb_width == "auto":
            arm.width_source = (f"selected by the held-out residual of the unconstrained fit (with the "
                                f"cut-off) from {', '.join(f'{w:g}' for w in widths)} rad/s")
    else:
        state, log = states[0]
    cutoff = float(cutoff)
    train, test = state.train, state.test

    width = arm.width
    rows = state.rows(width)

    # round 0: weights from the torque scales; its residual is the first noise estimate
    R0, c0 = state.compress(rows, 1.0 / arm.torque_scale)
    cond = float(np.linalg.cond(_tri(R0[:, arm.indep])))
    x0 = state.ols(R0, c0)
    sigma = state.noise(x0, width)

    speed = np.sqrt(np.mean(state.d.qd[train] ** 2, axis=0))
    R, c = state.compress(rows, 1.0 / state.long_run(x0, width))

    # physically consistent estimate, in scaled units x~ = x / s: each primary link's scaled
    # parameters in the bounded log-Cholesky coordinates (parametrisation.from_bounded: its mass,
    # centre of mass and second moments within LinkBounds by construction), friction f / s with
    # f_v, f_c >= 0; the prior: the URDF (projected into the bounds where it is not inside)
    solve = _Consistent(arm)
    x_prior = arm.x_prior / s
    rms_tau = np.sqrt(np.mean(tau[train] ** 2, axis=0))
    arm.friction_prior(np.where(rms_tau > 0, rms_tau, arm.effort))
    wp = s / (prior * arm.prior_scale)    # 1 / the prior's std, scaled units
    z, rounds = None, []
    for rnd in range(2):                   # solve, re-estimate the noise, solve again
        # |R x~ - c|^2 + |wp (x~ - x~_prior)|^2 = |Rp x~ - cp|^2 + const: one square system,
        # Rp^T Rp = R^T R + diag(wp^2) (Cholesky), cp = Rp^-T (R^T c + wp^2 x~_prior). The same
        # problem without the constraints is linear: its solution projected into the bounds, or
        # the prior, whichever costs less, starts the solver; the solver's cost is the full one
        # less the unconstrained minimum, and it stops when a step lowers that by less than FTOL
        solve.Rp = np.linalg.cholesky(R.T @ R + np.diag(wp ** 2)).T
        solve.cp = np.linalg.solve(solve.Rp.T, R.T @ c + wp ** 2 * x_prior)
        x_lin = np.linalg.solve(solve.Rp, solve.cp)
        cost_lin = 0.5 * float(np.sum((R @ x_lin - c) ** 2) + np.sum((wp * (x_lin - x_prior)) ** 2))
        starts = [solve.start(x_lin), solve.start(x_prior)] + ([z] if z is not None else [])
        z = min(starts, key=lambda v: float(np.sum(solve.fun(v) ** 2)))
        bar.set_postfix_str(f"solve {rnd + 1}/2")
        solve.bar = bar
        result = least_squares(solve.fun, z, jac=solve.jac, bounds=solve.limits(), method="trf", x_scale=1.0,
                               ftol=FTOL, xtol=1e-12, gtol=1e-12, max_nfev=MAX_NFEV)
        result.cost += cost_lin
        z = result.x
        rounds.append({"nfev": int(result.nfev), "status": int(result.status), "message": str(result.message),
                       "cost": float(result.cost), "cost_unconstrained": cost_lin})
        x = solve.assemble(z)[0] * s
        sigma = state.noise(x, width)
        R, c = state.compress(rows, 1.0 / state.long_run(x, width))
    bar.close()

    # covariances at the final weights (linearised, bounds not active): every parameter and the
    # base combinations, from log and prior, and the prior's alone; a combination's relative
    # std: the torque uncertainty it leaves on random states of the robot (arm.effect)
    cov = np.linalg.inv(R.T @ R + np.diag(wp ** 2))
    std_post = np.sqrt(np.diag(cov)) * s
    std_beta = np.sqrt(np.einsum("ij,jk,ik->i", arm.T, cov, arm.T))
    prior_beta = np.sqrt((arm.T ** 2) @ (1.0 / wp ** 2))
    effect = arm.effect(sigma)
    x_ols = state.ols(R, c)                # the unconstrained optimum, for comparison

    res = state.residual(np.column_stack([np.r_[arm.pi_urdf, np.zeros(3 * n)], x, x_ols]), test, width)
    residual = {"before": res[0], "after": res[1], "after_unconstrained": res[2], "train_after": sigma}
    fit = {"t": t, "train": train, "test": test, "t_split": log["t_split"], "cutoff": cutoff,
           "wide": log["wide"], "decimation": log["decimation"], "test_fraction": tf, "v_stick": v_stick,
           "stuck": 1.0 - state.sliding[train].mean(axis=0), "speed": speed, "unmeasured": unmeasured}
    estimate = {"x": x, "sigma": sigma, "std_post": std_post, "std_beta": std_beta, "prior_beta": prior_beta,
                "effect": effect, "residual": residual, "cond": cond, "rounds": rounds}
    report = _report(arm, fit, estimate, {"prior": prior})
    ident = Identification(arm, x, report)
    if out is not None:
        ident.write(out)
    return ident


class _Consistent:
    """The consistent solve's residual |Rp x~(z) - cp| in the solver's variables z: each primary
    link's bounded log-Cholesky coordinates (10 per body, ``from_bounded`` in its body's scaled
    units) then the friction (3 n)."""

    def __init__(self, arm):
        self.arm, self.n, self.p = arm, arm.n, arm.p
        self.att = arm.attached / arm.scale[:10 * arm.n]
        self.rho = np.array([b.rho for b in arm.bounds_scaled])
        self.Rp = self.cp = self.bar = None

    def limits(self):
        """(lower, upper) of z: each link's theta_0 = log(m)/2 >= that of its least mass, its
        centre of mass theta_7..9 within +-reach; f_v, f_c >= 0."""
        n = self.n
        lo, hi = np.full(13 * n, -np.inf), np.full(13 * n, np.inf)
        for i, b in enumerate(self.arm.bounds_scaled):
            lo[10 * i] = 0.5 * math.log(b.mass)
            lo[10 * i + 7:10 * i + 10], hi[10 * i + 7:10 * i + 10] = -b.reach, b.reach
            lo[10 * i + 1:10 * i + 4] = math.log(THIN * b.rho)    # D's diagonal: no thinner than this
        lo[10 * n:12 * n] = 0.0
        return lo, hi

    def start(self, x):
        """z of scaled parameters ``x`` (p,), each link projected into its bounds and the friction
        to >= 0."""
        n = self.n
        z = np.array(x, dtype=float)
        for i, b in enumerate(self.arm.bounds_scaled):
            pi, _ = project(x[10 * i:10 * i + 10] - self.att[10 * i:10 * i + 10], b)
            z[10 * i:10 * i + 10] = to_bounded(pi, b.rho)
            z[10 * i + 1:10 * i + 4] = np.maximum(z[10 * i + 1:10 * i + 4], math.log(2 * THIN * b.rho))
        z[10 * n:12 * n] = np.maximum(z[10 * n:12 * n], 0.0)
        return z

    def assemble(self, z):
        """(x~, d x~ / d z) of the solver's variables z."""
        n, p = self.n, self.p
        x, D = np.empty(p), np.zeros((p, p))
        pi, dpi = from_bounded(z[:10 * n].reshape(n, 10), self.rho)
        x[:10 * n] = self.att + pi.ravel()
        for i in range(n):
            D[10 * i:10 * i + 10, 10 * i:10 * i + 10] = dpi[i]
        x[10 * n:] = z[10 * n:]
        D[10 * n:, 10 * n:] = np.eye(3 * n)
        return x, D

    def fun(self, z):
        return self.Rp @ self.assemble(z)[0] - self.cp

    def jac(self, z):
        if self.bar is not None:
            self.bar.update(1)
        return self.Rp @ self.assemble(z)[1]


def identification_cutoff(t, q):
    """The zero-phase cut-off (Hz) identification fits on, from the log's measured spectrum
    (codegen.logs.noise): BAND_MARGIN x the highest joint's motion band, where the order-4
    forward-backward filter leaves the band's motion untouched to (1 / BAND_MARGIN)^8 = 1.5e-5 (the
    regression's nonlinear terms, g(q) and C(q, v) v, are filtered after they are formed: a filter
    that bites into the motion biases them, where noise only adds variance), and at least the cut-off
    of the least predicted acceleration error (``noise.reference_cutoff`` with ``derivative=2``),
    over the joints that move (a range of more than ten noise levels), below 0.45 x the Nyquist
    frequency. ``t`` (N,) s, ``q`` (N, n) rad."""
    from ..noise import measure, reference_cutoff
    nz = measure(t, q)
    moving = np.ptp(q, axis=0) > 10 * np.maximum(nz.sigma, nz.resolution)
    if not moving.any():
        moving[:] = True
    cut = max(BAND_MARGIN * np.max(nz.band[moving]), np.median(reference_cutoff(nz, derivative=2)[moving]))
    return float(min(cut, 0.45 * 0.5 / nz.dt))


def lowpass(t, y, cutoff):
    """y (N, k) through the zero-phase low-pass of ``codegen.logs.smoothing.derivatives``
    at ``cutoff`` Hz (cubic to the uniform grid of the median step of ``t`` (N,), 4th-order
    Butterworth forward and backward, cubic back), in blocks of columns."""
    y = np.asarray(y, dtype=float)
    flat = y.reshape(len(t), -1)
    out = np.empty_like(flat)
    for k in range(0, flat.shape[1], 64):
        out[:, k:k + 64] = derivatives(t, flat[:, k:k + 64], cutoff).q
    return out.reshape(y.shape)
