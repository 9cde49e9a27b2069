"""Seed 003 (Arbo, Grotli & Gravdahl): the I&I speed observer on the two-link arm (SPEC §12.3),
compared with the reconstructed Astolfi-Ortega-Venkatraman observer (SPEC §5); plus the
quadrature study (docs/quadrature.md) and the ur5 benchmark.

Scenario ``seed003``: plant at y(0) = [0, 0], x(0) = [-0.29, 6.66] (Table I), u = 0 [ASSUMPTION
A3-4], horizon 2 s. I&I observer (k1, k2, k3, c_r) = (40, 8, 2.5, 0.001) with state
xi(0) = [-8.45, 68.33], s_y(0) = [1, 2], s_x(0) = [10, 20], r(0) = 0.1 (Table I), set through
``obs.state`` since s_y(0) != y(0). AOV observer: k1 = 10, k2 = 8, k3 = 2.5, c_r = 1, r(0) = 1 and
the same filter states taken literally (qhat(0) = s_y(0), phat(0) = s_x(0), xi(0) = Table I)
[ASSUMPTION, SPEC §5 item 5].

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

from ...target import Discretization

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

    from ...observers import build
    from ...observers._ii_common import DEFAULT_N
    robot = load_robot("seed003_2r_abs")
    N = N or DEFAULT_N
    q = dict(N=N, wrap=wrap, N_period=N_period)
    return (build("ii_speed", robot, k1=40.0, k2=8.0, k3=2.5, c_r=1e-3, r0=R0, **q),
            build("ii_aov", robot, k1=10.0, k2=8.0, k3=2.5, c_r=1.0, r0=1.0, **q))


def _observer(spec, reference, dt):
    if reference:
        from ...reference import reference_observer
        return reference_observer(spec, dt=dt, method="rk4", hold=HOLD)
    from ... import compile_observer
    return compile_observer(spec, dt=dt, method="rk4", hold=HOLD)


def run_seed003(reference=False, out=None, T=HORIZON, dt=DT, plots=True, N=None, wrap="auto",
                N_period=None):
    """Closed loop of SPEC §12.3 with both observers; returns (summary, traces dict)."""
    from ..plant import Plant
    sp_ii, sp_aov = specs(N, wrap, N_period)
    robot = sp_ii.robot
    n = robot.n
    plant = Plant(robot, dt, substeps=10)
    obs = {"ii": _observer(sp_ii, reference, dt), "aov": _observer(sp_aov, reference, dt)}
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
    summary.update({"dt": dt, "T": T, "method": "rk4", "hold": HOLD, "plant_substeps": 10, "N_quadrature": sp_ii.options.N,
                    "N_period": sp_ii.options.N_period, "wrap": list(sp_ii.options.periodic),
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
            plot(tr, sweep, out, n)
    return summary, tr


def summarize(tr, n):
    """Convergence figures of both observers (SPEC §12.3 'Expected')."""
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
    """Fig. 5: ||[xi'; s_y'; s_x'; r']|| at the Table-I state for r on a log grid 1e-3..1e2."""
    r_grid = np.logspace(-3, 2, 51) if r_grid is None else np.asarray(r_grid)
    vals = [np.linalg.norm(obs.rhs(np.concatenate([XI0, SY0, SX0, [r]]), Y0, np.zeros(2))) for r in r_grid]
    return r_grid, np.array(vals)


def plot(tr, sweep, out, n):
    """Figs. 2-5 of the seed (PNG, matplotlib Agg)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t, X = tr["t"], tr["x"]
    Si, Sa = tr["states"]["ii"], tr["states"]["aov"]
    Ei, Ea = tr["est"]["ii"], tr["est"]["aov"]
    w = t <= 0.2
    fig, ax = plt.subplots(n, 1, figsize=(6, 5), sharex=True)
    for i in range(n):
        ax[i].plot(t[w], X[w, i], "b-", label="y")
        ax[i].plot(t[w], Si[w, n + i], "g--", label="s_y (I&I, seed 003)")
        ax[i].plot(t[w], Sa[w, n + i], "r:", label="qhat (AOV)")
        ax[i].set_ylabel(f"y{i + 1} [rad]")
    ax[0].legend(fontsize=8)
    ax[-1].set_xlabel("t [s]")
    fig.suptitle("Fig. 2: joint angles")
    fig.savefig(out / "fig2_angles.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(n, 1, figsize=(6, 5), sharex=True)
    for i in range(n):
        ax[i].plot(t, X[:, n + i], "b-", label="x")
        ax[i].plot(t, Ei[:, i], "g--", label="s_x (I&I)")
        ax[i].plot(t, Ea[:, i], "r:", label="T phat (AOV)")
        ax[i].set_ylabel(f"x{i + 1} [rad/s]")
    ax[0].legend(fontsize=8)
    ax[-1].set_xlabel("t [s]")
    fig.suptitle("Fig. 3: joint speeds")
    fig.savefig(out / "fig3_speeds.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].semilogy(t, np.sum((Ei[:, :n] - X[:, n:]) ** 2, axis=1), "g", label="I&I ||s_x - x||^2")
    ax[0].semilogy(t, np.sum((Ea[:, :n] - X[:, n:]) ** 2, axis=1), "r", label="AOV")
    ax[0].set_xlabel("t [s]")
    ax[0].legend()
    ax[0].set_title("Fig. 4: ||s_x - x||^2")
    ax[1].plot(t, Si[:, -1], "g", label="r (I&I)")
    ax[1].plot(t, Sa[:, -1], "r", label="r (AOV)")
    ax[1].set_xlabel("t [s]")
    ax[1].legend()
    ax[1].set_title("dynamic scaling r(t)")
    fig.tight_layout()
    fig.savefig(out / "fig4_error_and_r.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(*sweep, "k.-")
    ax.set_xlabel("r")
    ax.set_ylabel("||[xi'; s_y'; s_x'; r']||")
    ax.set_title("Fig. 5: RHS norm at the Table-I state")
    fig.tight_layout()
    fig.savefig(out / "fig5_stiffness.png", dpi=110)
    plt.close(fig)


def seed003(reference, out):
    """Registry entry (python -m codegen simulate seed003)."""
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
    sub-steps below 5 us); at 2 c_r they are ~2500x smaller."""
    from models import load_robot

    from ... import compile_observer
    from ...observers import build
    from ...reference import reference_observer
    from ..engine import simulate
    from ..plant import Plant
    from .. import plots
    robot = load_robot("ur5")
    n = robot.n
    t0 = time.perf_counter()
    spec = build("ii_speed", robot, N=N, wrap=False, r0=2e-3)
    t_gen = time.perf_counter() - t0
    t0 = time.perf_counter()
    obs = (reference_observer(spec, dt=dt, substeps=substeps, hold="foh") if reference else
           compile_observer(spec, dt=dt, substeps=substeps, hold="foh", cflags=("-O1",)))
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
               "observer": "numpy reference" if reference else "C (-O1)"}
    if not reference:
        summary["lib_bytes"] = int(obs.lib_path.stat().st_size)
    if out is not None:
        out = Path(out)
        res.write_csv(out / "run.csv")
        plots.error_norms(out / "errors.png", res.t, {"xhat - x": err, "s_x - x": sx},
                          title="I&I speed observer on ur5 (N = 8)")
    return summary


SCENARIOS = {"seed003": seed003, "seed003-ur5": seed003_ur5}


# ============================================================================ quadrature study
QUADRATURE_NOTES = """## Why the reduction, and the defaults (N = 16, N_period = N)

The integrands are analytic in sigma and 2 pi-periodic for revolute joints, with complex
singularities where det M vanishes (seed-003 arm: phi = y1 - y2 at +-0.94 i, the strip half-width
d). Gauss-Legendre on [0, y_i] converges at a rate set by |y_i|: once a link has gone round
(seed-003 scenario: y2 = 9.3 rad at t = 2 s) N = 16 leaves ~5e-3 relative error in beta and its
AD derivatives dbeta/ds_y, dbeta/ds_x, while dbeta/dy is exact (fundamental theorem of
calculus); the mismatch enters the z dynamics times the velocity and the observer drifted
(||xhat - x|| = 0.65 at 2 s). With the reduction the Gauss-Legendre part has |rho| <= pi and the
whole periods use the periodic trapezoidal rule, which converges like exp(-N d) (one full period,
worst of 3 random (s_y, s_x), relative, stacked beta / dbeta/ds_y / dbeta/ds_x integrands):

| N | 2R trapezoid | 2R Gauss-Legendre | ur5 trapezoid | ur5 Gauss-Legendre |
|---:|---:|---:|---:|---:|
| 8 | 8.0e-03 | 7.4e-02 | 2.0e-02 | 4.1e-02 |
| 16 | 8.3e-06 | 1.2e-03 | 4.8e-04 | 2.4e-03 |
| 24 | 6.7e-09 | 1.5e-05 | 1.2e-05 | 2.5e-04 |
| 32 | 4.5e-12 | 1.9e-07 | 2.8e-07 | 2.0e-05 |

Defaults: N = 16 Gauss-Legendre nodes on [0, rho] and N_period = N trapezoid nodes per period
(`codegen.observers._ii_common.DEFAULT_N`, `ii_speed.build(..., wrap="auto", N_period=None)`).
In the seed-003 scenario N_period = 32 and 16 give ||xhat - x|| = 1.97e-6 at t = 2 s either way
(xhat agrees to 5e-11 from t = 1 s on; the largest difference, 6.6e-4, is at t = 0.61 s during
the transient, just after y2 passes pi): the residual is the time discretisation, not the
quadrature, so the cheaper N_period = N is the default; pass N_period = 2 N for ~1e-11 on the
2R arm. The reduction doubles the quadrature points of a periodic column (N + N_period instead
of N); a column whose integrand does not depend on sigma (column 1 of a serial arm: M and C do
not depend on q_1) is y_i H_i exactly, with no nodes at all. The 6-DoF ur5 has nearer
singularities (slower convergence, ~1e-3 at N = 8 for |rho| <= pi); N = 8 there is a
documented cost/accuracy trade (see the benchmark in `bench()`), not an accuracy claim.
`wrap=False` restores the plain [0, y_i] quadrature (fine while every |y_i| stays below ~pi).

## Known gap in the seed's proof (S003 (37))

(37) bounds the term -(r'/r) eta^T M eta of d/dt(1/2 eta^T M eta), eta = z / r, by
-(r'/r) k_m ||eta||^2. That holds only while r' >= 0; when r decays (r' < 0, the term is
positive) the valid bound is -(r'/r) k_M ||eta||^2, and the decrease of the eta part of the
Lyapunov function is not guaranteed by the printed argument. Observed in our runs: in the
seed-003 scenario r falls from 0.1 to c_r = 1e-3 within ~50 ms (r' < 0 on 78 % of the 2 s) and
1/2 eta^T M eta grows from 4.9e3 (t = 5 ms) to 5.2e5 (t = 45 ms) while ||z|| = ||xhat - x||
keeps decreasing (9.5 -> 1.4); afterwards r sits at c_r and everything converges. So the gap
is real in the proof (eta is not monotone) but has not shown up as a loss of convergence of z.
"""


def quadrature_study(robots=("seed003_2r_abs", "ur5"), Ns=range(2, 17), samples=4, seed=0,
                     write=None, y_range=3 * np.pi):
    """beta, dbeta/ds_y, dbeta/ds_x (reference formulas, N nodes, interval reduction of the
    periodic joints: N-node Gauss-Legendre on [0, rho], |rho| <= pi, plus m periods by the
    N-node trapezoid) against an adaptive reference (scipy.integrate.quad_vec, epsabs 1e-14,
    epsrel 1e-13) of the same integrands on the whole [0, y_i] (so the reduction itself is
    checked). y ~ U(-y_range, y_range)^n (up to 1.5 turns: m in {-1, 0, 1}). Returns
    {robot: {N: (err_beta, err_dsy, err_dsx, err_beta_nowrap)}}: worst relative errors over
    ``samples`` random (y, s_y, s_x), the last one without reduction (N-node Gauss-Legendre on
    [0, y_i]); with ``write`` a path, writes the markdown table there."""
    from scipy.integrate import quad_vec

    from models import load_robot

    from ...reference import reference_robot
    from ...reference import ii_speed as ref
    rng = np.random.default_rng(seed)
    k1 = 40.0
    table = {}
    for name in robots:
        robot = reference_robot(load_robot(name).source)
        n = robot.n
        periodic = list(np.asarray(robot.periodic, dtype=bool))
        rows = {N: [0.0, 0.0, 0.0, 0.0] for N in Ns}
        for _ in range(samples):
            y = rng.uniform(-y_range, y_range, n)
            s_y = np.mod(y + rng.normal(scale=0.5, size=n) + np.pi, 2 * np.pi) - np.pi
            s_x = rng.normal(scale=2.0, size=n)

            def integrand(sig, i):
                z = s_y.copy()
                z[i] = sig
                Hi, dq, dx = ref.h_column_derivatives(robot, z, s_x, k1, i)
                dq[:, i] = 0.0
                return np.concatenate([Hi, dq.ravel(), dx.ravel()])

            exact = sum(quad_vec(lambda s, i=i: integrand(s, i), 0.0, y[i], epsabs=1e-14,
                                 epsrel=1e-13, limit=1000)[0] for i in range(n))
            eb, esy, esx = exact[:n], exact[n:n + n * n].reshape(n, n), exact[n + n * n:].reshape(n, n)
            for N in Ns:
                b, _, dsy, dsx = ref.beta_and_derivatives(robot, y, s_y, s_x, k1, N, True, periodic)
                b0, *_ = ref.beta_and_derivatives(robot, y, s_y, s_x, k1, N, False)
                for k, (a, e) in enumerate(((b, eb), (dsy, esy), (dsx, esx), (b0, eb))):
                    rows[N][k] = max(rows[N][k], float(np.linalg.norm(a - e) / np.linalg.norm(e)))
        table[name] = rows
    if write is not None:
        write_quadrature_doc(table, write, samples, y_range)
    return table


def write_quadrature_doc(table, path, samples, y_range=3 * np.pi):
    lines = ["# Quadrature order of the I&I speed observers (seed 003)", "",
             "beta (12) and its derivatives (14), (15) are quadratures of the columns of H. For a "
             "2 pi-periodic (revolute) joint the interval is reduced (`wrap`, default \"auto\"): "
             "y_i = 2 pi m + rho, m = floor(y_i / 2 pi + 1/2), |rho| <= pi, and "
             "int_0^{y_i} = m int_{-pi}^{pi} + int_0^{rho}, the period by the N_period-node "
             "trapezoidal rule (default N_period = N), [0, rho] by N-node Gauss-Legendre. The "
             "table gives the worst relative error (2-norm, Frobenius for matrices) over "
             f"{samples} random y ~ U(-{y_range / np.pi:g} pi, {y_range / np.pi:g} pi)^n "
             "(up to 1.5 turns), s_y = y + N(0, 0.5^2) wrapped to [-pi, pi), s_x ~ N(0, 2^2), "
             "k1 = 40, against scipy.integrate.quad_vec (adaptive, epsabs 1e-14, epsrel 1e-13) "
             "of the same exact integrands on the whole [0, y_i] (so the reduction itself is "
             "checked); the last column is N-node Gauss-Legendre on [0, y_i] without the "
             "reduction. Generated by "
             "`codegen.sim.scenarios.seed003.quadrature_study(write='docs/quadrature.md')`.", ""]
    for name, rows in table.items():
        lines += [f"## {name}", "", "| N | beta | dbeta/ds_y | dbeta/ds_x | beta, no reduction |",
                  "|---:|---:|---:|---:|---:|"]
        for N, (a, b, c, d) in rows.items():
            lines.append(f"| {N} | {a:.2e} | {b:.2e} | {c:.2e} | {d:.2e} |")
        lines.append("")
    lines += [QUADRATURE_NOTES]
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text("\n".join(lines))
    return path


# ============================================================================ benchmark
def bench(robot="ur5", N=8, native=False, blocks=51, wrap=False, opt="-O1"):
    """ur5 I&I RHS in C (codegen.harness.time_target) vs the numpy/pin reference (timeit).
    Returns a dict with generation, emit, compile times, C size and ns per RHS / step;
    ``wrap`` is the interval reduction of the quadrature (ii_speed.build; off as in the
    seed003-ur5 scenario), ``opt`` the optimisation level for this ~100k-instruction kernel
    (-O3 takes more than 8 minutes to compile it on this machine, -O1 about one)."""
    import timeit

    from models import load_robot

    from ...build import build, repo_root
    from ...emit import emit
    from ...harness import time_target
    from ...observers import build as build_observer
    from ...reference import reference_observer
    from ...reference import ii_speed as ref_ii
    rb = load_robot(robot)
    t0 = time.perf_counter()
    spec = build_observer("ii_speed", rb, N=N, wrap=wrap)
    t_gen = time.perf_counter() - t0
    t0 = time.perf_counter()
    disc = Discretization(dt=1e-3, method="rk4", substeps=1, hold="zoh")
    target = emit(spec.target(disc), repo_root() / "build" / "bench", spec=spec)
    t_emit = time.perf_counter() - t0
    t0 = time.perf_counter()
    build(target, native=native, extra_flags=[opt])
    t_cc = time.perf_counter() - t0
    c_bytes = sum(f.stat().st_size for f in target.glob("*.c"))
    ours = time_target(target, blocks=blocks, extra_flags=[opt])
    ref = reference_observer(spec, disc)
    rng = np.random.default_rng(0)
    y = rb.sample_configurations(1, 1)[0]
    x = np.concatenate([rng.normal(size=rb.n), y + 0.1, rng.normal(size=rb.n), [0.1]])
    u = np.zeros(rb.n)
    reps = 20
    t_ref = min(timeit.repeat(lambda: ref.rhs(x, y, u), number=reps, repeat=3)) / reps
    return {"robot": robot, "N": N, "wrap": list(spec.options.periodic), "opt": opt, "rhs_instructions": int(spec.rhs.n_instructions()),
            "generate_s": round(t_gen, 2), "emit_s": round(t_emit, 2), "compile_s": round(t_cc, 2),
            "c_bytes": int(c_bytes), "ns_per_rhs": ours["ns_per_rhs"], "ns_per_rk4_step": ours["ns_per_step"],
            "ns_per_rhs_reference": t_ref * 1e9, "speedup": t_ref * 1e9 / ours["ns_per_rhs"],
            "gate_1ms": ours["ns_per_rhs"] <= 1e6}
