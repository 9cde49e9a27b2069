"""The reference robots' friction (codegen/reference/robots/friction.py):

    tau_f(v) = F v + coulomb tanh(v / w) + offset

from the description (closed-form and DH "F", the URDF's damping and friction through pinocchio)
and a source's "friction" entry; in the forward dynamics of every kind, through hyper-duals
(exact derivatives) and pinocchio's ABA derivatives (elastic robots); and equal to the symbolic
model's."""
from pathlib import Path

import numpy as np
import pytest

from codegen.reference import SEED_SOURCES, reference_robot
from codegen.reference.robots import hyperdual as hd
from codegen.reference.robots.urdf import file_sha256

pin = pytest.importorskip("pinocchio")

DATA = Path(__file__).parents[1] / "data"
ARM = DATA / "friction_arm.urdf"
RNG = np.random.default_rng(20240612)


def _rel(a, b):
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


def _arm_source(**friction):
    src = {"kind": "urdf", "path": str(ARM), "sha256": file_sha256(ARM), "locked_joints": {},
           "snap_tol": 1e-9}
    return dict(src, friction=friction) if friction else src


def test_friction_entry_replaces_the_description_and_is_the_equation():
    """seed000 (F = diag(0.1, 0.3)) with coulomb, offset and a width: F v + c tanh(v/w) + o."""
    src = dict(SEED_SOURCES["seed000_2r"], friction={"coulomb": [1.0, 0.5], "offset": [0.2, -0.1],
                                                     "coulomb_width": 0.05})
    r = reference_robot(src)
    for v in RNG.normal(scale=0.2, size=(10, 2)):
        want = np.array([0.1, 0.3]) * v + np.array([1.0, 0.5]) * np.tanh(v / 0.05) + [0.2, -0.1]
        assert _rel(r.friction_torque(v), want) < 1e-15
    r2 = reference_robot(dict(SEED_SOURCES["seed000_2r"], friction={"viscous": [0.0, 1.0]}))
    assert np.array_equal(r2.F, np.diag([0.0, 1.0]))
    q, v, tau = np.array([0.3, -0.4]), np.array([0.02, -0.5]), np.array([10.0, 3.0])
    M, C, g = r.M(q), r.C(q, v), r.g(q)
    assert _rel(r.forward_dynamics(q, v, tau), np.linalg.solve(M, tau - C @ v - g - r.friction_torque(v))) < 1e-14


def test_urdf_reference_reads_pinocchio_friction():
    """model.damping -> F, model.friction -> coulomb; the width and offsets from the entry."""
    r = reference_robot(_arm_source(coulomb_width=0.1, offset=[0.25, 0.0, -0.12]))
    assert np.array_equal(np.diag(r.F), [0.4, 0.3, 0.0]) and np.array_equal(r.coulomb, [1.5, 1.0, 0.5])
    m = pin.buildModelFromUrdf(str(ARM))
    d = m.createData()
    for q, v, tau in zip(RNG.uniform(-2, 2, (10, 3)), RNG.normal(scale=0.3, size=(10, 3)),
                         RNG.normal(scale=5, size=(10, 3))):
        tf = m.damping * v + m.friction * np.tanh(v / 0.1) + [0.25, 0.0, -0.12]
        assert _rel(r.forward_dynamics(q, v, tau), pin.aba(m, d, q, v, tau - tf)) < 1e-13
    xarm = Path(pin.__file__).resolve()
    for parent in xarm.parents:
        path = parent / "share" / "example-robot-data" / "robots" / "xarm_description" / "urdf" / "xarm7.urdf"
        if path.is_file():
            x = reference_robot({"kind": "urdf", "path": str(path), "friction": {"coulomb_width": 0.2}})
            assert np.array_equal(x.coulomb, [1.0] * 7) and np.array_equal(np.diag(x.F), [10, 10, 5, 5, 5, 2, 2])
            break


@pytest.mark.parametrize("source,match", [
    (_arm_source(), "needs a positive 'coulomb_width'"),
    (_arm_source(coulomb_width=0.0), "needs a positive 'coulomb_width'"),
    (dict(SEED_SOURCES["seed000_2r"], friction={"coulomb": [1.0, 1.0]}), "needs a positive"),
    (dict(SEED_SOURCES["seed000_2r"], friction={"stiction": [1.0, 1.0]}), "keys among"),
    ({"kind": "elastic", "rigid": SEED_SOURCES["seed000_2r"], "J": [1, 1], "K": [100, 100],
      "friction": {"offset": [0.1, 0.1]}}, "in its 'rigid' source"),
])
def test_bad_friction_entries_are_refused(source, match):
    with pytest.raises(ValueError, match=match):
        reference_robot(source)


def test_hyperdual_tanh_and_friction_derivatives_are_exact():
    """tanh on hyper-duals: first and second derivatives against the closed forms; the friction
    Jacobian against central differences."""
    x, u, w = np.array([0.03, -0.2, 1.1]), np.array([1.0, -0.5, 2.0]), np.array([0.3, 1.0, -1.0])
    h = hd.tanh(hd.seeded(x, u, w))
    t = np.tanh(x)
    assert _rel(h.a, t) < 1e-16 and _rel(h.b, (1 - t ** 2) * u) < 1e-15
    assert _rel(h.c, (1 - t ** 2) * w) < 1e-15 and _rel(h.d, -2 * t * (1 - t ** 2) * u * w) < 1e-15
    r = reference_robot(_arm_source(coulomb_width=0.1, offset=[0.25, 0.0, -0.12]))
    v, eps = np.array([0.02, -0.15, 0.4]), 1e-7
    fd = np.column_stack([(r.friction_torque(v + eps * e) - r.friction_torque(v - eps * e)) / (2 * eps)
                          for e in np.eye(3)])
    assert _rel(r.friction_jacobian(v), fd) < 1e-7


def test_dh_elastic_friction_through_hyperduals():
    """seed004_2r elastic with link friction: y3 = FD(x1, x2, -K(x1 - x3)) with tau_f, and the
    exact (hyper-dual) D y3 against central differences."""
    from models.catalog import load_elastic
    e = load_elastic("seed004_2r").with_friction(coulomb=[3.0, 2.0], offset=[0.5, -0.4], width=0.1)
    r = reference_robot(e.source)
    assert r.exact and np.array_equal(r.rigid.coulomb, [3.0, 2.0])
    x = np.r_[0.3, -0.5, 0.05, -0.08, 0.31, -0.49, 0.1, 0.0]
    x1, x2, x3 = x[:2], x[2:4], x[4:6]
    want = np.linalg.solve(r.M(x1), -r.K @ (x1 - x3) - r.rigid.nle(x1, x2) - r.rigid.friction_torque(x2))
    assert _rel(r.y3(x), want) < 1e-13
    assert _rel(np.array(e.f(x)).ravel()[2:4], want) < 1e-12                 # the symbolic model
    _, Q = r.spong_jacobian(x)
    h = 1e-6
    for d in np.eye(8)[:6]:
        fd = (r.y3(x + h * d) - r.y3(x - h * d)) / (2 * h)
        assert np.abs(Q[4:6] @ d - fd).max() <= 1e-6 * max(1.0, np.abs(fd).max())


def test_urdf_elastic_friction_derivatives_match_central_differences():
    """Elastic friction_arm (URDF rigid part, Coulomb and offsets): D y3 from pinocchio's ABA
    derivatives plus d tau_f/dv against central differences of y3."""
    r = reference_robot({"kind": "elastic", "rigid": _arm_source(coulomb_width=0.1, offset=[0.25, 0, -0.12]),
                         "J": [0.5] * 3, "K": [200.0] * 3})
    assert not r.exact
    rng, h = np.random.default_rng(5), 1e-6
    q1 = rng.uniform(-1.5, 1.5, 3)
    x = np.concatenate([q1, 0.1 * rng.standard_normal(3), q1 + 1e-2 * rng.standard_normal(3),
                        rng.standard_normal(3)])
    _, Q = r.spong_jacobian(x)
    for d in np.concatenate([np.eye(12)[:9], rng.standard_normal((3, 12))]):
        fd = (r.y3(x + h * d) - r.y3(x - h * d)) / (2 * h)
        assert np.abs(Q[6:9] @ d - fd).max() <= 1e-6 * max(1.0, np.abs(fd).max()), d


@pytest.mark.parametrize("kind", ["closed_form", "dh", "urdf"])
def test_reference_forward_dynamics_equals_the_model_with_friction(kind):
    """Our symbolic model and the reference rebuilt from its source agree with friction on."""
    from models import load_robot
    robot = {"closed_form": lambda: load_robot("seed000_2r").with_friction(coulomb=[2.0, 1.0], offset=0.3),
             "dh": lambda: load_robot("seed004_3r").with_friction(coulomb=1.0, offset=[0.1, 0.2, 0.3],
                                                                  width=0.07),
             "urdf": lambda: load_robot(urdf=ARM)}[kind]()
    ref = reference_robot(robot.source)
    for q, v, tau in zip(robot.sample_configurations(20, seed=1), RNG.normal(scale=0.3, size=(20, robot.n)),
                         RNG.normal(scale=10.0, size=(20, robot.n))):
        assert _rel(np.array(robot.fd(q, v, tau)), ref.forward_dynamics(q, v, tau)) < 1e-10
        assert _rel(np.array(robot.tau_f(v)), ref.friction_torque(v)) < 1e-15
