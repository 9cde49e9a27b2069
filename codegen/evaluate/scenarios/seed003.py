"""Seed 003 (Arbo, Grotli & Gravdahl): the I&I speed observer on the two-link arm (docs/papers/experiments.md §12.3),
compared with the reconstructed Astolfi-Ortega-Venkatraman observer (docs/papers/seed003.md §5), and the I&I
observer on ur5 (``seed003-ur5``). The quadrature study is in sim/studies.py, the ur5 benchmark in
codegen/evaluate/bench.py.

Scenario ``seed003``: plant at y(0) = [0, 0], x(0) = [-0.29, 6.66] (Table I), u = 0 [ASSUMPTION
A3-4], horizon 2 s. I&I observer (k1, k2, k3, c_r) = (40, 8, 2.5, 0.001) with state
xi(0) = [-8.45, 68.33], s_y(0) = [1, 2], s_x(0) = [10, 20], r(0) = 0.1 (Table I), set through
``obs.state`` since s_y(0) != y(0). AOV observer: k1 = 10, k2 = 8, k3 = 2.5, c_r = 1, r(0) = 1 and
the same filter states taken literally (qhat(0) = s_y(0), phat(0) = s_x(0), xi(0) = Table I)
[ASSUMPTION, docs/papers/seed003.md §5 item 5].

Sample time: dt = 1e-4 s, RK4, one sub-step, for the plant (10 RK4 sub-steps) and both observers.
The observer's fastest mode is about k1/k_m = 505 1/s plus psi2 ~ r^2/2 ||dbeta/dy||^2, both far
inside RK4's stability interval at this dt while r stays below ~1 (it does here: Fig. 5 shows
the RHS norm growing like r^2 beyond r ~ 1). The observers use the first-order hold on y
(``hold="foh"``): with y held over each sample, xhat carries a bias ~ dt ||dbeta/dy|| |x|
(dbeta/dy ~ k1 M^{-1}, eigenvalues up to k1/k_m = 505 1/s): |xhat - x| ~ 0.07 at dt = 1e-4 and
~ 0.015 at 2e-5, linear in dt (measured); the linear hold removes that first-order term.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ...core.target import Discretization
from ..sim import plots
from ..sim.blocks import block, compiler_flags
from ..sim.engine import simulate
from ..sim.plant import Plant

Y0 = np.array([0.0, 0.0])
X0 = np.array([-0.29, 6.66])
XI0 = np.array([-8.45, 68.33])
SY0 = np.array([1.0, 2.0])
SX0 = np.array([10.0, 20.0])
R0 = 0.1
DT = 1e-4
HOLD = "foh"        # y linear between samples: a zero-order hold biases xhat by O(dt ||dbeta/dy|| |x|)
HORIZON = 2.0


def specs(N=None, wrap="auto", N_period=None):
    """(ii_speed spec, ii_aov spec) of the seed-003 arm with the seed's gains; N, wrap and
    N_period: the quadrature of beta (ii_speed.build, docs/quadrature.md)."""
    from models import load_robot

    from ...families.observers import build
    from ...families.observers.ii_speed import DEFAULT_N
    robot = load_robot("seed003_2r_abs")
    N = N or DEFAULT_N
    q = dict(N=N, wrap=wrap, N_period=N_period)
    return (build("ii_speed", robot, k1=40.0, k2=8.0, k3=2.5, c_r=1e-3, r0=R0, **q),
            build("ii_aov", robot, k1=10.0, k2=8.0, k3=2.5, c_r=1.0, r0=1.0, **q))


def run_seed003(reference=False, out=None, T=HORIZON, dt=DT, plots=True, N=None, wrap="auto",
                N_period=None):
    """Closed loop of docs/papers/experiments.md §12.3 with both observers (I&I speed and AOV).

    Parameters
    ----------
    reference : bool
        Observers by the numpy reference instead of the compiled C.
    out : path-like, optional
        Folder for seed003.npz and (with ``plots``) the figures; None: nothing written.
    T : float
        Horizon, s.
    dt : float
        Sample time, s.
    plots : bool
        Write Figs. 2-5 into ``out``.
    N, wrap, N_period
        The quadrature of beta (``specs``).

    Returns
    -------
    summary : dict
    traces : dict
        t (N,), x (N, 2n), states and est per observer ("ii", "aov").
    """
    sp_ii, sp_aov = specs(N, wrap, N_period)
    robot = sp_ii.robot
    n = robot.n
    plant = Plant(robot, dt, substeps=10)
    disc = Discretization(dt=dt, method="rk4", hold=HOLD)
    obs = {"ii": block(sp_ii, disc, reference=reference), "aov": block(sp_aov, disc, reference=reference)}
    x0 = {"ii": np.concatenate([XI0, SY0, SX0, [R0]]),
          "aov": np.concatenate([XI0, SY0, SX0, [1.0]])}
    for k, o in obs.items():
        o.reset(Y0, np.zeros(2 * n))
        o.state = x0[k]
    plant.reset(Y0, X0)
    N = int(round(T / dt)) + 1
    X = np.empty((N, 2 * n))
    S = {k: np.empty((N, 3 * n + 1)) for k in obs}
    E = {k: np.empty((N, 2 * n)) for k in obs}
    u = np.zeros(n)                                            # [ASSUMPTION A3-4] u = 0
    x = plant.state
    t0 = time.perf_counter()
    for k in range(N):
        X[k] = x
        for name, o in obs.items():
            if HOLD == "zoh":
                S[name][k] = o.state           # the state at t_k (step then advances it)
            E[name][k] = o.step(x[:n], u)
            if HOLD == "foh":
                S[name][k] = o.state           # first-order hold: step brings the state to t_k
        if k < N - 1:
            x = plant.advance(u)
    wall = time.perf_counter() - t0
    t = np.arange(N) * dt
    tr = {"t": t, "x": X, "states": S, "est": E}
    summary = summarize(tr, n)
    summary.update({"dt": dt, "T": T, "method": disc.method, "hold": disc.hold, "plant_substeps": 10,
                    "N_quadrature": sp_ii.options.N, "N_period": sp_ii.options.N_period,
                    "wrap": list(sp_ii.options.periodic),
                    "reference": bool(reference), "wall_s": round(wall, 3),
                    "k_m": sp_ii.design["k_m"], "k_M": sp_ii.design["k_M"],
                    "k_c": sp_ii.design["k_c"]})
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        sweep = stiffness_sweep(obs["ii"])
        summary["fig5_rhs_norm_at_r"] = {f"{r:g}": float(v) for r, v in zip(sweep[0][::10], sweep[1][::10])}
        np.savez(out / "seed003.npz", t=t, x=X, **{f"state_{k}": v for k, v in S.items()},
                 **{f"est_{k}": v for k, v in E.items()}, sweep_r=sweep[0], sweep_norm=sweep[1])
        if plots:
            figures(tr, sweep, out, n)
    return summary, tr


def summarize(tr, n):
    """Convergence figures of both observers (docs/papers/experiments.md §12.3 'Expected') from the traces ``tr`` of
    ``run_seed003``, for ``n`` joints: a dict per observer."""
    t, X = tr["t"], tr["x"]
    q, qd = X[:, :n], X[:, n:]
    res = {}
    for name in ("ii", "aov"):
        St, Et = tr["states"][name], tr["est"][name]
        ey = np.linalg.norm(St[:, n:2 * n] - q, axis=1)
        ex = np.linalg.norm(Et[:, :n] - qd, axis=1)            # filtered speed estimate
        exh = np.linalg.norm(Et[:, n:] - qd, axis=1)           # unfiltered xhat
        r = St[:, -1]

        def settle(err, level):
            above = np.nonzero(err >= level)[0]
            return 0.0 if len(above) == 0 else (float(t[above[-1] + 1]) if above[-1] + 1 < len(t) else float("inf"))

        res[name] = {"|s_y-y| t=0": float(ey[0]), "|s_y-y| final": float(ey[-1]),
                     "t(|s_y-y|<1e-2)": settle(ey, 1e-2),
                     "|s_x-x| t=0": float(ex[0]), "|s_x-x| t=0.5": float(ex[min(np.searchsorted(t, 0.5), len(t) - 1)]),
                     "|s_x-x| final": float(ex[-1]), "t(|s_x-x|<1e-2)": settle(ex, 1e-2),
                     "|xhat-x| final": float(exh[-1]),
                     "r max": float(r.max()), "r final": float(r[-1])}
    return res


def stiffness_sweep(obs, r_grid=None):
    """Fig. 5: ||[xi'; s_y'; s_x'; r']|| of the I&I observer block ``obs`` at the Table-I state
    for r on ``r_grid`` (default a log grid 1e-3..1e2, 51 points); returns (r_grid, norms)."""
    r_grid = np.logspace(-3, 2, 51) if r_grid is None else np.asarray(r_grid)
    vals = [np.linalg.norm(obs.rhs(np.concatenate([XI0, SY0, SX0, [r]]), Y0, np.zeros(2))) for r in r_grid]
    return r_grid, np.array(vals)


def figures(tr, sweep, out, n):
    """Figs. 2-5 of the seed (PNG, see sim/plots.py) into ``out``, from the traces ``tr`` and the
    ``sweep`` of ``stiffness_sweep``, for ``n`` joints."""
    t, X = tr["t"], tr["x"]
    Si, Sa = tr["states"]["ii"], tr["states"]["aov"]
    Ei, Ea = tr["est"]["ii"], tr["est"]["aov"]
    w = t <= 0.2
    plots.per_joint(out / "fig2_angles.png", t[w], X[w, :n],
                    {"s_y (I&I, seed 003)": Si[w, n:], "qhat (AOV)": Sa[w, n:]},
                    ylabel="y{} [rad]", truth_label="y", title="Fig. 2: joint angles")
    plots.per_joint(out / "fig3_speeds.png", t, X[:, n:], {"s_x (I&I)": Ei, "T phat (AOV)": Ea},
                    ylabel="x{} [rad/s]", truth_label="x", title="Fig. 3: joint speeds")
    sq = {"I&I ||s_x - x||^2": np.sum((Ei[:, :n] - X[:, n:]) ** 2, axis=1),
          "AOV": np.sum((Ea[:, :n] - X[:, n:]) ** 2, axis=1)}
    plots.panels(out / "fig4_error_and_r.png", t,
                 [plots.Panel(sq, title="Fig. 4: ||s_x - x||^2", log="y", ylabel="||s_x - x||^2 [(rad/s)^2]"),
                  plots.Panel({"r (I&I)": Si[:, -1], "r (AOV)": Sa[:, -1]}, title="dynamic scaling r(t)",
                              ylabel="r [1] (dimensionless)")],
                 cols=2, cell=(5, 4))
    plots.panels(out / "fig5_stiffness.png", sweep[0],
                 [plots.Panel({"": sweep[1]}, ylabel="||[xi'; s_y'; s_x'; r']||", log="xy", legend=False)],
                 title="Fig. 5: RHS norm at the Table-I state", cell=(6, 4), xlabel="r [1] (dimensionless)")


def seed003(reference, out):
    """Registry entry (python -m codegen simulate seed003): ``run_seed003`` with ``reference`` and
    ``out``; returns its summary."""
    summary, _ = run_seed003(reference=reference, out=out)
    return summary


def seed003_ur5(reference=False, out=None, T=2.0, dt=1e-3, substeps=4, N=8):
    """The I&I speed observer on ur5 in a simulated motion (issue: 6-DoF on-line).

    Plant: ur5 under gravity compensation plus PD tracking of q_d = q_c + 0.3 sin(w t + phi)
    (w = 2..2.5 rad/s), integrated by compiled RK4 (4 sub-steps of the 1 kHz sample). Observer:
    ii_speed with N = 8 Gauss-Legendre nodes, wrap off (the motion stays within +-pi of the
    range centre, so no interval reduction is needed), first-order hold, 4 RK4 sub-steps per
    1 ms sample: its fastest mode k1/lambda_min(M) is a few thousand 1/s on this arm.
    Compiled at -O1 (a ~100k-instruction kernel: -O3 takes >8 min on this machine).
    Initial estimate zero (xhat(0) = s_x(0) = 0, s_y(0) = y(0)) while the arm moves.
    r(0) = 2 c_r (the theory needs r(0) > c_r) [ASSUMPTION]: psi1, psi2 (53)-(54) grow like
    r^2 k_M^2 / (k1 k_m) ||Deltabar||^2, and with ur5's k_m = 0.016, k_M = 4.7 the seed's
    r(0) = 0.1 puts the linearisation's eigenvalues at about -5e5 1/s (explicit RK4 would need
    sub-steps below 5 us); at 2 c_r they are ~2500x smaller.

    Parameters
    ----------
    reference : bool
        Observer by the numpy reference instead of the compiled C.
    out : path-like, optional
        Folder for run.csv and errors.png; None: nothing written.
    T : float
        Horizon, s.
    dt : float
        Sample time of plant, law and observer, s.
    substeps : int
        RK4 sub-steps per sample (plant and observer).
    N : int
        Gauss-Legendre nodes of beta.

    Returns
    -------
    dict
        Errors of xhat and s_x at a few times, r_max, sizes and timings.
    """
    from models import load_robot

    from ...families.observers import build
    robot = load_robot("ur5")
    n = robot.n
    t0 = time.perf_counter()
    spec = build("ii_speed", robot, N=N, wrap=False, r0=2e-3)
    t_gen = time.perf_counter() - t0
    t0 = time.perf_counter()
    obs = block(spec, Discretization(dt=dt, method="rk4", hold="foh", substeps=substeps), reference=reference)
    t_cc = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    centre = 0.5 * (robot.q_lower + robot.q_upper)
    phi, w = rng.uniform(0, 2 * np.pi, n), 2.0 + 0.1 * np.arange(n)
    g = robot.g
    Kp, Kd = 50.0 * np.ones(n), 10.0 * np.ones(n)

    def law(t, y, est, x):
        qd_ref = centre + 0.3 * np.sin(w * t + phi)
        vd_ref = 0.3 * w * np.cos(w * t + phi)
        return np.asarray(g(x[:n])).ravel() + Kp * (qd_ref - x[:n]) + Kd * (vd_ref - x[n:])

    q0 = centre + 0.3 * np.sin(phi)
    t0 = time.perf_counter()
    res = simulate(Plant(robot, dt, substeps=4), q0, 0.3 * w * np.cos(phi), T, dt, law,
                   {"ii": obs}, log_states=("ii",))
    wall = time.perf_counter() - t0
    err = res.est["ii"][:, n:] - res.qd                     # xhat - x
    sx = res.est["ii"][:, :n] - res.qd                      # s_x - x
    at = lambda a, tt: float(np.linalg.norm(a[min(int(round(tt / dt)), len(a) - 1)]))  # noqa: E731
    summary = {"xhat_err": {f"{tt:g}s": at(err, tt) for tt in (0.0, 0.1, 0.5, 1.0, T)},
               "s_x_err": {f"{tt:g}s": at(sx, tt) for tt in (0.0, 0.1, 0.5, 1.0, T)},
               "r_max": float(res.states["ii"][:, -1].max()), "max_speed": float(np.abs(res.qd).max()),
               "N": N, "dt": dt, "substeps": substeps, "hold": "foh",
               "rhs_instructions": int(spec.rhs.n_instructions()),
               "generate_s": round(t_gen, 2), "compile_s": round(t_cc, 2), "loop_wall_s": round(wall, 2),
               "observer": "numpy reference" if reference else f"C ({' '.join(compiler_flags(spec))})"}
    if not reference:
        summary["lib_bytes"] = int(obs.lib_path.stat().st_size)
    if out is not None:
        out = Path(out)
        res.write_csv(out / "run.csv")
        plots.error_norms(out / "errors.png", res.t, {"xhat - x": err, "s_x - x": sx},
                          title="I&I speed observer on ur5 (N = 8)")
    return summary


SCENARIOS = {"seed003": seed003, "seed003-ur5": seed003_ur5}
DESCRIPTIONS = {"seed003": "seed 003 (Arbo et al.): I&I speed observer vs AOV on the 2R arm (Figs. 2-5)",
                "seed003-ur5": "seed 003 (Arbo et al.), beyond the paper: the I&I speed observer on ur5 (2 s)"}
