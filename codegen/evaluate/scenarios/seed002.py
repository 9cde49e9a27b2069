"""Seed 002 (Lotfi & Namvar) §V reproduced, and the adaptive observer on ur5 (docs/papers/experiments.md §12.2).

Plant: the robot under computed-torque tracking with the *true* state [ASSUMPTION, docs/papers/experiments.md §12.2]

    tau = M(q) (qdd_d + 40 (qd_d - qd) + 400 (q_d - q)) + C(q, qd) qd + F qd + g(q),
    q_d = [sin 10 t, cos 10 t],  q(0) = q_d(0),  qd(0) = qd_d(0),

integrated in C (RK4, torque held over a step). Because the controller uses the true state, the
plant does not depend on the observers: the loop runs the plant first, then every observer over
the recorded samples with ``run`` (the loop in C, or the numpy reference with reference=True).

Measurements: y = (q_s, f_f) for the adaptive observer, y = q_s for the non-smooth one, with
q_s = q + white Gaussian noise sampled at 1 kHz and held (std = 0.3 RMS(q_i) "30 %", A2-3, or
a fixed std), and the CoM forces f_{f,i} = m_i (J_p^i qdd + Jdot_p^i qd - g_o) of docs/papers/seed002.md §3.1
computed from the true state and the applied torque (no force noise, docs/papers/experiments.md §12.2).

Step: dt = 1e-4 s for everything (docs/papers/seed002.md §3.3: the sign of (35) is integrated literally, no
smoothing; RK4 with the measurement held over the step).

Scenarios: ``seed002`` (noise-free, Figs. 1–2 plus the comparison), ``seed002-noisy``
(std = 0.3 RMS(q_i), Figs. 3–4), ``seed002-noise-3mrad`` (std = 0.003 rad), ``seed002-ur5``,
``seed002-claims`` (the paper's two comparisons with (35) examined: the noise-free
transient per 0.5 s window with one setting changed at a time, and the noise std at which the
steady-state ordering flips, by bisection, per noise realisation).
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np

from ...core.target import Discretization
from ...verify.trajectory import inverse_dynamics_function
from ..sim import plots
from ..sim.blocks import block
from ..sim.plant import Plant

KP, KD = 400.0, 40.0                     # computed-torque gains, docs/papers/experiments.md §12.2
SU_INIT = np.array([2.0, 2.0, -1.0, -1.0])   # est0 = [qd_hat(0), qhat(0)], [S002 §V-B]


# ---------------------------------------------------------------------------- plant side
def seed002_reference(t):
    """q_d, qd_d, qdd_d of q_d = [sin 10 t, cos 10 t]  [S002 §V]."""
    w = 10.0
    return (np.array([np.sin(w * t), np.cos(w * t)]), w * np.array([np.cos(w * t), -np.sin(w * t)]),
            -w * w * np.array([np.sin(w * t), np.cos(w * t)]))


def sinusoid_reference(robot, amplitude=0.6, omega=1.5, seed=3):
    """q_d = q_c + A sin(w_i t + phi_i) per joint, inside the joint ranges of ``robot`` (ur5 run):
    A = ``amplitude`` rad, w_i = ``omega`` (1 + 0.3 i) rad/s, q_c and phi_i drawn with ``seed``.
    Returns ref(t) -> (q_d, qd_d, qdd_d), each (n,)."""
    rng = np.random.default_rng(seed)
    n = robot.n
    lo, hi = np.maximum(robot.q_lower, -np.pi), np.minimum(robot.q_upper, np.pi)
    qc = 0.5 * (lo + hi) + rng.uniform(-0.5, 0.5, n)
    w = omega * (1.0 + 0.3 * np.arange(n))
    phi = rng.uniform(0, 2 * np.pi, n)

    def ref(t):
        s, c = np.sin(w * t + phi), np.cos(w * t + phi)
        return qc + amplitude * s, amplitude * w * c, -amplitude * w * w * s
    return ref


def track(robot, reference, T, dt, substeps=1):
    """Closed-loop computed-torque tracking (module docstring, KP, KD) of ``robot`` with the true
    state, from q_d(0): ``reference(t)`` -> (q_d, qd_d, qdd_d), horizon ``T`` and sample period ``dt``
    in s, ``substeps`` plant RK4 steps per sample. Returns t (N,) s, Q, QD, TAU (N, n) rad, rad/s, N m."""
    N = int(round(T / dt)) + 1
    plant = Plant(robot, dt, substeps=substeps)
    ct = inverse_dynamics_function(robot)          # computed torque: M a + C qd + F qd + g
    qd0, vd0, _ = reference(0.0)
    plant.reset(qd0, vd0)
    n = robot.n
    X, TAU = np.empty((N, 2 * n)), np.empty((N, n))
    x = plant.state
    for k in range(N):
        q_d, v_d, a_d = reference(k * dt)
        q, v = x[:n], x[n:]
        tau = np.asarray(ct(q, v, a_d + KD * (v_d - v) + KP * (q_d - q))).reshape(-1)
        X[k], TAU[k] = x, tau
        if k < N - 1:
            x = plant.advance(tau)
    return np.arange(N) * dt, X[:, :n], X[:, n:], TAU


def noisy(Q, std, dt, rate=1e3, seed=0):
    """q_s = q + n for ``Q`` (N, n) rad sampled every ``dt`` s, n ~ N(0, std^2) (``std`` scalar or
    (n,) rad) drawn at ``rate`` Hz with ``seed`` and held (A2-3). Returns (N, n)."""
    std = np.broadcast_to(np.asarray(std, float), (Q.shape[1],))
    if not np.any(std > 0):
        return Q.copy()
    every = max(1, int(round(1.0 / (rate * dt))))
    rng = np.random.default_rng(seed)
    draws = rng.normal(size=((len(Q) + every - 1) // every, Q.shape[1])) * std
    return Q + np.repeat(draws, every, axis=0)[: len(Q)]


# ---------------------------------------------------------------------------- observers
def run_observer(spec, Y, U, dt, reference=False, est0=None):
    """EST (N, nest) of ``spec`` over the samples ``Y`` (N, ny), ``U`` (N, nu) (C, or the numpy
    reference if ``reference``), from ``est0`` (None: zeros), RK4 with step ``dt`` s and y held over
    each step (zero-order hold: the sign of (35) integrated literally, docs/papers/seed002.md §3.3)."""
    obs = block(spec, Discretization(dt=dt, method="rk4", hold="zoh"), reference=reference)
    obs.reset(Y[0], est0=est0)
    return obs.run(Y, U)


def _window(t, T_ss):
    return t >= t[-1] - T_ss


def _rms(E):
    return float(np.sqrt(np.mean(np.sum(E ** 2, axis=1))))


_TRACKS = {}


def experiment(robot_name="seed002_2r", T=5.0, dt=1e-4, noise=0.0, reference=False,
               su=True, reference_traj=None, substeps=1, T_ss=1.0, seed=0, rows="all", gains=None,
               su_est0=None):
    """Run the plant and the observers; returns a dict of arrays (see ``summarize``).

    robot_name      a models.load_robot name; seed002_2r tracks seed002_reference, others a
                    sinusoid_reference unless ``reference_traj`` (t -> q_d, qd_d, qdd_d) is given
    T, dt, T_ss     horizon, step and steady-state window [T - T_ss, T], s
    noise    0 (none), "rms30" (std = 0.3 RMS(q_i), A2-3) or a std in rad; ``seed`` of the draws
    reference       numpy reference observers instead of the compiled C
    su              also run the non-smooth observer (35) [S002 (35)]
    substeps        plant RK4 steps per sample;  rows: the non-minimal model's rows [S002 (2)-(11)]
    gains    keyword arguments of the adaptive observer's ``build`` (alpha, lam, gamma,
             thetahat0, zhat1_from_y0); None: Table II
    su_est0  initial [qd_hat, qhat] of (35); None: the seed's [2, 2, -1, -1] on the 2R arm"""
    from models import load_robot

    from ...families.observers import build
    from ...families.observers.lotfi_namvar import nonminimal
    robot = load_robot(robot_name)
    ref = reference_traj or (seed002_reference if robot_name == "seed002_2r" else sinusoid_reference(robot))
    key = (robot_name, T, dt, substeps) if reference_traj is None else None
    if key is None or key not in _TRACKS:
        run = track(robot, ref, T, dt, substeps)
        if key is not None:
            _TRACKS.clear()                    # keep one plant run: tests reuse it across noise levels
            _TRACKS[key] = run
    t, Q, QD, TAU = _TRACKS[key] if key is not None else run
    if isinstance(noise, str):
        if noise != "rms30":
            raise ValueError(f"noise must be a number or 'rms30', got {noise!r}")
        std = 0.3 * np.sqrt(np.mean(Q ** 2, axis=0))
    else:
        std = np.full(robot.n, float(noise))
    Qs = noisy(Q, std, dt, seed=seed)
    spec = build("lotfi_namvar", robot, rows=rows, **(gains or {}))
    nm = nonminimal(robot, rows)
    N = len(t)
    FF = np.asarray(nm.force_function().map(N)(Q.T, QD.T, TAU.T)).T            # docs/papers/seed002.md §3.1
    qs = ca.SX.sym("q", robot.n)
    J_fun = ca.Function("J_n", [qs], [nm.jacobian(qs)])
    Jall = np.asarray(J_fun.map(N)(Q.T)).reshape(nm.r, N, len(nm.joints))
    NU = np.einsum("rkj,kj->kr", Jall, QD[:, nm.joints])                        # [S002 (9)]
    EST = run_observer(spec, np.hstack([Qs, FF]), TAU, dt, reference)
    no, r = len(nm.joints), nm.r
    out = {"robot": robot_name, "t": t, "q": Q, "qd": QD, "tau": TAU, "q_s": Qs, "std": std,
           "f_f": FF, "nu": NU, "joints": nm.joints, "row_names": nm.row_names,
           "theta": nm.theta, "qd_hat": EST[:, :no], "nu_hat": EST[:, no:no + r],
           "theta_hat": EST[:, no + r:], "T_ss": T_ss, "dt": dt, "reference": reference,
           "J_n_smin": np.linalg.svd(Jall.transpose(1, 0, 2), compute_uv=False)[:, -1]}
    if su:
        sspec = build("su_nonsmooth", robot)
        est0 = su_est0 if su_est0 is not None else SU_INIT if robot.n == 2 else None
        out["su_est"] = run_observer(sspec, Qs, TAU, dt, reference, est0=est0)
        out["qd_hat_su"] = out["su_est"][:, :robot.n]
    return out


def summarize(d):
    """Figures of merit of the ``experiment`` dict ``d``: thetahat at the end, nu and qd errors at
    the end and their RMS over the steady-state window [T - T_ss, T]."""
    t, J = d["t"], d["joints"]
    ss = _window(t, d["T_ss"])
    e_qd = d["qd_hat"] - d["qd"][:, J]
    e_nu = d["nu_hat"] - d["nu"]
    s = {"robot": d["robot"], "T": float(t[-1]), "dt": d["dt"],
         "noise_std": [float(x) for x in d["std"]],
         "observable_joints": [int(j) for j in J],
         "theta_true": [float(x) for x in d["theta"]],
         "thetahat_final": [float(x) for x in d["theta_hat"][-1]],
         "nu_err_final_max": float(np.abs(e_nu[-1]).max()),
         "qd_err_final_max": float(np.abs(e_qd[-1]).max()),
         "qd_err_rms_ss_adaptive": _rms(e_qd[ss]),
         "nu_err_rms_ss": _rms(e_nu[ss])}
    if "qd_hat_su" in d:
        e_su = d["qd_hat_su"] - d["qd"]
        s["qd_err_final_max_su"] = float(np.abs(e_su[-1]).max())
        s["qd_err_rms_ss_su"] = _rms(e_su[ss])
    s["observers"] = "numpy reference" if d["reference"] else "compiled C"
    return s


# ---------------------------------------------------------------------------- the two open claims
WINDOWS = ((0.0, 0.5), (0.5, 1.0), (1.0, 1.5), (1.5, 2.0))   # s, the transient
TABLE_II_GAMMA = np.array([200.0, 250.0, 250.0, 100.0])
TRANSIENT_CASES = {   # name -> (adaptive gains, (35)'s initial estimate); None = the paper's
    "paper (Table II, (35) from [2, 2, -1, -1])": (None, None),
    "thetahat(0) = theta": ({"thetahat0": [0.5, 0.5, 1.0, 1.0]}, None),
    "gamma x 4": ({"gamma": 4 * TABLE_II_GAMMA}, None),
    "gamma / 4": ({"gamma": TABLE_II_GAMMA / 4}, None),
    "alpha = 60": ({"alpha": 60.0}, None),
    "lambda = 48": ({"lam": 48.0}, None),
    "zhat1(0) = pi(q0)": ({"zhat1_from_y0": 1.0}, None),
    "(35) from [0, 0, q(0)]": (None, np.array([0.0, 0.0, 0.0, 1.0])),
}


def windowed_rms(d, windows=WINDOWS):
    """RMS over each window [a, b) of ||qd_hat - qd|| for the adaptive observer and (35), and of
    ||nuhat - nu|| (rad/s, m/s) in the ``experiment`` dict ``d`` (run with su=True), ``windows`` in s:
    {"adaptive": [...], "su": [...], "nu": [...]}."""
    t, J = d["t"], d["joints"]
    errs = {"adaptive": d["qd_hat"] - d["qd"][:, J], "su": d["qd_hat_su"] - d["qd"], "nu": d["nu_hat"] - d["nu"]}
    return {k: [_rms(E[(t >= a) & (t < b)]) for a, b in windows] for k, E in errs.items()}


def transient_study(T=2.0, cases=TRANSIENT_CASES):
    """The noise-free transient of the adaptive observer (13) against (35) per
    window WINDOWS, for the paper's setting and one change at a time (thetahat(0), gamma, alpha,
    lambda, zhat(0), (35)'s initial estimate); plus the conditioning of J_n along the run.
    ``cases``: name -> (adaptive gains, (35)'s est0), see TRANSIENT_CASES; runs of ``T`` s."""
    rows = {}
    for name, (gains, su0) in cases.items():
        d = experiment(T=T, gains=gains, su_est0=su0)
        rows[name] = windowed_rms(d)
    smin = d["J_n_smin"]
    return {"windows_s": [list(w) for w in WINDOWS], "qd_error_rms": rows,
            "J_n_sigma_min": {"min": float(smin.min()), "median": float(np.median(smin))}}


def ordering(std, T=5.0, seed=0):
    """log(RMS_adaptive / RMS_(35)) of the steady-state joint-velocity error (last 1 s of T) at
    noise std (rad) drawn with ``seed``: < 0 while the adaptive observer is the quieter one."""
    s = summarize(experiment(T=T, noise=float(std), seed=seed))
    return float(np.log(s["qd_err_rms_ss_adaptive"] / s["qd_err_rms_ss_su"]))


def flip_noise(lo=0.03, hi=0.3, rel_tol=0.02, T=5.0, seed=0):
    """The noise std (rad, 1 kHz, held) at which the steady-state ordering of the
    adaptive observer and (35) flips, by bisection on log(std) between lo (adaptive quieter) and
    hi (adaptive noisier), until hi / lo <= 1 + ``rel_tol``; runs of ``T`` s, noise drawn with ``seed``.
    Returns {"std_rad", "bracket", "evaluations"}."""
    f_lo, f_hi = ordering(lo, T, seed), ordering(hi, T, seed)
    if not (f_lo < 0 < f_hi):
        raise ValueError(f"no flip between lo={lo} ({f_lo:+.3f}) and hi={hi} ({f_hi:+.3f})")
    evals = [(lo, f_lo), (hi, f_hi)]
    while hi / lo > 1 + rel_tol:
        mid = float(np.sqrt(lo * hi))
        f = ordering(mid, T, seed)
        evals.append((mid, f))
        lo, hi = (mid, hi) if f < 0 else (lo, mid)
    return {"std_rad": float(np.sqrt(lo * hi)), "bracket": [lo, hi],
            "evaluations": [[float(a), float(b)] for a, b in sorted(evals)]}


FLIP_SEEDS = (0, 1, 2)                 # noise realisations of the flip search


def claims(reference=False, out=Path("build/sim") / "seed002-claims"):
    """Scenario seed002-claims: the transient study (4a) and the flip noise level (4b), the
    latter per noise realisation FLIP_SEEDS (it moves with the realisation), 5 s runs. Compiled
    observers only (``reference`` must be False); ``out`` is accepted for the scenario interface."""
    if reference:
        raise ValueError("seed002-claims runs the compiled observers only (reference=False)")
    flips = {seed: flip_noise(seed=seed, rel_tol=0.05) for seed in FLIP_SEEDS}
    std = np.array([f["std_rad"] for f in flips.values()])
    rms_q = np.sqrt(np.mean(experiment(T=5.0)["q"] ** 2, axis=0))
    return {"transient": transient_study(),
            "flip": {"std_rad_per_seed": {str(k): f["std_rad"] for k, f in flips.items()},
                     "std_rad_median": float(np.median(std)), "std_rad_range": [float(std.min()), float(std.max())],
                     "median_over_rms_q": [float(np.median(std) / r) for r in rms_q],
                     "spec_30pct_std_rad": [float(0.3 * r) for r in rms_q],
                     "bisection": {str(k): f["evaluations"] for k, f in flips.items()}}}


def plot(d, out, tag):
    """Figures in the spirit of [S002 Figs. 1–4] of the ``experiment`` dict ``d``, written to the
    folder ``out``, titles prefixed by ``tag``."""
    out = Path(out)
    t, J, names = d["t"], d["joints"], d["row_names"]
    e_nu = d["nu_hat"] - d["nu"]
    r = e_nu.shape[1]
    plots.panels(out / "fig1_nu_error.png", t,
                 [plots.Panel({"": e_nu[:, j]}, title=f"nu~ {names[j]}", legend=False,
                              ylabel="nu_hat - nu [m/s]") for j in range(r)],
                 title=f"{tag}: link velocity estimation error (cf. Fig. 1)", cols=min(r, 4), cell=(3.2, 2.4))
    theta = plots.Panel({f"thetahat {names[j]}": d["theta_hat"][:, j] for j in range(r)}, legend=r <= 6,
                        hlines=np.unique(np.round(d["theta"], 12)),
                        ylabel="thetahat = 1/m [1/kg]")
    plots.panels(out / "fig2_thetahat.png", t, [theta], title=f"{tag}: parameter estimates (cf. Fig. 2)",
                 cell=(6, 3.5))
    errors = [("adaptive observer (13)", d["qd_hat"] - d["qd"][:, J], J)]
    if "qd_hat_su" in d:
        errors.append(("non-smooth observer (35)", d["qd_hat_su"] - d["qd"], range(d["qd"].shape[1])))
    ss = _window(t, d["T_ss"])
    for name, sel, title in (("fig3_qd_error.png", slice(None), "joint velocity error (cf. Fig. 3)"),
                             ("fig4_qd_error_steady.png", ss, "steady state (cf. Fig. 4)")):
        rows = [plots.Panel({f"qd~_{j + 1}": e[sel, k] for k, j in enumerate(joints)}, title=which,
                            ylabel="qd_hat - qd [rad/s]")
                for which, e, joints in errors]
        plots.panels(out / name, t[sel], rows, title=f"{tag}: {title}", cell=(7, 2.6))


def _scenario(tag, **kw):
    def run(reference=False, out=Path("build/sim") / tag):
        d = experiment(reference=reference, **kw)
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        plot(d, out, tag)
        s = summarize(d)
        s["noise"] = kw.get("noise", 0.0)
        return s
    run.__doc__ = f"Scenario {tag}: experiment({kw})."
    return run


SCENARIOS = {
    "seed002": _scenario("seed002", noise=0.0),
    "seed002-noisy": _scenario("seed002-noisy", noise="rms30"),
    "seed002-noise-3mrad": _scenario("seed002-noise-3mrad", noise=0.003),
    "seed002-claims": claims,
    "seed002-ur5": _scenario("seed002-ur5", robot_name="ur5", T=20.0, dt=1e-3, su=False,
                             substeps=2, T_ss=2.0),
}
# one line each for `simulate list` (docs/papers/experiments.md §12.2)
DESCRIPTIONS = {
    "seed002": "seed 002 (Lotfi & Namvar; Su): adaptive observer vs Su's (35), noise-free (Figs. 1-2)",
    "seed002-noisy": "seed 002 (Lotfi & Namvar; Su): the same, noise std 0.3 RMS(q_i) (Figs. 3-4)",
    "seed002-noise-3mrad": "seed 002 (Lotfi & Namvar; Su): the same, noise std 0.003 rad",
    "seed002-claims": "seed 002 (Lotfi & Namvar; Su): the paper's claims checked (transient, the noise level where they flip)",
    "seed002-ur5": "seed 002 (Lotfi & Namvar; Su), beyond the paper: the adaptive observer on ur5 (20 s)",
}
