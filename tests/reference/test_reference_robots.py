"""The reference robots (codegen/reference/robots.py and below): closed forms from the docs'
formulas, URDF robots through pinocchio, DH and elastic robots with hyper-dual derivatives."""
from pathlib import Path

import numpy as np
import pytest

from codegen.reference import SEED_SOURCES, reference_robot
from codegen.reference.robots.urdf import file_sha256
from conftest import ur5_source

pin = pytest.importorskip("pinocchio")

RNG = np.random.default_rng(20240601)   # shared, in file order: the draws of the original file
CLOSED_FORM = ["seed000_2r", "seed002_2r", "seed003_2r_abs"]


# ---------------------------------------------------------------------------- closed forms
def test_seed000_mass_matrix_numbers():
    """docs/papers/seed000.md §1.2: M11 = 38.3333 + 30 cos q2, M12 = 15 + 15 cos q2, M22 = 15."""
    robot = reference_robot(SEED_SOURCES["seed000_2r"])
    for q in RNG.uniform(-np.pi, np.pi, (20, 2)):
        c2 = np.cos(q[1])
        expected = np.array([[115.0 / 3.0 + 30.0 * c2, 15.0 + 15.0 * c2], [15.0 + 15.0 * c2, 15.0]])
        np.testing.assert_allclose(robot.M(q), expected, rtol=1e-14, atol=1e-12)
    np.testing.assert_array_equal(robot.F, np.diag([0.1, 0.3]))


def test_seed002_mass_matrix_from_jacobians():
    """docs/papers/experiments.md §11.2 Remark 2: M = J_p^T diag(m) J_p + J_o^T diag(I) J_o, J_p from [S002 (34)]."""
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
        # Mdot = C + C^T [docs/papers/seed000.md §0]. With h = 1e-5 and O(1..100) entries the central
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
    """docs/papers/seed003.md §4.2 / A3-1: (59) equals M^{-1}(k1 I - C^T) with C the Christoffel matrix."""
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


def test_urdf_continuous_joints_match_seed000_closed_form():
    """The seed-000 arm as a URDF with continuous joints (pinocchio nq = 2, (cos, sin)),
    in the vertical x-z plane (rotation about -y maps x to (cos q, 0, sin q)): pinocchio's
    M, C, g, F, forward dynamics equal the closed form of docs/papers/experiments.md §11.1 (tests/data/seed000_2r.urdf:
    I1 = m1 l1^2/12 = 10/12, I2 = m2 l2^2/12 = 3.75)."""
    path = Path(__file__).parents[1] / "data" / "seed000_2r.urdf"
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


# ---------------------------------------------------------------------------- derivatives
@pytest.mark.parametrize("name", ["seed000_2r", "seed003_2r_abs"])
def test_closed_form_derivatives_match_central_differences(name):
    """dMw_dq and dCab_dq (closed forms, used by the I&I references) against central
    differences of M(q) w and C(q, a) b (truncation ~ h^2: 1e-8 relative)."""
    robot, rng, h = reference_robot(SEED_SOURCES[name]), np.random.default_rng(3), 1e-5
    for _ in range(5):
        q, w, a, b = rng.uniform(-np.pi, np.pi, 2), *rng.standard_normal((3, 2))
        E = np.eye(2)
        fd_M = np.column_stack([(robot.M(q + h * e) @ w - robot.M(q - h * e) @ w) / (2 * h) for e in E])
        fd_C = np.column_stack([(robot.C(q + h * e, a) @ b - robot.C(q - h * e, a) @ b) / (2 * h) for e in E])
        np.testing.assert_allclose(robot.dMw_dq(q, w), fd_M, rtol=0, atol=1e-8 * np.abs(fd_M).max())
        np.testing.assert_allclose(robot.dCab_dq(q, a, b), fd_C, rtol=0, atol=1e-8 * max(1.0, np.abs(fd_C).max()))


def test_urdf_elastic_derivatives_match_central_differences():
    """An elastic ur5 (URDF rigid part): D y3 from pinocchio's analytic ABA derivatives against
    central differences of y3 (1e-6 relative), and y4 = D y3[f]; the Spong Jacobian's y3 rows
    are those derivatives."""
    robot = reference_robot({"kind": "elastic", "rigid": ur5_source(), "J": [1.0] * 6, "K": [100.0] * 6})
    assert not robot.exact
    rng, h = np.random.default_rng(4), 1e-6
    q1 = rng.uniform(-np.pi, np.pi, 6)                  # a realistic deflection q1 - q2 ~ 1e-2 rad
    x = np.concatenate([q1, rng.standard_normal(6), q1 + 1e-2 * rng.standard_normal(6), rng.standard_normal(6)])
    _, Q = robot.spong_jacobian(x)
    for d in np.concatenate([np.eye(24)[:18:5], rng.standard_normal((3, 24))]):
        fd = (robot.y3(x + h * d) - robot.y3(x - h * d)) / (2 * h)
        np.testing.assert_allclose(Q[12:18] @ d, fd, rtol=0, atol=1e-6 * np.abs(fd).max())
    f = robot.f(x)
    fd = (robot.y3(x + h * f) - robot.y3(x - h * f)) / (2 * h)
    np.testing.assert_allclose(robot.y4(x), fd, rtol=0, atol=1e-6 * np.abs(fd).max())


def test_elastic_over_closed_form_refuses_derivatives():
    """Tomei needs only M, C, g; the Spong coordinates need hyper-duals or pinocchio."""
    robot = reference_robot({"kind": "elastic", "rigid": SEED_SOURCES["seed000_2r"], "J": [1.0, 1.0],
                             "K": [100.0, 100.0]})
    assert robot.M(np.zeros(2)).shape == (2, 2)
    with pytest.raises(ValueError, match="DH .* or URDF"):
        robot.y4(np.zeros(8))


@pytest.mark.parametrize("source,match", [
    ("seed000_2r", "'kind'"),
    ({"kind": "formula"}, "unknown robot source kind 'formula'"),
    ({"kind": "closed_form", "model": "planar_3r", "params": {}}, "unknown closed-form model 'planar_3r'"),
])
def test_bad_robot_sources_raise(source, match):
    with pytest.raises(ValueError, match=match):
        reference_robot(source)
