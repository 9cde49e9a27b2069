"""The independent reference (codegen.reference): robots from SPEC's formulas and
pinocchio, the reduced-order observer, its discretization and its input checks.

Uses a tiny fake description (a plain dict), so it depends on no other module of the project.
"""
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from codegen.reference import SEED_SOURCES, reference_observer, reference_robot
from codegen.reference.robots import file_sha256

pin = pytest.importorskip("pinocchio")

RNG = np.random.default_rng(20240601)
CLOSED_FORM = ["seed000_2r", "seed002_2r", "seed003_2r_abs"]


def _erd_robots():
    """example-robot-data's robots folder: <cmeel.prefix>/share/example-robot-data/robots,
    found by walking up from the installed pinocchio package."""
    for parent in Path(pin.__file__).resolve().parents:
        cand = parent / "share" / "example-robot-data" / "robots"
        if cand.is_dir():
            return cand
    pytest.skip("example-robot-data robots folder not found")


def ur5_source(**extra):
    path = _erd_robots() / "ur_description" / "urdf" / "ur5_robot.urdf"
    return dict({"kind": "urdf", "path": str(path), "sha256": file_sha256(path),
                 "locked_joints": {}, "snap_tol": 1e-9}, **extra)


def fake_spec(source, k0=16.037, family="reduced_order"):
    """The plain-data description the reference reads (ObserverSpec.describe() keys)."""
    n = reference_robot(source).n
    return {"family": family, "variant": None, "robot": source, "p_default": [k0],
            "names": {"p": ["k0"], "x": [f"z{i}" for i in range(n)], "y": [f"q{i}" for i in range(n)],
                      "u": [f"tau{i}" for i in range(n)], "est": [f"dq_hat{i}" for i in range(n)]},
            "options": {"kind": "Options"}, "hybrid": False,
            "rate_states": [f"z{i}" for i in range(n)] if family == "reduced_order" else [],
            "gains": {"k0": ["k0"]} if family == "reduced_order" else {}}


# ---------------------------------------------------------------------------- closed forms
def test_source_import_is_independent():
    """The hook's rule, checked here too: no CasADi, no symbolic code."""
    bad = re.compile(r"import casadi|from casadi|from codegen\.(observers|symbolic|emit|discretize|spec)|import models|from models")
    for f in Path(__file__).parents[1].joinpath("codegen", "reference").glob("*.py"):
        assert not bad.search(f.read_text()), f


def test_seed000_mass_matrix_numbers():
    """SPEC §1.2: M11 = 38.3333 + 30 cos q2, M12 = 15 + 15 cos q2, M22 = 15."""
    robot = reference_robot(SEED_SOURCES["seed000_2r"])
    for q in RNG.uniform(-np.pi, np.pi, (20, 2)):
        c2 = np.cos(q[1])
        expected = np.array([[115.0 / 3.0 + 30.0 * c2, 15.0 + 15.0 * c2], [15.0 + 15.0 * c2, 15.0]])
        np.testing.assert_allclose(robot.M(q), expected, rtol=1e-14, atol=1e-12)
    np.testing.assert_array_equal(robot.F, np.diag([0.1, 0.3]))


def test_seed002_mass_matrix_from_jacobians():
    """SPEC §11.2 Remark 2: M = J_p^T diag(m) J_p + J_o^T diag(I) J_o, J_p from [S002 (34)]."""
    robot = reference_robot(SEED_SOURCES["seed002_2r"])
    m1, m2, l1, lc1, lc2 = 2.0, 1.0, 0.4, 0.2, 0.1
    I1, I2 = m1 * 0.4 ** 2 / 12, m2 * 0.2 ** 2 / 12
    J_o = np.array([[1.0, 0.0], [1.0, 1.0]])
    for q in RNG.uniform(-np.pi, np.pi, (20, 2)):
        s1, c1, s12, c12 = np.sin(q[0]), np.cos(q[0]), np.sin(q.sum()), np.cos(q.sum())
        J_p = np.array([[-lc1 * s1, lc1 * c1, -l1 * s1 - lc2 * s12, l1 * c1 + lc2 * c12],
                        [0.0, 0.0, -lc2 * s12, lc2 * c12]]).T                    # [S002 (34)]
        M = J_p.T @ np.diag([m1, m1, m2, m2]) @ J_p + J_o.T @ np.diag([I1, I2]) @ J_o
        np.testing.assert_allclose(robot.M(q), M, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(robot.com_jacobian(q), J_p, rtol=1e-14, atol=1e-16)
        # the Jacobian is that of the CoM positions (central differences, error ~ h^2)
        h = 1e-6
        fd = np.column_stack([(robot.com_positions(q + h * e) - robot.com_positions(q - h * e)) / (2 * h)
                              for e in np.eye(2)])
        np.testing.assert_allclose(fd, J_p, atol=1e-9)


def _mdot_fd(robot, q, v, h=1e-5):
    """Mdot = dM/dt along v, by central differences (truncation ~ h^2 |M'''|)."""
    return (robot.M(q + h * v) - robot.M(q - h * v)) / (2 * h)


def _christoffel_checks(robot, samples=10, rtol_mdot=1e-8):
    n = robot.n
    for _ in range(samples):
        q = RNG.uniform(-np.pi, np.pi, n)
        v, a, b = RNG.standard_normal((3, n))
        C = robot.C(q, v)
        # Mdot = C + C^T [SPEC §0]. With h = 1e-5 and O(1..100) entries the central
        # difference is good to ~1e-9 absolute; 1e-8 relative to the largest entry of M.
        scale = np.abs(robot.M(q)).max() * max(1.0, np.abs(v).max())
        np.testing.assert_allclose(C + C.T, _mdot_fd(robot, q, v), rtol=0, atol=rtol_mdot * scale)
        # C(q, a) b = C(q, b) a [S000 (3)]: exact up to round-off
        lhs, rhs = robot.C(q, a) @ b, robot.C(q, b) @ a
        np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-12 * max(1.0, np.abs(lhs).max()))


@pytest.mark.parametrize("name", CLOSED_FORM)
def test_christoffel_properties_closed_form(name):
    _christoffel_checks(reference_robot(SEED_SOURCES[name]))


def test_seed003_equation_59_is_transposed_christoffel():
    """SPEC §4.2 / A3-1: (59) equals M^{-1}(k1 I - C^T) with C the Christoffel matrix."""
    robot = reference_robot(SEED_SOURCES["seed003_2r_abs"])
    c1, c2, c3 = 0.9698, 0.1575, 0.264
    k1 = 40.0
    for _ in range(20):
        y = RNG.uniform(-np.pi, np.pi, 2)
        x = RNG.uniform(-10, 10, 2)
        phi = y[0] - y[1]
        s, c = np.sin(phi), np.cos(phi)
        D = c1 * c2 - c3 ** 2 * c ** 2
        H59 = np.array([[c2 * k1 + c3 ** 2 * x[1] * s * c, c3 * (c2 * x[0] * s - k1 * c)],
                        [-c3 * (c1 * x[1] * s + k1 * c), c1 * k1 - c3 ** 2 * x[0] * s * c]]) / D
        H = np.linalg.solve(robot.M(y), k1 * np.eye(2) - robot.C(y, x).T)
        np.testing.assert_allclose(H, H59, rtol=1e-12, atol=1e-12)
    # gravity_scale multiplies G (A3-2)
    src = dict(SEED_SOURCES["seed003_2r_abs"], params=dict(SEED_SOURCES["seed003_2r_abs"]["params"], gravity_scale=9.81))
    y = RNG.uniform(-1, 1, 2)
    np.testing.assert_allclose(reference_robot(src).g(y), 9.81 * robot.g(y), rtol=1e-15)


@pytest.mark.parametrize("name", CLOSED_FORM)
def test_closed_form_forward_dynamics(name):
    robot = reference_robot(SEED_SOURCES[name])
    for _ in range(5):
        q, v, tau = RNG.standard_normal((3, 2))
        qdd = robot.forward_dynamics(q, v, tau)
        np.testing.assert_allclose(robot.M(q) @ qdd + robot.C(q, v) @ v + robot.F @ v + robot.g(q), tau,
                                   rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------------------- URDF
def test_ur5_forward_dynamics_matches_crba_nle():
    robot = reference_robot(ur5_source())
    assert robot.n == 6
    model = pin.buildModelFromUrdf(robot.path)
    data = model.createData()
    for _ in range(10):
        q, v, tau = RNG.uniform(-np.pi, np.pi, 6), RNG.standard_normal(6), 10 * RNG.standard_normal(6)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        nle = pin.nonLinearEffects(model, data, q, v)
        expected = np.linalg.solve(M, tau - nle - robot.F @ v)
        np.testing.assert_allclose(robot.forward_dynamics(q, v, tau), expected, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(robot.M(q), robot.M(q).T, rtol=0, atol=0)
        np.testing.assert_allclose(robot.nle(q, v), robot.C(q, v) @ v + robot.g(q), rtol=1e-10, atol=1e-10)


def test_ur5_christoffel_properties():
    _christoffel_checks(reference_robot(ur5_source()), samples=5)


def test_ur5_sha256_mismatch_raises():
    with pytest.raises(ValueError, match="sha256"):
        reference_robot(ur5_source(sha256="0" * 64))


def test_ur5_locked_joint_is_a_sub_block():
    """Locking wrist_3 at a value: the reduced M, g are the free block of the full ones."""
    full = reference_robot(ur5_source())
    locked = reference_robot(ur5_source(locked_joints={"wrist_3_joint": 0.7}))
    assert locked.n == 5 and "wrist_3_joint" not in locked.joint_names
    for _ in range(5):
        q = RNG.uniform(-np.pi, np.pi, 5)
        qf = np.append(q, 0.7)
        np.testing.assert_allclose(locked.M(q), full.M(qf)[:5, :5], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(locked.g(q), full.g(qf)[:5], rtol=1e-10, atol=1e-10)
    with pytest.raises(ValueError, match="not_a_joint"):
        reference_robot(ur5_source(locked_joints={"not_a_joint": 0.0}))


SEED000_URDF = """<?xml version="1.0"?>
<robot name="seed000_2r">
  <link name="world"/>
  <joint name="j1" type="continuous">
    <parent link="world"/><child link="link1"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 -1 0"/>
    <dynamics damping="0.1" friction="0"/>
  </joint>
  <link name="link1">
    <inertial><origin xyz="0.5 0 0" rpy="0 0 0"/><mass value="10"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="{I1}" iyz="0" izz="{I1}"/></inertial>
  </link>
  <joint name="j2" type="continuous">
    <parent link="link1"/><child link="link2"/>
    <origin xyz="1 0 0" rpy="0 0 0"/><axis xyz="0 -1 0"/>
    <dynamics damping="0.3" friction="0"/>
  </joint>
  <link name="link2">
    <inertial><origin xyz="0.75 0 0" rpy="0 0 0"/><mass value="20"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="{I2}" iyz="0" izz="{I2}"/></inertial>
  </link>
</robot>
"""


def test_urdf_continuous_joints_match_seed000_closed_form(tmp_path):
    """The seed-000 arm as a URDF with continuous joints (pinocchio nq = 2, (cos, sin)),
    in the vertical x-z plane (rotation about -y maps x to (cos q, 0, sin q)): pinocchio's
    M, C, g, F, forward dynamics equal the closed form of SPEC §11.1."""
    path = tmp_path / "seed000_2r.urdf"
    path.write_text(SEED000_URDF.format(I1=repr(10.0 / 12), I2=repr(20.0 * 2.25 / 12)))
    urdf = reference_robot({"kind": "urdf", "path": str(path), "sha256": file_sha256(path),
                            "locked_joints": {}, "snap_tol": 1e-9})
    closed = reference_robot(SEED_SOURCES["seed000_2r"])
    assert urdf.model.nq == 4 and urdf.n == 2
    np.testing.assert_allclose(urdf.F, closed.F, rtol=1e-15)
    for _ in range(10):
        q, v, tau = RNG.uniform(-np.pi, np.pi, 2), RNG.standard_normal(2), 50 * RNG.standard_normal(2)
        np.testing.assert_allclose(urdf.M(q), closed.M(q), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(urdf.C(q, v), closed.C(q, v), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(urdf.g(q), closed.g(q), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(urdf.forward_dynamics(q, v, tau), closed.forward_dynamics(q, v, tau),
                                   rtol=1e-10, atol=1e-10)
    # locking a continuous joint at an angle: the remaining arm is link 1 carrying a rigid link 2
    locked = reference_robot({"kind": "urdf", "path": str(path), "locked_joints": {"j2": 0.4}})
    q1 = np.array([0.3])
    np.testing.assert_allclose(locked.M(q1), closed.M(np.array([0.3, 0.4]))[:1, :1], rtol=1e-12)
    np.testing.assert_allclose(locked.g(q1), closed.g(np.array([0.3, 0.4]))[:1], rtol=1e-12)


# ---------------------------------------------------------------------------- observer
def test_reduced_order_equations_and_init():
    """rhs = forward_dynamics(y, x2hat, tau) - k0 x2hat; output = z + k0 y; the first
    estimate equals est0 [S000 (6),(9)]."""
    for source in (SEED_SOURCES["seed000_2r"], ur5_source()):
        spec = fake_spec(source, k0=7.5)
        ref = reference_observer(spec, dt=1e-3, hold="zoh")
        robot = ref.robot
        n = robot.n
        x, y, u = RNG.standard_normal((3, n))
        x2hat = x + 7.5 * y
        np.testing.assert_allclose(ref.output(x, y, u), x2hat, rtol=1e-15)
        # M z' = tau - C x2hat - F x2hat - g - k0 M x2hat, the unsolved form of [S000 (6)]
        M = robot.M(y)
        lhs = M @ ref.rhs(x, y, u)
        rhs = u - robot.C(y, x2hat) @ x2hat - robot.F @ x2hat - robot.g(y) - 7.5 * M @ x2hat
        np.testing.assert_allclose(lhs, rhs, rtol=1e-10, atol=1e-10)
        est0 = RNG.standard_normal(n)
        ref.reset(y, est0)
        np.testing.assert_allclose(ref.state, est0 - 7.5 * y, rtol=1e-15)
        np.testing.assert_allclose(ref.step(y, u), est0, rtol=1e-14, atol=1e-15)
        # p given at reset overrides the default
        ref.reset(y, est0, p=[3.0])
        assert ref.params[0] == 3.0
        np.testing.assert_allclose(ref.state, est0 - 3.0 * y, rtol=1e-15)


def _exact_step(ref, x, y, u, dt):
    sol = solve_ivp(lambda t, z: ref.rhs(z, y, u), (0.0, dt), x, method="DOP853", rtol=1e-13, atol=1e-13)
    return sol.y[:, -1]


@pytest.mark.parametrize("dt,substeps", [(1e-3, 1), (1e-2, 10)])
def test_rk4_step_matches_exact_flow(dt, substeps):
    """One step of rk4 with y, u held equals the exact flow (solve_ivp, rtol 1e-13) to 1e-9."""
    spec = fake_spec(SEED_SOURCES["seed000_2r"])
    ref = reference_observer(spec, dt=dt, method="rk4", substeps=substeps, hold="zoh")
    for _ in range(5):
        y, est0 = RNG.uniform(-2, 2, 2), RNG.uniform(-3, 3, 2)
        u = 100 * RNG.standard_normal(2)
        ref.reset(y, est0)
        x0 = ref.state
        ref.step(y, u)
        assert np.abs(ref.state - _exact_step(ref, x0, y, u, dt)).max() <= 1e-9


@pytest.mark.parametrize("method,order", [("euler", 1), ("rk4", 4)])
def test_convergence_order(method, order):
    """Halving h divides the error over a step by 2^order (checked within 25 %)."""
    spec = fake_spec(SEED_SOURCES["seed000_2r"], k0=5.0)
    dt = 0.05
    y, est0, u = np.array([0.4, -0.8]), np.array([1.0, -2.0]), np.array([30.0, -10.0])
    errs = []
    for substeps in (4, 8, 16):
        ref = reference_observer(spec, dt=dt, method=method, substeps=substeps, hold="zoh")
        ref.reset(y, est0)
        x0 = ref.state
        ref.step(y, u)
        errs.append(np.abs(ref.state - _exact_step(ref, x0, y, u, dt)).max())
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    np.testing.assert_allclose(ratios, 2.0 ** order, rtol=0.25)


def _seed000_plant(t):
    robot = reference_robot(SEED_SOURCES["seed000_2r"])

    def tau(tt):
        return robot.g(np.zeros(2)) + np.array([20 * np.sin(3 * tt), 10 * np.cos(2 * tt)])

    def f(tt, s):
        return np.concatenate([s[2:], robot.forward_dynamics(s[:2], s[2:], tau(tt))])

    return robot, tau, f, np.array([0.1, -0.2, 0.5, -0.3])


def test_continuous_observer_converges_on_seed000_plant():
    """SPEC §1.1: with k0 = 16.037 (SPEC §1.2) the estimate of the continuous-time observer
    converges to the true velocity; the error falls by > 1e5 within 1 s (rate ~ k0)."""
    t = np.linspace(0.0, 1.0, 11)
    robot, tau, plant, s0 = _seed000_plant(t)
    ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), hold="zoh")
    k0 = ref.params[0]

    def f(tt, s):
        return np.concatenate([plant(tt, s[:4]), ref.rhs(s[4:], s[:2], tau(tt))])

    z0 = -k0 * s0[:2]                                   # x2hat(0) = 0
    sol = solve_ivp(f, (0, 1), np.concatenate([s0, z0]), t_eval=t, method="DOP853", rtol=1e-12, atol=1e-12)
    err = [np.linalg.norm(ref.output(s[4:], s[:2], tau(tt)) - s[2:4]) for tt, s in zip(t, sol.y.T)]
    assert err[0] > 0.5 and err[-1] < 1e-5 * err[0]
    assert np.all(np.diff(err) < 0)


def test_sampled_observer_error_is_first_order_in_dt():
    """The sampled observer (y, u held over each step) tracks the velocity up to a bias
    O(dt) from the hold: halving dt halves the final error (within 20 %)."""
    finals = []
    for dt in (1e-3, 5e-4):
        t = np.arange(int(round(1.0 / dt)) + 1) * dt
        robot, tau, plant, s0 = _seed000_plant(t)
        sol = solve_ivp(plant, (0, t[-1]), s0, t_eval=t, method="DOP853", rtol=1e-12, atol=1e-12)
        Q, V = sol.y[:2].T, sol.y[2:].T
        U = np.array([tau(tt) for tt in t])
        ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), dt=dt, method="rk4", hold="zoh")
        ref.reset(Q[0])                                   # x2hat(0) = 0
        err = np.linalg.norm(ref.run(Q, U) - V, axis=1)
        assert err[0] > 0.5 and err[-1] < 0.1 * err[0]
        finals.append(err[-1])
    np.testing.assert_allclose(finals[0] / finals[1], 2.0, rtol=0.2)


def test_step_run_consistency():
    spec = fake_spec(SEED_SOURCES["seed002_2r"], k0=12.0)
    Y, U = RNG.uniform(-1, 1, (50, 2)), RNG.standard_normal((50, 2))
    a = reference_observer(spec, dt=2e-3, method="rk4", substeps=2, hold="zoh")
    b = reference_observer(spec, dt=2e-3, method="rk4", substeps=2, hold="zoh")
    a.reset(Y[0], [0.3, -0.1])
    b.reset(Y[0], [0.3, -0.1])
    EST = a.run(Y, U)
    EST_steps = np.array([b.step(y, u) for y, u in zip(Y, U)])
    np.testing.assert_array_equal(EST, EST_steps)
    np.testing.assert_array_equal(a.state, b.state)
    assert EST.shape == (50, 2)


def test_euler_is_one_explicit_step():
    spec = fake_spec(SEED_SOURCES["seed000_2r"])
    ref = reference_observer(spec, dt=1e-3, method="euler", hold="zoh")
    y, u = np.array([0.2, 0.3]), np.array([1.0, 2.0])
    ref.reset(y, [1.0, 1.0])
    x0 = ref.state
    ref.step(y, u)
    np.testing.assert_allclose(ref.state, x0 + 1e-3 * ref.rhs(x0, y, u), rtol=1e-15)


@pytest.mark.parametrize("args,name", [
    ((np.zeros(3), np.zeros(2)), "y"),
    ((np.zeros(2), np.zeros((2, 2))), "u"),
    ((np.array([0.0, np.nan]), np.zeros(2)), "y"),
    ((np.zeros(2), np.array([np.inf, 0.0])), "u"),
    (("ab", np.zeros(2)), "y"),
])
def test_bad_step_inputs_raise_and_keep_state(args, name):
    ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), hold="zoh")
    ref.reset([0.1, 0.2], [1.0, 2.0])
    before = ref.state
    with pytest.raises(ValueError, match=rf"^{name} .*\(2,\)"):
        ref.step(*args)
    np.testing.assert_array_equal(ref.state, before)


def test_bad_run_and_reset_inputs():
    ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), hold="zoh")
    with pytest.raises(RuntimeError, match="reset"):
        ref.step(np.zeros(2), np.zeros(2))
    ref.reset([0.1, 0.2])
    before = ref.state
    Y, U = np.zeros((5, 2)), np.zeros((5, 2))
    with pytest.raises(ValueError, match=r"^U .*\(5, 2\)"):
        ref.run(Y, U[:4])
    with pytest.raises(ValueError, match=r"^Y .*\(N, 2\)"):
        ref.run(np.zeros((5, 3)), U)
    U[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"^U must be finite.*row 3"):
        ref.run(Y, U)
    np.testing.assert_array_equal(ref.state, before)
    with pytest.raises(ValueError, match=r"^y0 "):
        ref.reset([0.1])
    with pytest.raises(ValueError, match=r"^est0 "):
        ref.reset([0.1, 0.2], [np.nan, 0.0])
    with pytest.raises(ValueError, match=r"^p "):
        ref.reset([0.1, 0.2], p=[1.0, 2.0])
    np.testing.assert_array_equal(ref.state, before)


def test_bad_construction():
    spec = fake_spec(SEED_SOURCES["seed000_2r"])
    with pytest.raises(ValueError, match="method"):
        reference_observer(spec, method="rk45")
    with pytest.raises(ValueError, match="dt"):
        reference_observer(spec, dt=0.0)
    with pytest.raises(ValueError, match="substeps"):
        reference_observer(spec, substeps=0)
    with pytest.raises(ValueError, match="family"):
        reference_observer(fake_spec(SEED_SOURCES["seed000_2r"], family="nope"))
    with pytest.raises(ValueError, match="sizes"):
        reference_observer({**spec, "names": {**spec["names"], "x": ["a"]}})
    with pytest.raises(ValueError, match="jump"):
        reference_observer({**spec, "hybrid": True})
    with pytest.raises(ValueError, match="options"):
        reference_observer({**spec, "options": {"kind": "Nonsense"}})
