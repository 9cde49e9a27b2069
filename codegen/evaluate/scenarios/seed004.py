"""Seed 004 (Caciolai & Pustina): elastic-joint robots, Tomei and Ciccarella-Germani observers,
Spong's controllers. Simulations 1-10 of docs/papers/experiments.md §12.4: ``python -m codegen simulate seed004-simK``.

Discretisation (stated; the seed integrates the continuous-time loop with ode15s): every block
is sampled at dt = 1e-4 s.
  * plant: RK4 with 2 substeps (h = 5e-5 s; fastest plant mode ~ sqrt(K (M^-1 + J^-1)) ~ 260
    rad/s, h |lambda| ~ 0.013), u held over the sample (zero-order hold);
  * controllers: evaluated once per sample (zero-order hold on u);
  * observers: RK4 with a first-order hold on the measurements (``hold="foh"``: y linear
    between samples, u held as the plant saw it), which is the continuous-time observer driven
    by a piecewise-linear y. With the plain zero-order hold the held y lags the true one by up
    to dt |q'|; in Sims 6/8 (link speeds up to ~670 rad/s) that alone leaves a persistent
    estimation error of ~5 (O2, O3 do not reach 2 %). 2R: one RK4 step per sample (fastest
    observer eigenvalue -1000: h |lambda| = 0.1). 3R: 4 RK4 substeps per sample (h = 2.5e-5):
    O4 from the Sim-6 state has a transient of ~1e5 in the estimated velocities (the "very large
    transient" of Sim 10) and one or two substeps are not enough to follow it (RK4 blows up /
    does not converge); 4 and 8 substeps give the same convergence time (0.29 s / 0.30 s).
    The 3R kernels call the RHS routine instead of inlining it (``inline=False``): ~1 s compile.
``dt_check`` in Sim 1's summary compares with dt = 5e-5.

Figures: one PNG per figure of the paper, named after it (``fig08_sim3_o1_errors.png``), with
the paper's quantities (per-component errors x - xhat of link and motor positions and
velocities; link tracking errors; the desired trajectory) over the paper's time spans
(FIG_SPAN, read off the axes of the authors' report), each with a CSV of the plotted data;
``run.csv`` holds the whole run at 1 kHz. The 3R manifold controller uses the authors' fast
poles 70 [-1, -1.2, ..., -1.6] (docs/papers/seed004.md §10), the 2R one the seed's -70 {1.1, ..., 1.4} (A4-5).

When the controller uses the true state, the plant/controller loop runs first and the observers
then run over the recorded (y, u) in C (``obs.run``): they do not act on the loop. With an
estimated state (Sim 2) the observer is stepped inside the loop.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ...core.target import Discretization
from ..sim import plots
from ..sim.blocks import bind, block, stage
from ..sim.elastic_plant import ElasticPlant
from ..sim.engine import write_columns

DT = 1e-4
PLANT_SUBSTEPS = 2
OBSERVER_HOLD = "foh"
OBSERVER_SUBSTEPS = {2: 1, 3: 4}          # per number of joints (see the module docstring)
T_SIM, T_TRAJ = 10.0, 5.0
THRESHOLD = 0.02                  # convergence: ||e(t)|| < 2 % of ||e(0)|| from then on
FAST_POLES_2R = -70.0 * np.array([1.1, 1.2, 1.3, 1.4])     # [S004 Sim. 2] (A4-5: the seed's set)
FAST_POLES_3R = 70.0 * np.array([-1, -1.2, -1.3, -1.4, -1.5, -1.6])   # [CODE-CP config_3R.m] docs/papers/seed004.md §10
STATE_BLOCKS = ("link_q", "link_qd", "motor_q", "motor_qd")   # x = [q1; q1'; q2; q2'] (docs/papers/seed004.md §6)
CSV_EVERY = 10                    # run.csv (and figure CSVs over spans > 1 s) at 1 kHz
FIG_SPAN = {3: 2.2, 4: 0.045, 8: 0.2, 9: 0.2, 10: 0.1, 11: 0.032, 12: 0.5, 13: 0.1,
            14: 0.2, 15: 0.05, 16: 0.15, 17: 0.2}   # time axis of the paper's figures [s] (report.pdf)


# ---------------------------------------------------------------------------- building blocks
def _robot(name):
    from models.catalog import load_elastic
    return load_elastic(name)


def observer(robot, kind, eigenvalues=None, reference=False, dt=DT, hold=OBSERVER_HOLD, substeps=None):
    """A stepped observer of ``robot``: kind 'tomei' [docs/papers/seed004.md §7] or 'O1'..'O4' [docs/papers/seed004.md §8] with the
    given ``eigenvalues`` (CG only; None: its default), C or the numpy ``reference``; RK4 with
    ``substeps`` (None: OBSERVER_SUBSTEPS) per sample of ``dt`` s, measurement ``hold``.
    Returns (spec, block)."""
    from ...families.observers import ciccarella_germani, tomei
    spec = tomei.build(robot) if kind == "tomei" else \
        ciccarella_germani.build(robot, kind, eigenvalues=eigenvalues)
    substeps = OBSERVER_SUBSTEPS.get(robot.n, 4) if substeps is None else substeps
    disc = Discretization(dt=dt, method="rk4", hold=hold, substeps=substeps)
    return spec, block(spec, disc, reference=reference, inline=robot.n < 3)


def measurement(spec, X):
    """The measurement rows (N, ny) of the observer ``spec`` for true states X (N, 4n),
    ``x = [q1; q1'; q2; q2']`` [docs/papers/seed004.md §6]."""
    n = X.shape[1] // 4
    x1, x2, x3 = X[:, :n], X[:, n:2 * n], X[:, 2 * n:3 * n]
    names = spec.y_names
    if spec.family == "tomei":
        return np.hstack([x1, x2])
    v = spec.variant
    if v == "O1":
        return x1
    if v == "O4":
        return x3
    if v == "O2":
        return np.stack([x1, x2], axis=2).reshape(len(X), 2 * n)
    K = np.diag(spec.robot.K)
    assert len(names) == 2 * n
    return np.hstack([x3, (x1 - x3) * K])


def controller(robot, kind, dt=DT):
    """Spong's controller, kind 'fl' (feedback linearisation) or 'manifold' (fast poles
    FAST_POLES_2R / FAST_POLES_3R) of ``robot`` [docs/papers/seed004.md §9, §10], compiled; evaluated once per
    sample of ``dt`` s (u held)."""
    from ...families.controllers import spong
    if kind == "fl":
        spec = spong.feedback_linearization(robot)
    else:
        spec = spong.integral_manifold(robot, fast_poles=FAST_POLES_2R if robot.n == 2 else FAST_POLES_3R)
    return block(spec, Discretization(dt=dt, method="rk4", hold="zoh"))


def reference_table(t, q0, qf, T=T_TRAJ):
    """Rows [q_d and its derivatives 1..4] (N, 5n) of spong.cubic_reference at the times t (N,) s:
    cubic rest-to-rest from ``q0`` to ``qf`` (n,) rad in ``T`` s, then held [docs/papers/experiments.md §12.4]."""
    q0, qf = np.asarray(q0, float), np.asarray(qf, float)
    t = np.asarray(t, float)[:, None]
    s = np.clip(t / T, 0.0, 1.0)
    dq = qf - q0
    moving = ((t > 0) & (t < T)).astype(float)
    return np.hstack([q0 + dq * (3 * s ** 2 - 2 * s ** 3), moving * dq * (6 * s - 6 * s ** 2) / T,
                      moving * dq * (6 - 12 * s) / T ** 2, moving * (-12 * dq / T ** 3) + 0 * s,
                      0 * dq + 0 * s])


def closed_loop(robot, ctrl, x0, qf, T=T_SIM, dt=DT, est_observer=None, est0=None):
    """Plant ``robot`` + compiled controller ``ctrl`` (+ observer feeding the controller). Returns
    t (N,) s, X (N, 4n), U (N, n) N m (and EST (N, 4n)). The loop runs in Python over bound C calls
    (no per-call checks; a non-zero C status still raises).

    x0 (4n,) initial state; qf (n,) final link position (rad) of reference_table; T, dt in s;
    est_observer: (spec, block) of :func:`observer` whose estimate, from ``est0``, replaces x."""
    stage(f"closed loop of {robot.name}: {T:g} s at dt {dt:g} s"
          + (" with the estimated state" if est_observer else ""))
    plant = ElasticPlant(robot, dt, substeps=PLANT_SUBSTEPS)
    x0 = np.asarray(x0, dtype=float)
    plant.reset(x0)
    n, nx = robot.n, robot.nx
    N = int(round(T / dt)) + 1
    t = np.arange(N) * dt
    R = reference_table(t, x0[:n], qf)
    X, U = np.empty((N, nx)), np.empty((N, n))
    EST = np.empty((N, nx)) if est_observer else None
    cin, u, x, none = np.zeros(9 * n), np.zeros(n), np.zeros(nx), np.zeros(1)
    _, ctrl_u = bind(ctrl, cin, none, u)
    plant_step, plant_x = bind(plant.block, none, u, x)
    if est_observer:
        spec, obs = est_observer
        y_of = lambda xx: measurement(spec, xx[None])[0]  # noqa: E731
        y, est = np.zeros(max(1, len(spec.y_names))), np.zeros(nx)
        obs_step, obs_est = bind(obs, y, u, est)
        obs.reset(y_of(x0), est0)
    for k in range(N):
        plant_x()                      # x = x_k (output of the plant block, no advance)
        X[k] = x
        if est_observer:
            y[:] = y_of(x)
            obs_est()                  # the estimate at t_k (u unused by the estimate)
            EST[k] = est
            cin[:nx] = est
        else:
            cin[:nx] = x
        cin[nx:] = R[k]
        ctrl_u()                       # u = u_k
        U[k] = u
        if est_observer:
            obs_step()                 # u_k is what the plant sees over [t_k, t_k+1]
        plant_step()
    return (t, X, U, EST) if est_observer else (t, X, U)


def run_observer(spec, obs, X, U, est0):
    """Observer ``obs`` (of ``spec``) over recorded true states ``X`` (N, 4n) and inputs ``U`` (N, n),
    from the initial estimate ``est0`` (4n,): EST (N, 4n), the estimate at each sample."""
    stage(f"running {spec.family}{'' if spec.variant is None else ' ' + spec.variant} over {len(X)} samples")
    Y = measurement(spec, X)
    obs.reset(Y[0], est0)
    return obs.run(Y, U)


def convergence_time(t, E, threshold=THRESHOLD):
    """First t after which ||E(t)|| < threshold ||E(0)|| for good (inf if never)."""
    nrm = np.linalg.norm(E, axis=1)
    bad = np.flatnonzero(~(nrm < threshold * nrm[0]))
    if bad.size == 0:
        return 0.0
    return float(t[bad[-1] + 1]) if bad[-1] + 1 < len(t) else float("inf")


def _safe_run(spec, obs, X, U, est0):
    """run_observer, or (None, reason) when the observer blows up (non-finite state)."""
    try:
        return run_observer(spec, obs, X, U, est0), None
    except Exception as exc:  # ObserverError / FloatingPointError: the observer diverged
        return None, f"{type(exc).__name__}: {str(exc)[:120]}"


def _run_until_failure(spec, obs, X, U, est0):
    """Sample by sample until the observer fails: (estimates so far (k, 4n), k)."""
    Y = measurement(spec, X)
    obs.reset(Y[0], est0)
    EST = []
    for k in range(len(Y)):
        try:
            EST.append(obs.step(Y[k], U[k]))
        except Exception:
            break
    return np.array(EST).reshape(-1, X.shape[1]), len(EST)


def sign_changes(t, E, t_end, floor=1e-3):
    """Oscillation measure: sign changes of the error components of ``E`` (N, m) over t <= t_end
    (t (N,) s), summed over components, ignoring samples where |e_j| < floor * max_t |e_j|
    (no flicker around zero)."""
    E = E[t <= t_end]
    total = 0
    for e in E.T:
        big = e[np.abs(e) >= floor * max(np.abs(e).max(), 1e-300)]
        total += int(np.count_nonzero(np.diff(np.sign(big))))
    return total


# ---------------------------------------------------------------------------- figures and CSVs
def _stride(span):
    """Rows kept in a CSV: every sample over a short span, every CSV_EVERY-th over a long one."""
    return 1 if span <= 1.0 else CSV_EVERY


def _window(t, span):
    """Samples with t <= span (to half a sample)."""
    return slice(0, int(np.searchsorted(t, span + 0.5 * (t[1] - t[0]), side="right")))


def error_figure(out, fig, name, t, E, title):
    """[S004 Fig. fig]: the per-component errors E (N, 4n) over the paper's span FIG_SPAN[fig]
    (or as far as E goes) against t (N,) s as <out>/figNN_<name>.png and .csv, with ``title``.
    Returns {"png", "csv", "span_s"}."""
    w = _window(t, FIG_SPAN[fig])
    t, E = t[w][:len(E)], E[w][:len(t[w])]
    stem = Path(out) / f"fig{fig:02d}_{name}"
    n = E.shape[1] // 4
    png = plots.elastic_errors(stem.with_suffix(".png"), t, E, title=f"Fig. {fig}: {title}")
    csv = write_columns(stem.with_suffix(".csv"),
                        {"t": t, **{f"e_{k}": E[:, i * n:(i + 1) * n] for i, k in enumerate(STATE_BLOCKS)}})
    return {"png": str(png), "csv": str(csv), "span_s": float(t[-1])}


def trajectory_figure(out, fig, name, t, R, n, title):
    """[S004 Figs. 2, 7]: the desired trajectory (q_d and derivatives 1..3) as PNG and CSV
    <out>/figNN_<name> for paper figure ``fig``, with ``title``: t (N,) s, R (N, >= 4n) rows of
    reference_table, n joints. Returns {"png", "csv"}."""
    stem = Path(out) / f"fig{fig:02d}_{name}"
    png = plots.joint_trajectory(stem.with_suffix(".png"), t, R, n, title=f"Fig. {fig}: {title}")
    k = slice(None, None, _stride(t[-1]))
    csv = write_columns(stem.with_suffix(".csv"), {"t": t[k], **{name: R[k, d * n:(d + 1) * n] for d, name in
                                                                  enumerate(("q_d", "qd_d", "qdd_d", "qddd_d"))}})
    return {"png": str(png), "csv": str(csv)}


def tracking_figure(out, fig, name, t, errors, title):
    """[S004 Figs. 5, 6]: one panel per controller, the link tracking errors q_d - q1 (N, n) of
    ``errors`` (label -> array, or None when the run failed) against t (N,) s, 0-10 s, as PNG and
    CSV <out>/figNN_<name> for paper figure ``fig``, with ``title``. Returns {"png", "csv", "failed"}."""
    stem = Path(out) / f"fig{fig:02d}_{name}"
    done = {k: e for k, e in errors.items() if e is not None}
    rows = [plots.Panel({f"Link {i + 1} tracking error": e[:, i] for i in range(e.shape[1])},
                        ylabel="q_d - q1 [rad]", title=label) for label, e in done.items()]
    png = plots.panels(stem.with_suffix(".png"), t, rows, title=f"Fig. {fig}: {title}", cell=(8, 2.8))
    k = slice(None, None, _stride(t[-1]))
    csv = write_columns(stem.with_suffix(".csv"),
                        {"t": t[k], **{f"{label.split()[0]}_e": e[k] for label, e in done.items()}})
    return {"png": str(png), "csv": str(csv), "failed": [k for k, e in errors.items() if e is None]}


def write_run(out, t, X, U, estimates, name="run.csv"):
    """<out>/<name>: t, true state, input and each observer's estimate, every CSV_EVERY-th
    sample (1 kHz); an estimate shorter than t (an observer that failed) is padded with NaN.
    X (N, 4n), U (N, n); ``estimates`` name -> (<= N, 4n). Returns the path as str."""
    n = X.shape[1] // 4
    k = slice(None, None, CSV_EVERY)
    cols = {"t": t[k], **{k_: X[k, i * n:(i + 1) * n] for i, k_ in enumerate(STATE_BLOCKS)}, "u": U[k]}
    for kind, EST in estimates.items():
        full = np.full(X.shape, np.nan)
        full[:len(EST)] = EST
        cols[f"{kind}_est"] = full[k]
    return str(write_columns(Path(out) / name, cols))


# ---------------------------------------------------------------------------- Sim 1
SIM1_X0 = np.array([-np.pi / 2, 0, 0, 0, -np.pi / 2, 0, 0, 0])
SIM1_XHAT0 = np.array([-np.pi / 2, 0, 0, 0, 0, 0, 0, 0])
QF_2R = [np.pi / 2, 0]
O1_2R = -100.0 * np.arange(3, 11)                 # [S004 Sim. 1] sigma(A - KC) = -100 {3, ..., 10}


def sim1(reference=False, out="build/sim/seed004-sim1", T=T_SIM, dt=DT, dt_check=True):
    """2R: Tomei (A = K2 = Q = 2000 I, Ka_eff = 10000 I) vs CG O1 (-100{3..10}); true-state FL
    controller (A4-10) on the swing-up reference. Figs. 2-4, run.csv.
    C or numpy ``reference`` observers; figures and CSVs in the folder ``out``; horizon ``T`` and
    sample period ``dt`` in s. Returns the summary dict.
    ``dt_check``: rerun O1 over 0.2 s at dt / 2 (its convergence time must not move)."""
    robot = _robot("seed004_2r")
    t0 = time.perf_counter()
    t, X, U = closed_loop(robot, controller(robot, "fl"), SIM1_X0, QF_2R, T=T, dt=dt)
    summary = {"dt": dt, "plant_substeps": PLANT_SUBSTEPS, "controller": "feedback linearisation (true state)"}
    ests, figures = {}, {}
    for kind, eig, fig in (("tomei", None, 3), ("O1", O1_2R, 4)):
        spec, obs = observer(robot, kind, eig, reference=reference, dt=dt)
        ests[kind] = EST = run_observer(spec, obs, X, U, SIM1_XHAT0)
        E = X - EST
        summary[f"{kind}_t_2pct_s"] = convergence_time(t, E)
        summary[f"{kind}_max_motor_velocity_error"] = float(np.abs(E[:, 6:]).max())
        name = "Tomei" if kind == "tomei" else "Ciccarella-Germani O1"
        figures[f"fig{fig:02d}"] = error_figure(out, fig, f"sim1_{kind.lower()}_errors", t, E,
                                                f"Sim 1, estimation error of the {name} observer")
    summary["O1_final_error"] = float(np.linalg.norm(X[-1] - ests["O1"][-1]))
    if dt_check:   # the same O1 run at half the sample time: the figure must not move
        spec, obs = observer(robot, "O1", O1_2R, reference=reference, dt=dt / 2)
        th, Xh, Uh = closed_loop(robot, controller(robot, "fl", dt / 2), SIM1_X0, QF_2R, T=0.2, dt=dt / 2)
        Eh = Xh - run_observer(spec, obs, Xh, Uh, SIM1_XHAT0)
        summary["O1_t_2pct_s_half_dt_0.2s"] = convergence_time(th, Eh)
    summary["max_|u|"] = float(np.abs(U).max())
    summary["tracking_rms_rad"] = float(np.sqrt(np.mean((X[:, :2] - _ref_path(t, SIM1_X0[:2], QF_2R)) ** 2)))
    figures["fig02"] = trajectory_figure(out, 2, "2r_desired_trajectory", t,
                                         reference_table(t, SIM1_X0[:2], QF_2R), 2, "2R desired trajectory")
    summary["figures"] = dict(sorted(figures.items()))
    summary["csv"] = write_run(out, t, X, U, ests)
    summary["wall_s"] = time.perf_counter() - t0
    return summary


def _ref_path(t, q0, qf):
    return reference_table(t, q0, qf)[:, :len(q0)]


# ---------------------------------------------------------------------------- Sim 2
def sim2(reference=False, out="build/sim/seed004-sim2", T=T_SIM, dt=DT):
    """2R: FL vs integral-manifold controller, each with the true state (Fig. 5) and with the
    CG-O1 estimate (Fig. 6; initial estimate as Sim 1). run.csv holds the estimated-state runs.
    C or numpy ``reference`` observers; figures and CSVs in the folder ``out``; horizon ``T`` and
    sample period ``dt`` in s. Returns the summary dict."""
    robot = _robot("seed004_2r")
    t0 = time.perf_counter()
    summary = {"dt": dt, "manifold_fast_poles": FAST_POLES_2R.tolist()}
    errors = {"true": {}, "estimated": {}}
    ests, runs = {}, {}
    for kind in ("fl", "manifold"):
        label = "FL controller" if kind == "fl" else "manifold controller"
        ctrl = controller(robot, kind)
        t, X, U = closed_loop(robot, ctrl, SIM1_X0, QF_2R, T=T, dt=dt)
        R = _ref_path(t, SIM1_X0[:2], QF_2R)
        summary[f"{kind}_true_rms_rad"] = float(np.sqrt(np.mean((X[:, :2] - R) ** 2)))
        errors["true"][label] = R - X[:, :2]
        obs = observer(robot, "O1", O1_2R, reference=reference, dt=dt)
        try:
            t, X, U, EST = closed_loop(robot, ctrl, SIM1_X0, QF_2R, T=T, dt=dt, est_observer=obs,
                                       est0=SIM1_XHAT0)
            summary[f"{kind}_estimated_rms_rad"] = float(np.sqrt(np.mean((X[:, :2] - R) ** 2)))
            errors["estimated"][label] = R - X[:, :2]
            ests[f"{kind}_O1"], runs[kind] = EST, (X, U)
        except Exception as exc:
            summary[f"{kind}_estimated_rms_rad"] = float("inf")
            summary[f"{kind}_estimated_failure"] = str(exc)[:120]
            errors["estimated"][label] = None
    for state in ("true", "estimated"):   # docs/papers/experiments.md §12.4: the manifold controller tracks better
        fl, mf = summary[f"fl_{state}_rms_rad"], summary[f"manifold_{state}_rms_rad"]
        summary[f"fl_over_manifold_rms_{state}"] = fl / mf if mf > 0 else float("inf")
    summary["figures"] = {
        "fig05": tracking_figure(out, 5, "sim2_tracking_state_feedback", t, errors["true"],
                                 "Sim 2, tracking error with state feedback"),
        "fig06": tracking_figure(out, 6, "sim2_tracking_estimated_state", t, errors["estimated"],
                                 "Sim 2, tracking error with the Ciccarella-Germani O1 estimate")}
    summary["csv"] = [write_run(out, t, X, U, {f"{kind}_O1": ests[f"{kind}_O1"]}, name=f"run_{kind}.csv")
                      for kind, (X, U) in runs.items()]
    summary["wall_s"] = time.perf_counter() - t0
    return summary


# ---------------------------------------------------------------------------- Sims 3-10 (3R)
Q3_REST = np.array([0, np.pi / 2, 0])
X0_SIM3 = np.r_[Q3_REST, 0, 0, 0, Q3_REST, 0, 0, 0]
X0_SIM5 = np.r_[-np.pi, np.pi, -np.pi, 0, 0, 0, -np.pi, np.pi, -np.pi, 0, 0, 0]         # (5.4)
X0_SIM6 = np.r_[-np.pi, np.pi, -np.pi, -4, 5, 10, -1.5 * np.pi, 0.5 * np.pi, -np.pi, 6, 10, -20]  # (5.8)
QF_3R = [np.pi / 2, np.pi, 0]                                                             # (5.5)
STUDIES = {
    # sim: (observers with their paper figure, x0, initial estimate, eigenvalue range)
    3: ((("O1", 8), ("O2", 9)), X0_SIM3, np.r_[Q3_REST, np.zeros(9)], (-250, -260)),
    4: ((("O1", 10),), X0_SIM3, np.r_[Q3_REST, np.zeros(9)], (-500, -510)),
    5: ((("O1", 11), ("O2", 12)), X0_SIM5, np.zeros(12), (-85, -90)),
    6: ((("O2", 13),), X0_SIM6, np.zeros(12), (-250, -260)),
    7: ((("O3", 14),), X0_SIM3, np.zeros(12), (-250, -260)),
    8: ((("O3", 15),), X0_SIM6, np.zeros(12), (-250, -260)),
    9: ((("O4", 16),), X0_SIM3, np.zeros(12), (-250, -260)),
    10: ((("O4", 17),), X0_SIM6, np.zeros(12), (-250, -260)),
}


def study_3r(k, reference=False, out=None, T=T_SIM, dt=DT):
    """3R study k (docs/papers/experiments.md §12.4 table): manifold controller (fast poles FAST_POLES_3R) on the true
    state to [pi/2, pi, 0]; the paper's error figures (and Fig. 7 for Sim 3), run.csv.
    C or numpy ``reference`` observers; figures and CSVs in the folder ``out``; horizon ``T`` and
    sample period ``dt`` in s. Returns the summary dict.
    ``out`` None: no files."""
    observers_, x0, xhat0, (e0, e1) = STUDIES[k]
    robot = _robot("seed004_3r")
    t0 = time.perf_counter()
    t, X, U = closed_loop(robot, controller(robot, "manifold"), x0, QF_3R, T=T, dt=dt)
    eig = np.linspace(e0, e1, 12)
    summary = {"dt": dt, "observer": f"RK4 x{OBSERVER_SUBSTEPS[3]} substeps, {OBSERVER_HOLD}",
               "eigenvalues": [e0, e1], "manifold_fast_poles": FAST_POLES_3R.tolist(),
               "max_|u|": float(np.abs(U).max()), "max_|link_velocity|": float(np.abs(X[:, 3:6]).max()),
               "loop_s": time.perf_counter() - t0}
    ests, figures = {}, {}
    for kind, fig in observers_:
        spec, obs = observer(robot, kind, eig, reference=reference, dt=dt)
        EST, fail = _safe_run(spec, obs, X, U, xhat0)
        if EST is None or not np.all(np.isfinite(EST)):
            summary[f"{kind}_converged"] = False
            summary[f"{kind}_failure"] = fail
            EST, k_fail = _run_until_failure(spec, obs, X, U, xhat0)
            if k_fail:
                nrm = np.linalg.norm(X[:k_fail] - EST, axis=1)
                summary[f"{kind}_failed_at_s"] = float(t[k_fail])
                summary[f"{kind}_error_before_failure"] = float(nrm[-1])
                summary[f"{kind}_initial_error"] = float(nrm[0])
        else:
            E = X - EST
            nrm = np.linalg.norm(E, axis=1)
            tc = convergence_time(t, E)
            summary[f"{kind}_converged"] = bool(nrm[-1] < THRESHOLD * nrm[0])
            summary[f"{kind}_t_2pct_s"] = tc
            summary[f"{kind}_initial_error"] = float(nrm[0])
            summary[f"{kind}_peak_error"] = float(nrm.max())
            summary[f"{kind}_peak_velocity_error"] = float(np.abs(E[:, [3, 4, 5, 9, 10, 11]]).max())
            summary[f"{kind}_peak_position_error"] = float(np.abs(E[:, [0, 1, 2, 6, 7, 8]]).max())
            summary[f"{kind}_sign_changes_to_2pct"] = sign_changes(t, E, tc)
            summary[f"{kind}_final_error"] = float(nrm[-1])
        ests[kind] = EST
        if out is not None and len(EST):
            figures[f"fig{fig:02d}"] = error_figure(
                out, fig, f"sim{k}_{kind.lower()}_errors", t, X[:len(EST)] - EST,
                f"Sim {k}, estimation error of {kind}, eigenvalues in [{e0}, {e1}]")
    if out is not None:
        if k == 3:
            figures["fig07"] = trajectory_figure(out, 7, "3r_desired_trajectory", t,
                                                 reference_table(t, x0[:3], QF_3R), 3, "3R desired trajectory")
        summary["figures"] = dict(sorted(figures.items()))
        summary["csv"] = write_run(out, t, X, U, ests)
    summary["wall_s"] = time.perf_counter() - t0
    return summary


def _study(k):
    return lambda reference=False, out=None: study_3r(k, reference=reference, out=out)


SCENARIOS = {"seed004-sim1": sim1, "seed004-sim2": sim2,
             **{f"seed004-sim{k}": _study(k) for k in STUDIES}}
# one line each for `simulate list` (docs/papers/experiments.md §12.4)
PAPER = "seed 004 (Caciolai & Pustina)"
DESCRIPTIONS = {
    "seed004-sim1": f"{PAPER}, Sim 1: 2R, Tomei vs Ciccarella-Germani O1 (Figs. 2-4)",
    "seed004-sim2": f"{PAPER}, Sim 2: 2R, feedback linearisation vs integral manifold (Figs. 5-6)",
    **{f"seed004-sim{k}": f"{PAPER}, Sim {k}: 3R, manifold controller, observer "
       + ", ".join(f"{o} (Fig. {f})" for o, f in obs) + f", eigenvalues in [{lo:g}, {hi:g}]"
       for k, (obs, _, _, (lo, hi)) in STUDIES.items()},
}
