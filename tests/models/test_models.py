"""Closed-form seed robots against their formulas (docs/papers/), and the Christoffel properties."""
import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from models import ModelError, load_robot
from models.closed_form import Absolute2R, Planar2R, seed000_2r
from models.robot import RobotModel

angles = st.lists(st.floats(-np.pi, np.pi), min_size=2, max_size=2)
speeds = st.lists(st.floats(-5, 5), min_size=2, max_size=2)


def test_seed000_matches_spec_numbers():
    """docs/papers/seed000.md §1.2/§11.1: M11 = 38.3333 + 30 cos q2, M12 = 15 + 15 cos q2, M22 = 15; g; F."""
    r = load_robot("seed000_2r")
    for q in np.random.default_rng(0).uniform(-np.pi, np.pi, (50, 2)):
        c2 = np.cos(q[1])
        M = np.array(r.M(q))
        assert np.allclose(M, [[115 / 3 + 30 * c2, 15 + 15 * c2], [15 + 15 * c2, 15]], rtol=1e-14)
        g = np.array(r.g(q)).ravel()
        g2 = 20 * 0.75 * 9.81 * np.cos(q[0] + q[1])
        assert np.allclose(g, [(10 * 0.5 + 20 * 1) * 9.81 * np.cos(q[0]) + g2, g2], rtol=1e-14)
    assert np.allclose(np.diag(r.F), [0.1, 0.3])


def test_seed002_mass_matrix_is_jacobian_form():
    """docs/papers/experiments.md §11.2: M = J_p^T diag(m) J_p + J_o^T diag(I) J_o, J_p from (34)."""
    r = load_robot("seed002_2r")
    m1, m2, l1, lc1, lc2 = 2.0, 1.0, 0.4, 0.2, 0.1
    I1, I2 = m1 * 0.4 ** 2 / 12, m2 * 0.2 ** 2 / 12
    for q in np.random.default_rng(1).uniform(-np.pi, np.pi, (50, 2)):
        s1, c1, s12, c12 = np.sin(q[0]), np.cos(q[0]), np.sin(q.sum()), np.cos(q.sum())
        Jp = np.array([[-lc1 * s1, lc1 * c1, -l1 * s1 - lc2 * s12, l1 * c1 + lc2 * c12],
                       [0, 0, -lc2 * s12, lc2 * c12]]).T
        Jo = np.array([[1, 0], [1, 1]])
        M = Jp.T @ np.diag([m1, m1, m2, m2]) @ Jp + Jo.T @ np.diag([I1, I2]) @ Jo
        assert np.allclose(np.array(r.M(q)), M, rtol=1e-13)
        assert np.allclose(np.array(r.Jcom(q)), Jp, rtol=1e-13, atol=1e-15)


def test_seed003_matches_spec():
    """docs/papers/seed003.md §4.2: M = [[c1, c3 cos phi], [c3 cos phi, c2]], Christoffel C, G = [c4 cos y1; c5 cos y2]."""
    r = load_robot("seed003_2r_abs")
    y, x = np.array([0.4, -1.1]), np.array([0.7, -2.0])
    phi = y[0] - y[1]
    assert np.allclose(np.array(r.M(y)), [[0.9698, 0.264 * np.cos(phi)], [0.264 * np.cos(phi), 0.1575]])
    assert np.allclose(np.array(r.C(y, x)), [[0, 0.264 * np.sin(phi) * x[1]], [-0.264 * np.sin(phi) * x[0], 0]])
    assert np.allclose(np.array(r.g(y)).ravel(), [1.74 * np.cos(y[0]), 0.44 * np.cos(y[1])])
    with pytest.raises(ModelError, match="no link lengths"):
        r.com(y)


@pytest.mark.parametrize("name", ["seed000_2r", "seed002_2r", "seed003_2r_abs"])
def test_closed_form_coriolis_is_christoffel_of_M(name):
    """The hand-typed C of each closed-form robot equals RobotModel's generic Christoffel C."""
    r = load_robot(name)
    q, v = ca.SX.sym("q", 2), ca.SX.sym("v", 2)
    generic = ca.Function("Cg", [q, v], [RobotModel.coriolis(r, q, v)])
    for q0, v0 in zip(*np.random.default_rng(2).normal(size=(2, 20, 2))):
        assert np.allclose(np.array(generic(q0, v0)), np.array(r.C(q0, v0)), rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("name", ["seed000_2r", "seed002_2r", "seed003_2r_abs"])
@settings(max_examples=40, deadline=None)
@given(q=angles, a=speeds, b=speeds)
def test_christoffel_properties(name, q, a, b):
    """Mdot = C + C^T (Mdot by AD directional derivative) and C(q,a)b = C(q,b)a  [S000 (3)]."""
    r = load_robot(name)
    qs = ca.SX.sym("q", 2)
    Mdot = ca.Function("Mdot", [qs], [ca.jtimes(r.mass_matrix(qs), qs, ca.DM(a))])
    C = np.array(r.C(q, a))
    scale = np.abs(np.array(r.M(q))).max() * (1 + np.abs(a).max())
    assert np.abs(np.array(Mdot(q)) - C - C.T).max() <= 1e-12 * scale
    assert np.allclose(C @ b, np.array(r.C(q, b)) @ a, rtol=1e-12, atol=1e-12 * scale * (1 + np.abs(b).max()))


def test_mass_scaling_for_example_1b():
    """docs/papers/experiments.md §11.1 Example 1b: masses (and rod inertias) x 1.1."""
    M0, M1 = seed000_2r().M([0.3, 0.2]), seed000_2r(mass_scale=1.1).M([0.3, 0.2])
    assert np.allclose(np.array(M1), 1.1 * np.array(M0))


def test_bad_closed_form_parameters():
    with pytest.raises(ModelError, match="positive"):
        Planar2R("bad", 0.0, 1, 1, 1, 0.5, 0.5, 0.1, 0.1)
    with pytest.raises(ModelError, match="positive definite"):
        Absolute2R("bad", 0.1, 0.1, 0.2, 0, 0)


def test_catalog_errors():
    with pytest.raises(KeyError, match="unknown robot"):
        load_robot("nope")
    with pytest.raises(ValueError, match="exactly one"):
        load_robot()
