"""Seed 003: I&I speed observer (docs/papers/seed003.md §4) and the reconstructed AOV observer (docs/papers/seed003.md §5)."""
from functools import lru_cache

import casadi as ca
import numpy as np
import pytest

from codegen import compile_observer
from codegen.families import observers
from codegen.families.design import ii_speed_bounds
from codegen.reference import reference_observer
from codegen.reference.families import ii_speed as ref_ii
from codegen.verify import relative_error
from models import load_robot

TOL = 1e-9
QUAD_TOL = 5e-4       # reduced quadrature at the default N, |y| <= 3 pi (docs/quadrature.md)
RNG = np.random.default_rng(3)


def _reference(spec, dt, hold="zoh"):
    ref = reference_observer(spec, dt=dt, method="rk4", hold=hold)
    assert ref.family.N == spec.options.N      # the quadrature order reaches the reference
    assert ref.family.periodic == list(spec.options.periodic)    # and the same interval reduction
    assert ref.family.N_period == spec.options.N_period
    return ref


def _random_state(robot, y, scale=1.0, r=(0.05, 0.5)):
    n = robot.n
    return np.concatenate([RNG.normal(size=n) * 5 * scale, y + 0.3 * RNG.normal(size=n),
                           RNG.normal(size=n) * 3 * scale, [RNG.uniform(*r)]])


def test_cholesky_velocity_and_skew_S():
    """docs/papers/seed003.md §5: M^{-1} = T T^T (T lower), T^{-1} = T^T M, and S(q, b) skew-symmetric
    (symbolic helpers shared by the AOV observer and its bounds)."""
    from codegen.core.symbolic import cholesky_velocity, skew_S
    robot = load_robot("seed003_2r_abs")
    q, b = ca.SX.sym("q", 2), ca.SX.sym("b", 2)
    f = ca.Function("f", [q, b], [*cholesky_velocity(robot, q), skew_S(robot, q, b)])
    for _ in range(5):
        M, T, Tinv, S = (np.array(v) for v in f(RNG.uniform(-np.pi, np.pi, 2), RNG.normal(size=2)))
        assert T[0, 1] == 0.0 and np.all(np.diag(T) > 0)
        assert np.allclose(T @ T.T @ M, np.eye(2), atol=1e-12)
        assert np.allclose(Tinv @ T, np.eye(2), atol=1e-12)
        assert np.abs(S + S.T).max() <= 1e-12 * max(np.abs(S).max(), 1.0)
        assert np.abs(S).max() > 1e-6                  # not trivially zero


def test_eq59_is_transposed_christoffel_symbolic():
    """docs/papers/seed003.md §4.2 / A3-1: (59) = M^{-1}(k1 I - C^T) with the models' Christoffel C (CasADi side)."""
    robot = load_robot("seed003_2r_abs")
    c1, c2, c3 = 0.9698, 0.1575, 0.264
    y, x, k1 = ca.SX.sym("y", 2), ca.SX.sym("x", 2), ca.SX.sym("k1")
    H = ca.Function("H", [y, x, k1], [ca.solve(robot.mass_matrix(y), k1 * ca.DM.eye(2) - robot.coriolis(y, x).T)])
    Hc = ca.Function("Hc", [y, x, k1], [ca.solve(robot.mass_matrix(y), k1 * ca.DM.eye(2) - robot.coriolis(y, x))])
    for _ in range(20):
        yv, xv, kv = RNG.uniform(-np.pi, np.pi, 2), RNG.uniform(-10, 10, 2), RNG.uniform(5, 50)
        phi = yv[0] - yv[1]
        s, c = np.sin(phi), np.cos(phi)
        D = c1 * c2 - c3 ** 2 * c ** 2
        H59 = np.array([[c2 * kv + c3 ** 2 * xv[1] * s * c, c3 * (c2 * xv[0] * s - kv * c)],
                        [-c3 * (c1 * xv[1] * s + kv * c), c1 * kv - c3 ** 2 * xv[0] * s * c]]) / D
        np.testing.assert_allclose(np.array(H(yv, xv, kv)), H59, rtol=1e-12, atol=1e-12)
        if abs(s) > 0.1 and np.linalg.norm(xv) > 1:      # the Christoffel H really differs from (59)
            assert np.abs(np.array(Hc(yv, xv, kv)) - H59).max() > 1e-3


def test_design_reproduces_seed_constants():
    """k_m, k_M, k_c of docs/papers/seed003.md §4.2 / [S003 (58)] and Deltabar_x = k_c/k_m (Lemma 1)."""
    d = ii_speed_bounds(load_robot("seed003_2r_abs"))
    assert abs(d.k_m - 0.079239) < 5e-7
    assert abs(d.k_M - 1.048061) < 5e-7
    assert abs(d.k_c - 0.264) < 1e-9
    assert d.deltabar_x == pytest.approx(d.k_c / d.k_m, rel=1e-12)


def test_lemma2_coefficients_match_closed_form():
    """a_ji = sup_phi |dH0_ij/dphi| (docs/papers/seed003.md §4.2 closed form of H0) to 1e-6 relative."""
    d = ii_speed_bounds(load_robot("seed003_2r_abs"))
    c1, c2, c3 = 0.9698, 0.1575, 0.264
    phi = np.linspace(-np.pi, np.pi, 400001)
    c, s = np.cos(phi), np.sin(phi)
    D = c1 * c2 - c3 ** 2 * c ** 2
    dD = 2 * c3 ** 2 * c * s
    # H0 = [[c2, -c3 c], [-c3 c, c1]] / D; derivative in closed form
    d11 = -c2 * dD / D ** 2
    d12 = (c3 * s * D + c3 * c * dD) / D ** 2
    d22 = -c1 * dD / D ** 2
    want = np.array([[np.abs(d11).max(), np.abs(d12).max()], [np.abs(d12).max(), np.abs(d22).max()]])
    np.testing.assert_allclose(d.dy_k1, want, rtol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("family", ["ii_speed", "ii_aov"])
def test_emitted_c_equals_reference_2dof(family):
    """RHS, init, estimate, single steps and a run: C against numpy reference, <= 1e-9 relative."""
    robot = load_robot("seed003_2r_abs")
    spec = observers.build(family, robot)
    dt = 1e-4
    obs = compile_observer(spec, dt=dt, method="rk4", hold="zoh")
    ref = _reference(spec, dt)
    worst = 0.0
    for k in range(60):
        # angles past +-pi (a link going round): the interval reduction y = 2 pi m + rho
        y = robot.sample_configurations(1, 100 + k)[0] + 2 * np.pi * RNG.integers(-2, 3, 2)
        u = RNG.normal(size=2)
        est0 = RNG.normal(size=4) * 3
        obs.reset(y, est0)
        ref.reset(y, est0)
        worst = max(worst, relative_error(obs.state, ref.state))
        # a filter state near the init one: |beta| grows with |y| (~k1 |y| / k_m), so a random
        # xi would give a huge xhat and a step far outside RK4's stability interval
        x = ref.state + np.concatenate([RNG.normal(size=2), 0.3 * RNG.normal(size=2), RNG.normal(size=2), [0]])
        x[-1] = RNG.uniform(*((1.0, 1.5) if family == "ii_aov" else (0.05, 0.5)))
        worst = max(worst, relative_error(obs.rhs(x, y, u), ref.rhs(x, y, u)))
        obs.state = x
        ref.state = x
        worst = max(worst, relative_error(obs.step(y, u), ref.step(y, u)))
        worst = max(worst, relative_error(obs.state, ref.state))
    assert worst <= TOL, worst


@lru_cache(maxsize=1)
def _ur5_spec():
    """ur5 I&I spec shared by the ur5 tests: N = 4 (with the interval reduction: 4 + 4 nodes
    per column) keeps generation and the cold C compile short."""
    robot = load_robot("ur5")
    return robot, observers.build("ii_speed", robot, N=4, bounds=ii_speed_bounds(robot, samples=50, refine=False))


def test_symbolic_equals_reference_ur5():
    """ur5: the CasADi RHS (quadrature + AD) against the reference (quadrature + pinocchio's
    analytical RNEA derivatives), <= 1e-9 relative; fast (no C)."""
    robot, spec = _ur5_spec()
    ref = _reference(spec, 1e-3)
    for k in range(3):
        y = robot.sample_configurations(1, k)[0] + 2 * np.pi * RNG.integers(-1, 2, 6)
        x = _random_state(robot, y)
        u = RNG.normal(size=robot.n) * 10
        a = np.array(spec.rhs(x, y, u, spec.p_default)).ravel()
        assert relative_error(a, ref.rhs(x, y, u)) <= TOL
        e = RNG.normal(size=2 * robot.n)
        assert relative_error(np.array(spec.init(y, e, spec.p_default)).ravel(),
                              ref.family.init(ref.robot, y, e, spec.p_default)) <= TOL


@pytest.mark.slow
def test_emitted_c_equals_reference_ur5():
    """ur5: emitted C RHS against the reference on random inputs, <= 1e-9 relative, with the
    interval reduction (wrap="auto": all six joints revolute). N = 4 keeps the cold compile
    short (the step calls the RHS routine, codegen/discrete/discretize.py); the accuracy of beta against
    scipy is test_quadrature_converges's business. The library comes from the build cache
    after the first compile."""
    robot, spec = _ur5_spec()
    assert spec.options.periodic == (True,) * 6
    # ~100k-instruction kernel; its default gains need sub-steps at 1 kHz (the stability check
    # finds a spectral radius of 22 with one RK4 step, and its search for the substeps costs
    # minutes on this kernel): the RHS compared here does not depend on the step, so no check
    obs = compile_observer(spec, dt=1e-3, method="rk4", hold="zoh", substeps=1, check=False, cflags=("-O1",))
    ref = _reference(spec, 1e-3)
    for k in range(3):
        y = robot.sample_configurations(1, 10 + k)[0] + 2 * np.pi * RNG.integers(-1, 2, 6)
        x = _random_state(robot, y)
        u = RNG.normal(size=robot.n) * 10
        assert relative_error(obs.rhs(x, y, u), ref.rhs(x, y, u)) <= TOL


@pytest.mark.slow
def test_seed003_scenario_converges():
    """docs/papers/experiments.md §12.3 (0.6 s): s_y -> y, xhat and s_x -> x, r bounded, for the I&I observer; the
    AOV comparison is in the same summary."""
    from codegen.evaluate.scenarios.seed003 import run_seed003
    s, tr = run_seed003(T=0.6, plots=False)
    ii, aov = s["ii"], s["aov"]
    assert ii["|s_y-y| final"] < 1e-2 < ii["|s_y-y| t=0"]
    assert ii["|xhat-x| final"] < 1e-2
    # e_x' = -psi2 e_x once xhat = x, psi2 >= k3 = 2.5: e^{-2.5 * 0.6} = 0.22
    assert ii["|s_x-x| final"] < 0.15 * ii["|s_x-x| t=0"]
    assert ii["r max"] <= 0.2 and ii["r final"] >= 1e-3 - 1e-12     # r > c_r, bounded
    assert aov["|s_y-y| final"] < ii["|s_y-y| t=0"] and aov["r max"] < 10
    n = 2
    ex = np.linalg.norm(tr["est"]["ii"][:, :n] - tr["x"][:, n:], axis=1)
    assert ex[-1] < ex[len(ex) // 2] < ex[len(ex) // 4]


def test_wrap_option_resolution():
    """wrap="auto" follows robot.periodic (models side) and the reference robot's own flags
    (pinocchio joint types, closed forms); True on a robot without periodic joints and a spec
    whose flags disagree with the reference are errors."""
    from codegen.families.observers._ii_common import resolve_wrap
    from codegen.reference import reference_robot
    from codegen.reference.families.ii_speed import check_periodic
    for name in ("ur5", "seed003_2r_abs", "seed000_2r"):
        robot = load_robot(name)
        rr = reference_robot(robot.source)
        assert list(robot.periodic) == list(rr.periodic) == [True] * robot.n
        assert resolve_wrap(robot, "auto") == check_periodic(rr, robot.periodic) == [True] * robot.n
        assert resolve_wrap(robot, False) == [False] * robot.n
    robot = load_robot("seed003_2r_abs")

    class Sliding:                       # a robot declaring a non-periodic (prismatic) joint
        n, name, joint_names, periodic = 2, "sliding", ["a", "b"], np.array([True, False])
    assert resolve_wrap(Sliding, "auto") == [True, False]
    with pytest.raises(ValueError):
        resolve_wrap(Sliding, True)
    with pytest.raises(ValueError):                    # the spec reduces a joint the reference
        check_periodic(Sliding, [True, True])           # robot does not know to be periodic
    spec = observers.build("ii_speed", robot, wrap=False)
    assert spec.options.periodic == (False, False) and _reference(spec, 1e-3).family.periodic == [False, False]


def test_wrap_removes_the_drift_at_large_angles():
    """At y2 = 9.3 rad (where the seed-003 arm is at t = 2 s) the reduced quadrature keeps
    dbeta/ds_y, dbeta/ds_x at the adaptive value; N-node Gauss-Legendre on [0, 9.3] does not."""
    from codegen.reference import reference_robot
    from codegen.evaluate.sim.studies import adaptive_beta
    robot = reference_robot(load_robot("seed003_2r_abs").source)
    y, s_y, s_x, k1 = np.array([1.2, 9.3]), np.array([1.25, 9.3 - 2 * np.pi]), np.array([-2.0, 4.0]), 40.0
    exact = adaptive_beta(robot, y, s_y, s_x, k1, epsabs=1e-13, epsrel=1e-12)

    def err(periodic, N_period=None):
        b, _, dsy, dsx = ref_ii.beta_and_derivatives(robot, y, s_y, s_x, k1, 16, True, periodic, N_period)
        return np.abs(np.concatenate([b, dsy.ravel(), dsx.ravel()]) - exact).max()
    assert err([False, False]) > 1e-3 * np.abs(exact).max()
    assert err([True, True]) < 1e-4 * np.abs(exact).max()      # ~5e-6 relative
    assert err([True, True], 32) < 1e-7 * np.abs(exact).max()


def test_quadrature_converges():
    """beta and its derivatives (reduced intervals) converge with N to the adaptive value on
    the whole [0, y_i], |y_i| up to 3 pi; small at the default N on the 2-DoF arm."""
    from codegen.families.observers._ii_common import DEFAULT_N
    from codegen.evaluate.sim.studies import quadrature_study
    t = quadrature_study(robots=("seed003_2r_abs",), Ns=(4, 8, 16, 24), samples=2)["seed003_2r_abs"]
    for k in range(3):
        assert t[4][k] > t[8][k] > t[16][k] > t[24][k]
    assert max(t[DEFAULT_N][:3]) < QUAD_TOL
