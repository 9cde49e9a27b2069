"""The design's numeric dynamics (codegen.families.design.rigid_batch) against the symbolic model
it replaces there: M(q), the Christoffel tensor, the products C(q, v) v, C(q, v)^T C(q, v) v, g(q)
and dg/dq on catalog arms, unaligned chains with prismatic joints and a branching tree; c0
computed from the tree equals c0 from the symbolic Christoffel slices; a 50-joint design stays within its memory
bound; a design over its CPU budget is refused naming --design k0= (docs/papers/seed000.md §0,
docs/architecture.md)."""
import tracemalloc
import xml.etree.ElementTree as ET

import casadi as ca
import numpy as np
import pytest

from codegen.core.symbolic import christoffel_slices
from codegen.families.design import configurations as cf
from codegen.families.design.rigid_batch import TreeBatch
from models import load_robot
from models.urdf import load_urdf
from urdf_chain import Joint, Link, write_chain


def _txt(x):
    return " ".join(repr(float(e)) for e in np.atleast_1d(x))


def _unaligned_chain(n, seed=0, types=("revolute", "prismatic", "continuous")):
    """n joints of random types, unaligned axes and placements, random inertials."""
    rng = np.random.default_rng(seed)
    joints = []
    for i in range(n):
        axis = rng.normal(size=3)
        moments = rng.uniform(0.01, 0.05, 3)
        inertia = {"ixx": _txt(moments[0]), "ixy": "0", "ixz": "0", "iyy": _txt(moments[1]), "iyz": "0",
                   "izz": _txt(moments[2])}
        link = Link(f"l{i}", mass=_txt(rng.uniform(0.5, 2.0)), com=_txt(rng.uniform(-0.1, 0.1, 3)),
                    inertia=inertia)
        joints.append(Joint(f"j{i}", types[i % len(types)], link, axis=_txt(axis / np.linalg.norm(axis)),
                            origin=_txt(rng.uniform(-0.2, 0.2, 3)), rpy=_txt(rng.uniform(-np.pi, np.pi, 3))))
    return joints


def _tree_urdf(path):
    """base - a - {b - c, d}: body d branches off a (a tree, not a chain)."""
    root = ET.Element("robot", name="tree")
    ET.SubElement(root, "link", name="base")
    for name, parent, axis, xyz, jtype in (("a", "base", "0 0 1", "0 0 0.1", "revolute"),
                                          ("b", "a", "0.6 0.8 0", "0.3 0 0", "revolute"),
                                          ("c", "b", "0 0 1", "0.2 0.1 0", "prismatic"),
                                          ("d", "a", "1 0 0", "0 0.3 0.1", "revolute")):
        j = ET.SubElement(root, "joint", name=f"j{name}", type=jtype)
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=name)
        ET.SubElement(j, "origin", xyz=xyz, rpy="0.1 -0.2 0.3")
        ET.SubElement(j, "axis", xyz=axis)
        ET.SubElement(j, "limit", lower="-1", upper="1", effort="10", velocity="2")
        link = ET.SubElement(root, "link", name=name)
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz="0.05 0.02 -0.01")
        ET.SubElement(inertial, "mass", value="1.3")
        ET.SubElement(inertial, "inertia", ixx="0.02", ixy="0.001", ixz="0", iyy="0.03", iyz="0", izz="0.01")
    path.write_text(ET.tostring(root, encoding="unicode"))
    return path


@pytest.fixture(params=["ur5", "chain", "tree"])
def robot(request, tmp_path):
    if request.param == "ur5":
        return load_robot("ur5")
    if request.param == "chain":
        return load_urdf(write_chain(tmp_path / "chain.urdf", _unaligned_chain(5)))
    return load_urdf(_tree_urdf(tmp_path / "tree.urdf"))


def test_mass_matrix_christoffel_and_products_match_the_symbolic_model(robot):
    n = robot.n
    Q = robot.sample_configurations(4, seed=3)
    V = np.random.default_rng(1).normal(size=(4, n))
    batch = TreeBatch(robot.tree, Q)
    assert batch.chain == (robot.name != "tree")
    q = ca.SX.sym("q", n)
    slices = ca.Function("s", [q], [christoffel_slices(robot, q)])
    M, T = batch.mass_matrix(), batch.christoffel()
    c, h = batch.coriolis_products(np.arange(4), V)
    g, dg = batch.gravity()
    dgf = ca.Function("dg", [q], [ca.jacobian(robot.gravity(q), q)])
    for s in range(4):
        np.testing.assert_allclose(M[s], np.array(robot.M(Q[s])), rtol=0, atol=1e-13)
        # slices [i, k*n + j] = C(q, e_k)[i, j];  T[i, j, k] = C(q, e_k)[i, j]
        np.testing.assert_allclose(T[s], np.array(slices(Q[s])).reshape(n, n, n).transpose(0, 2, 1),
                                   rtol=0, atol=1e-13)
        C = np.array(robot.C(Q[s], V[s]))
        np.testing.assert_allclose(c[s], C @ V[s], rtol=0, atol=1e-12 * max(1, np.abs(C @ V[s]).max()))
        np.testing.assert_allclose(h[s], C.T @ C @ V[s], rtol=0,
                                   atol=1e-12 * max(1, np.abs(C.T @ C @ V[s]).max()))
        np.testing.assert_allclose(g[s], np.array(robot.g(Q[s])).ravel(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(dg[s], np.array(dgf(Q[s])), rtol=0, atol=1e-12)


@pytest.mark.parametrize("n", [5, 14])
def test_c0_from_the_tree_equals_c0_from_the_christoffel_slices(n, tmp_path):
    """The tensor path (n <= TENSOR_MAX) and the product path (beyond, with its own starts) against
    the former computation (c0_batch on the symbolic slices from the n unit vectors and 2 random
    starts): equal up to round-off on the tensor path, never above it, on the product path, by
    more than its tolerance, and at most 2 % below (the ascents are local: fewer starts can miss a
    branch)."""
    robot = load_urdf(write_chain(tmp_path / "c.urdf", _unaligned_chain(n, seed=n)))
    pts = cf.sample_points(robot, 12, 0)
    stats = cf.ConfigurationStats.__new__(cf.ConfigurationStats)
    stats.robot, stats._model, stats._budget = robot, cf.dynamics_model(robot), cf._Budget(robot, 600)
    lmin, lmax, c0, _ = stats.at(pts)
    q = ca.SX.sym("q", n)
    f = ca.Function("s", [q], [christoffel_slices(robot, q)]).map(len(pts))
    want = cf.c0_batch(np.asarray(f(pts.T)).reshape(n, len(pts), n * n).transpose(1, 0, 2), n)[0]
    lam = np.linalg.eigvalsh(np.asarray(robot.M.map(len(pts))(pts.T)).reshape(n, len(pts), n).transpose(1, 0, 2))
    np.testing.assert_allclose(lmin, lam[:, 0], rtol=1e-12)
    np.testing.assert_allclose(lmax, lam[:, -1], rtol=1e-12)
    if n <= cf.TENSOR_MAX:
        np.testing.assert_allclose(c0, want, rtol=1e-12)
    else:
        assert np.all(c0 <= want * (1 + 1e-9)) and np.all(c0 >= 0.98 * want), np.c_[c0, want]


def test_the_ascent_iterates_every_configuration_together(monkeypatch, tmp_path):
    """Issue 23: c0's ascent beyond TENSOR_MAX joints iterates all configurations at once, the
    memory bound splitting the pairs of each iteration into blocks, not the configurations into
    chunks each iterated to the end (chunks x iterations calls: 5,316 calls of a few pairs each
    for the 513 samples of a 50-joint chain); the blocks do not change c0."""
    n, S = 9, 24
    robot = load_urdf(write_chain(tmp_path / "c.urdf", _unaligned_chain(n, seed=4, types=("revolute",))))
    model = cf.dynamics_model(robot)
    batch = model.batch(cf.sample_points(robot, S - 1, 0))
    whole = cf.c0_ascent(batch.coriolis_products, S, n, tol=1e-10, unit_starts=cf.LARGE_UNIT_STARTS, prune=True)
    monkeypatch.setattr(cf, "MEMORY_BYTES", model.pair_bytes * n * 4)      # 4 n pairs a call
    calls = []

    def products(rows, v):
        calls.append(np.asarray(rows).copy())
        return batch.coriolis_products(rows, v)
    c0, v = cf.c0_ascent(products, S, n, tol=1e-10, unit_starts=cf.LARGE_UNIT_STARTS, prune=True)
    assert all(len(r) <= 4 * n for r in calls)
    starts = S * (cf.LARGE_UNIT_STARTS + 2)
    first = np.concatenate(calls[S // 4:S // 4 + -(-starts // (4 * n))])    # after the unit-vector choice
    assert np.array_equal(np.unique(first), np.arange(S))
    np.testing.assert_allclose(c0, whole[0], rtol=1e-15)
    np.testing.assert_allclose(v, whole[1], rtol=0, atol=1e-15)


def test_the_c0_sup_does_not_evaluate_the_mass_matrix(robot, monkeypatch):
    """The sup of c0 (``extremes``' third) needs no lambda(M): ``at(..., eig=False)`` returns None
    for them and never forms M(q)."""
    stats = cf.ConfigurationStats.__new__(cf.ConfigurationStats)
    stats.robot, stats._model, stats._budget = robot, cf.dynamics_model(robot), cf._Budget(robot, 600)
    pts = cf.sample_points(robot, 6, 0)
    full = stats.at(pts)
    monkeypatch.setattr(TreeBatch, "mass_matrix", lambda *a, **k: pytest.fail("M(q) formed"))
    lmin, lmax, c0, v = stats.at(pts, eig=False)
    assert lmin is None and lmax is None
    np.testing.assert_array_equal(c0, full[2])
    np.testing.assert_array_equal(v, full[3])


@pytest.mark.slow
def test_fifty_joint_c0_stays_within_the_memory_bound(tmp_path):
    """F21 (issue 22): the former design allocated 24.8 GiB for 50 joints (the Christoffel tensor
    per (configuration, start) pair); the products keep a batch below MEMORY_BYTES."""
    robot = load_urdf(write_chain(tmp_path / "c50.urdf", _unaligned_chain(50, types=("revolute",))))
    stats = cf.ConfigurationStats.__new__(cf.ConfigurationStats)
    stats.robot, stats._model, stats._budget = robot, cf.dynamics_model(robot), cf._Budget(robot, 600)
    tracemalloc.start()
    try:
        lmin, _, c0, v = stats.at(cf.sample_points(robot, 8, 0))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= 2 * cf.MEMORY_BYTES, peak
    assert np.all(lmin > 0) and np.all(c0 > 0)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, rtol=1e-12)


def test_a_design_over_its_budget_is_refused_naming_the_gain_option(monkeypatch, tmp_path):
    from codegen.families.design import reduced_order as ro
    robot = load_urdf(write_chain(tmp_path / "slow.urdf", _unaligned_chain(6, seed=7)))
    monkeypatch.setattr(cf, "DESIGN_BUDGET_S", 0.0)
    monkeypatch.setenv("CODEGEN_CACHE", str(tmp_path / "cache"))
    with pytest.raises(cf.DesignBudgetError, match=r"--design k0=") as e:
        ro.reduced_order_gain(robot, eta=1.0, v_max=2.0, samples=16, seed=123)
    assert "\n" not in str(e.value) and "slow (6 joints)" in str(e.value)


def test_tensor_products_with_one_pair_per_configuration_or_several():
    """c0's products from a Christoffel tensor, C(q_s, v) = sum_k T[s, :, :, k] v_k: (C v, C^T C v)
    for pairs with one vector per configuration (rows increasing: one matrix product each) and
    for pairs that share configurations in any order, both against the sum written out."""
    rng = np.random.default_rng(5)
    S, n = 6, 4
    T = rng.normal(size=(S, n, n, n))
    products = cf.tensor_products(T)
    for rows in (np.arange(S), np.array([0, 2, 3, 5]), np.array([3, 1, 3, 0, 5, 1, 1])):
        v = rng.normal(size=(len(rows), n))
        C = np.einsum("pijk,pk->pij", T[rows], v)
        c = np.einsum("pij,pj->pi", C, v)
        got_c, got_h = products(rows, v)
        np.testing.assert_allclose(got_c, c, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(got_h, np.einsum("pij,pi->pj", C, c), rtol=1e-13, atol=1e-13)
