"""Seed 004: DH/elastic models, symbolic Lie tools, CG O1-O4 and Tomei against the reference,
the generated C against the reference, and a short Sim-1 run (docs/papers/seed004.md §6-§10, docs/papers/experiments.md §11.3-§11.4, §12.4)."""
import casadi as ca
import numpy as np
import pytest

from codegen.reference import reference_observer
from models.catalog import load_elastic, load_robot

TOL = 1e-9


def _rel(a, b):
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


@pytest.fixture(scope="module")
def qs():
    return np.random.default_rng(4).uniform(-np.pi, np.pi, size=(25, 3))


# ---------------------------------------------------------------- models (docs/papers/experiments.md §11.3, §11.4)
def test_2r_mass_matrix_and_gravity(qs):
    r = load_robot("seed004_2r")
    for q in qs[:, :2]:
        c2, c1, c12 = np.cos(q[1]), np.cos(q[0]), np.cos(q[0] + q[1])
        M = np.array([[1.52 + 0.32 * c2, 0.44 + 0.16 * c2], [0.44 + 0.16 * c2, 0.44]])
        assert np.abs(np.array(r.M(q)) - M).max() < 1e-13
        assert np.abs(np.asarray(r.g(q)).ravel() - [19.62 * c1 + 3.924 * c12, 3.924 * c12]).max() < 1e-12
        s = -0.16 * np.sin(q[1])
        v = np.array([0.7, -1.3])
        S = s * np.array([[v[1], v[0] + v[1]], [-v[0], 0]])
        assert np.abs(np.array(r.C(q, v)) - S).max() < 1e-13


def test_3r_mass_matrix_det_and_gravity(qs):
    r = load_robot("seed004_3r")
    for q in qs:
        _, q2, q3 = q
        M = np.array(r.M(q))
        M11 = (39 / 25 + 17 / 50 * np.cos(2 * q2) + 4 / 25 * np.cos(q3) + 4 / 25 * np.cos(2 * q2 + q3)
               + 1 / 50 * np.cos(2 * q2 + 2 * q3))
        want = np.array([[M11, 0, 0], [0, 38 / 25 + 8 / 25 * np.cos(q3), 11 / 25 + 4 / 25 * np.cos(q3)],
                         [0, 11 / 25 + 4 / 25 * np.cos(q3), 11 / 25]])
        assert np.abs(M - want).max() < 1e-13
        c23, c2 = np.cos(q2 + q3), np.cos(q2)
        detM = 6.4e-5 * (297 - 16 * np.cos(q3) ** 2) * (c23 ** 2 + 8 * c23 * c2 + 17 * c2 ** 2 + 30)
        assert abs(np.linalg.det(M) - detM) < 1e-12 * detM
        assert np.abs(np.asarray(r.g(q)).ravel() - [0, 19.62 * c2 + 3.924 * c23, 3.924 * c23]).max() < 1e-12


def test_3r_det_Q_formula(qs):
    """docs/papers/seed004.md §8.3 / report (5.7): det Q = 1.5625e34 / [(16 cos^2 q3 - 297)^2 (...)^2], for the
    symbolic Q = dPhi/dx (AD) and for the reference's hyper-dual Q."""
    from codegen.core import symbolic as sym
    e = load_elastic("seed004_3r")
    x = ca.SX.sym("x", 12)
    Phi, _ = sym.observability_map([x[i] for i in range(3)], [4] * 3, x, e.drift(x))
    Qf = ca.Function("Q", [x], [ca.jacobian(Phi, x)])
    from codegen.reference import reference_robot
    ref = reference_robot(e.source)
    for xs in e.sample_states(10, seed=3):
        q2, q3 = xs[1], xs[2]
        c23, c2 = np.cos(q2 + q3), np.cos(q2)
        want = 1.5625e34 / ((16 * np.cos(q3) ** 2 - 297) ** 2 * (c23 ** 2 + 8 * c23 * c2 + 17 * c2 ** 2 + 30) ** 2)
        assert abs(abs(np.linalg.det(np.array(Qf(xs)))) - want) < 1e-9 * want
        assert abs(abs(np.linalg.det(ref.spong_jacobian(xs)[1])) - want) < 1e-9 * want


def test_dh_reference_matches_symbolic_model():
    """Newton-Euler numpy DH reference vs the CasADi CoM-Jacobian model: M, C v + g, f(x)."""
    from codegen.reference import reference_robot
    for name in ("seed004_2r", "seed004_3r"):
        e = load_elastic(name)
        ref = reference_robot(e.source)
        for xs in e.sample_states(10, seed=1):
            q, v = xs[:e.n], xs[e.n:2 * e.n]
            assert _rel(ref.M(q), np.array(e.rigid.M(q))) < 1e-13
            nle = np.array(e.rigid.C(q, v)) @ v + np.asarray(e.rigid.g(q)).ravel()
            assert _rel(ref.rigid.nle(q, v), nle) < 1e-13
            assert _rel(ref.f(xs), np.array(e.f(xs))) < 1e-13


def test_elastic_robot_shape_and_source():
    e = load_elastic("seed004_2r")
    assert (e.n, e.nx) == (2, 8)
    assert e.source["kind"] == "elastic" and e.source["rigid"]["kind"] == "dh"
    assert np.allclose(np.diag(e.J), 37.5) and np.allclose(np.diag(e.K), 20000)
    assert np.allclose(np.diag(load_elastic("seed004_3r").J), 87.5)
    x, u = e.sample_states(1, seed=2)[0], np.array([3.0, -4.0])
    xd = np.asarray(e.xdot(x, u)).ravel()
    assert np.allclose(xd[6:], (20000 * (x[:2] - x[4:6]) + u) / 37.5)      # J q2'' = K(q1-q2) + u
    M = np.array(e.rigid.M(x[:2]))
    lhs = M @ xd[2:4] + np.array(e.rigid.C(x[:2], x[2:4])) @ x[2:4] + np.asarray(e.rigid.g(x[:2])).ravel()
    assert np.allclose(lhs + 20000 * (x[:2] - x[4:6]), 0, atol=1e-9)       # link equation


# ---------------------------------------------------------------- symbolic tools (docs/papers/seed004.md §8.1)
def test_relative_degree_and_decoupling_matrix():
    from codegen.core import symbolic as sym
    e = load_elastic("seed004_2r")
    x = ca.SX.sym("x", 8)
    f, G = e.drift(x), e.input_matrix(x)
    X = e.sample_states(5, seed=5)
    link = [x[0], x[1]]
    assert sym.check_relative_degree(link, [4, 4], x, f, G, X) > 0
    U = ca.Function("U", [x], [sym.decoupling_matrix(link, [4, 4], x, f, G)])
    for xs in X:     # U = M^{-1} K J^{-1}  (A.43)
        want = np.linalg.solve(np.array(e.rigid.M(xs[:2])), e.K) @ np.linalg.inv(e.J)
        assert _rel(np.array(U(xs)), want) < 1e-12
    with pytest.raises(ValueError, match="relative degree"):   # O4: q2 has relative degree 2
        sym.check_relative_degree([x[4], x[5]], [4, 4], x, f, G, X)
    assert sym.check_relative_degree([x[4], x[5]], [2, 2], x, f, G, X) > 0


def test_gains_from_eigenvalues():
    from codegen.families.design import ciccarella_germani_gains, spong_fl_gains, tomei_K1
    k = ciccarella_germani_gains("O1", 2, -100.0 * np.arange(3, 11))
    assert np.allclose(k, [1800, 1.19e6, 3.42e8, 3.6e10, 3400, 4.31e6, 2.414e9, 5.04e11], rtol=1e-12)
    k2 = ciccarella_germani_gains("O2", 1, [-300, -400, -500, -600])
    assert np.allclose(k2, [300, 1500, 7.4e5, 1.2e8])
    Kc = spong_fl_gains(2, -5.0 * np.arange(1, 9))
    assert np.allclose(Kc, [-15000, -6250, -875, -50, -1.05e6, -1.3325e5, -6275, -130])
    assert np.allclose(tomei_K1(2000 * np.eye(2), 2000 * np.eye(2)), 0.5 * np.eye(2))


def test_o2_error_dynamics_have_assigned_eigenvalues():
    """Per joint, A - K C with C = [e1; e2] (position, velocity) has the 4 assigned eigenvalues."""
    from codegen.families.design import ciccarella_germani_gains
    p = np.array([-300.0, -400, -500, -600])
    k = ciccarella_germani_gains("O2", 1, p)
    A = np.diag(np.ones(3), 1)
    KC = np.zeros((4, 4))
    KC[0, 0] = k[0]
    KC[1:, 1] = k[1:]
    assert np.allclose(np.sort(np.linalg.eigvals(A - KC).real), np.sort(p))


# ---------------------------------------------------------------- observers vs reference
# The numpy reference of O1/O2 builds Q(x) column by column with hyper-dual Newton-Euler
# (~0.08 s per rhs on the 2R, ~0.2 s on the 3R), so those cases use fewer random states and a
# shorter run; the tolerance is the same everywhere.
KINDS = ("O1", "O2", "O3", "O4", "tomei")
CASES = [(r, k) for r in ("seed004_2r", "seed004_3r") for k in KINDS]
DT_C = 1e-5
_BLOCKS = {}


def _heavy(robot, kind):
    return kind in ("O1", "O2")


def _block(robot, kind):
    """(robot, spec, C observer, reference) per case, compiled once for the module: explicit
    Euler at dt = 1e-5 (small kernels; the step is x + dt rhs), the 3R ones calling the rhs
    routine instead of inlining it (quick to compile)."""
    if (robot, kind) not in _BLOCKS:
        from codegen import compile_observer
        from codegen.families.observers import ciccarella_germani, tomei
        e = load_elastic(robot)
        spec = tomei.build(e) if kind == "tomei" else ciccarella_germani.build(e, kind)
        obs = compile_observer(spec, dt=DT_C, method="euler", inline=e.n < 3)
        _BLOCKS[robot, kind] = e, spec, obs, reference_observer(spec, dt=DT_C, method="euler")
    return _BLOCKS[robot, kind]


def _random_case(spec, rng, xs):
    n = spec.robot.n
    x = np.r_[xs, rng.normal(size=spec.nx - xs.size)] if spec.nx > xs.size else xs
    y = rng.normal(size=spec.ny)
    return x, y, 50 * rng.normal(size=n)


@pytest.mark.slow
@pytest.mark.parametrize("robot,kind", CASES)
def test_observer_rhs_against_reference(robot, kind):
    """Symbolic spec rhs and emitted C rhs against the numpy reference at random states,
    measurements and inputs (relative 1e-9)."""
    e, spec, obs, ref = _block(robot, kind)
    if kind in ("O1", "O2"):
        assert spec.design["structured_solve"]
    rng = np.random.default_rng(7)
    p0 = spec.p_default.copy()
    states = e.sample_states(3 if e.n == 3 and _heavy(robot, kind) else 6 if _heavy(robot, kind) else 10, seed=11)
    for xs in states:
        x, y, u = _random_case(spec, rng, xs)
        want = ref.rhs(x, y, u)
        got = np.asarray(spec.rhs(x, y, u, spec.p_default)).ravel()
        assert _rel(got, want) < TOL
        assert _rel(obs.rhs(x, y, u), want) < TOL
        if kind != "tomei":      # the correction term matters (not a test of f alone)
            p0[:-1] = 0
            assert _rel(np.asarray(spec.rhs(x, y, u, p0)).ravel(), got) > 1e-3


@pytest.mark.parametrize("robot,kind", CASES)
def test_emitted_c_step_and_run_against_reference(robot, kind):
    """Generated C step (explicit Euler, dt = 1e-5) against the numpy reference: one step from
    random states, and a run along a smooth measurement (relative 1e-9)."""
    e, spec, obs, ref = _block(robot, kind)
    heavy = _heavy(robot, kind)
    rng = np.random.default_rng(3)
    for xs in e.sample_states(1 if heavy else 5, seed=2):
        x, y, u = _random_case(spec, rng, xs)
        obs.reset(y)
        obs.state = x
        ref.reset(y)
        ref.state = x
        assert _rel(obs.step(y, u), ref.step(y, u)) < TOL
        assert _rel(obs.state, ref.state) < TOL
    # a run along a smooth measurement near a state
    x0 = e.sample_states(1, seed=9)[0]
    N = (8 if e.n == 3 else 20) if heavy else 200
    t = np.arange(N)[:, None] * DT_C
    from codegen.evaluate.scenarios.seed004 import measurement
    y0 = measurement(spec, x0[None, :4 * e.n])[0]          # consistent with the state
    Y = y0 + 0.01 * np.sin(5000 * t + np.arange(spec.ny))
    U = 20 * np.cos(3000 * t + np.arange(e.n))
    est0 = x0[:4 * e.n]
    obs.reset(Y[0], est0)
    ref.reset(Y[0], est0)
    assert _rel(obs.run(Y, U), ref.run(Y, U)) < TOL
    assert _rel(obs.state, ref.state) < TOL


def test_ill_conditioned_pivot_gives_nonfinite_status():
    """rcond_min above 1 makes every pivot 'ill-conditioned': the C step reports a non-finite
    result and the state stays unchanged."""
    from codegen.pipeline.load import ObserverError
    e, spec, obs, _ = _block("seed004_2r", "O1")
    x = e.sample_states(1, seed=4)[0]
    p = spec.p_default.copy()
    p[-1] = 2.0
    with pytest.raises(ValueError, match="not finite"):   # the check refuses it (issue 22 F2)
        obs.reset(x[:2], x, p)
    obs.reset(x[:2], x)
    obs.c_set_params(p)                  # the C alone
    before = obs.state
    with pytest.raises(ObserverError, match="(?i)finite"):
        obs.step(x[:2] + 0.01, np.zeros(2))
    assert np.array_equal(obs.state, before)
    obs.params = spec.p_default
    for _ in range(2):                   # the first-order hold integrates from the second sample on
        obs.step(x[:2] + 0.01, np.zeros(2))
    assert np.all(np.isfinite(obs.state)) and not np.array_equal(obs.state, before)


# ---------------------------------------------------------------- Sim 1, short horizon
@pytest.mark.slow
def test_sim1_o1_converges_within_50ms():
    """Sim 1 (2R, CG O1 with -100{3..10}, true-state FL): ||x - xhat|| < 2 % of its initial
    value from t = 0.05 s on (0.1 s horizon); Tomei has not converged by then."""
    from codegen.evaluate.scenarios import seed004 as s
    robot = load_elastic("seed004_2r")
    t, X, U = s.closed_loop(robot, s.controller(robot, "fl"), s.SIM1_X0, [np.pi / 2, 0], T=0.1)
    spec, obs = s.observer(robot, "O1", -100.0 * np.arange(3, 11))
    E = X - s.run_observer(spec, obs, X, U, s.SIM1_XHAT0)
    tc = s.convergence_time(t, E)
    assert 0.02 < tc < 0.05
    spec, obs = s.observer(robot, "tomei")
    assert s.convergence_time(t, X - s.run_observer(spec, obs, X, U, s.SIM1_XHAT0)) == np.inf


# ---------------------------------------------------------------- figures
def test_sim1_figures_one_per_paper_figure(tmp_path):
    """Sim 1 writes Figs. 2-4 as PNG + CSV named after the paper's figures; Fig. 4's CSV holds
    the per-component errors x - xhat of run.csv's O1 estimate, over the paper's span."""
    import csv

    from codegen.evaluate.scenarios import seed004 as s
    summary = s.sim1(out=tmp_path, T=0.05, dt_check=False)
    figs = summary["figures"]
    assert sorted(figs) == ["fig02", "fig03", "fig04"]
    assert figs["fig04"]["png"].endswith("fig04_sim1_o1_errors.png")
    for f in figs.values():
        assert (tmp_path / f["png"]).stat().st_size > 0
    read = lambda p: {k: np.array([float(r[k]) for r in rows]) for rows in [list(csv.DictReader(open(p)))]  # noqa: E731
                      for k in rows[0]}
    fig4, run = read(figs["fig04"]["csv"]), read(summary["csv"])
    assert fig4["t"][-1] == pytest.approx(s.FIG_SPAN[4], abs=1e-9)
    assert [k for k in fig4 if k != "t"] == [f"e_{b}{i}" for b in s.STATE_BLOCKS for i in range(2)]
    rows = np.searchsorted(fig4["t"], run["t"][run["t"] <= s.FIG_SPAN[4]] - 1e-12)
    for j, (b, i) in enumerate((b, i) for b in s.STATE_BLOCKS for i in range(2)):
        true, est = run[f"{b}{i}"], run[f"O1_est{j}"]
        assert np.allclose(fig4[f"e_{b}{i}"][rows], (true - est)[:len(rows)], rtol=0, atol=1e-12)


@pytest.mark.slow
def test_3r_manifold_uses_spec_fast_poles():
    """docs/papers/seed004.md §10: the 3R integral-manifold controller the scenarios compile places the fast poles
    at the authors' 70 [-1, -1.2, ..., -1.6] (its compiled gains are those of these poles)."""
    from codegen.families.controllers.spong import spong_fast_gains
    from codegen.evaluate.scenarios import seed004 as s
    robot = load_elastic("seed004_3r")
    ctrl = s.controller(robot, "manifold")
    poles = 70.0 * np.array([-1, -1.2, -1.3, -1.4, -1.5, -1.6])
    kf = spong_fast_gains(3, poles, np.diag(robot.K))
    assert np.allclose(ctrl.params[6:12], kf, rtol=1e-12)
    assert not np.allclose(kf, spong_fast_gains(3, -70.0 * (1 + 0.1 * np.arange(1, 7)), np.diag(robot.K)))
