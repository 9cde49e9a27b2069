"""Property test over random URDFs: serial chains of revolute, continuous, prismatic
and fixed joints with random names (unicode, C keywords, names that collide before or after
sanitising) and random inertial values (good, zero, negative, not positive definite, junk).
Each URDF either loads, and then M (crba), C v + g (nle) and the forward dynamics (aba) match
pinocchio's own algorithms on pinocchio's own parse of the file to 1e-10 (relative; absolute
below 1) and every slot macro
is a unique C identifier, or it is refused with a message naming an element (a joint, a link,
or the robot) of the file."""
import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

from codegen.pipeline.emit import _slot_macros
from models.robot import ModelError
from models.urdf import load_urdf
from urdf_chain import Joint, Link, write_chain

pin = pytest.importorskip("pinocchio")

TOL = 1e-10
C_WORDS = ["int", "for", "while", "return", "void", "static", "double", "auto", "register",
           "_Bool", "default", "x", "x.", "x_2", "X", "k_m", "k_M", "5dof", "*/", "a b"]
NAMES = st.one_of(
    st.sampled_from(C_WORDS),
    st.text(st.characters(blacklist_categories=("Cs", "Cc", "Zl", "Zp")), min_size=1, max_size=6),
    st.from_regex(r"[a-z][a-z0-9_]{0,5}", fullmatch=True))
BAD_VALUES = ["1_5", "nan", "inf", "-inf", "abc", " 2 ", "1e999", "0x10", ""]


@st.composite
def inertials(draw):
    """A link's <inertial>: mostly good (R diag R^T, positive), else zero, negative, not positive
    definite, absent or junk."""
    kind = draw(st.sampled_from(["good"] * 12 + ["none", "zero mass", "negative", "not pd", "junk"]))
    mass = draw(st.floats(0.05, 5.0))
    moments = draw(st.lists(st.floats(0.01, 1.0), min_size=3, max_size=3))
    angles = draw(st.lists(st.floats(-math.pi, math.pi), min_size=3, max_size=3))
    R = pin.rpy.rpyToMatrix(*angles)
    inertia = R @ np.diag(moments) @ R.T
    com = draw(st.lists(st.floats(-0.2, 0.2), min_size=3, max_size=3))
    if kind == "not pd":
        inertia[0, 0] = -inertia[0, 0]
    values = {k: repr(float(inertia[i, j])) for k, (i, j) in
              zip(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)))}
    mass_text = {"zero mass": "0", "negative": repr(-mass)}.get(kind, repr(mass))
    if kind == "junk":
        key = draw(st.sampled_from(["mass", "ixx", "iyz", "com"]))
        bad = draw(st.sampled_from(BAD_VALUES))
        if key == "mass":
            mass_text = bad
        elif key == "com":
            com = [bad, "0", "0"]
        else:
            values[key] = bad
    return (None if kind == "none" else mass_text), " ".join(map(str, com)), values


@st.composite
def chains(draw):
    """1-4 joints; names from a pool of distinct ones (which may still collide once sanitised:
    x, x., X), a link sometimes named like its joint, sometimes like anything (a duplicate)."""
    n = draw(st.integers(1, 4))
    pool = draw(st.lists(NAMES, min_size=2 * n, max_size=2 * n, unique=True))
    joints = []
    for i in range(n):
        jtype = draw(st.sampled_from(["revolute", "revolute", "continuous", "prismatic", "fixed"]))
        axis = draw(st.sampled_from(["0 0 1", "0 1 0", "1 0 0", "0 0 -1", "0.6 0.8 0", "1 1 1",
                                     "0 -1 0", "0 0 1", "0.3 0 0.2", "0 0 0"]))
        how = draw(st.sampled_from(["own"] * 6 + ["its joint's", "any"]))
        link = {"own": pool[n + i], "its joint's": pool[i], "any": draw(st.sampled_from(pool))}[how]
        mass, com, inertia = draw(inertials())
        xyz, rpy = (" ".join(repr(v) for v in draw(st.lists(st.floats(-r, r), min_size=3, max_size=3)))
                    for r in (0.5, 3.0))
        joints.append(Joint(pool[i], jtype, Link(link, mass=mass, com=com, inertia=inertia),
                            axis=axis, origin=xyz, rpy=rpy))
    return joints


def _rel(a, b):
    """|a - b| relative to |b|, or absolute where |b| < 1 (a torque of 1e-16 N m that is 0 in
    exact arithmetic, as gravity across a horizontal prismatic axis, has no relative error)."""
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1.0)


def _matches_pinocchio(robot, path, seed):
    """crba, nle and aba of pinocchio on its own parse of the file against ours, 3 samples."""
    m = pin.buildModelFromUrdf(str(path))
    d = m.createData()
    rng = np.random.default_rng(seed)
    for _ in range(3):
        q = rng.uniform(-1.0, 1.0, robot.n)
        v, tau = rng.normal(size=robot.n), rng.normal(scale=5.0, size=robot.n)
        qp = robot.pin_configuration(q)
        M = pin.crba(m, d, qp)
        M = np.triu(M) + np.triu(M, 1).T
        C, g = np.array(robot.C(q, v)), np.array(robot.g(q)).ravel()
        assert _rel(robot.M(q), M) <= TOL
        assert _rel(C @ v + g, pin.nonLinearEffects(m, d, qp, v)) <= TOL
        assert _rel(robot.fd(q, v, tau), pin.aba(m, d, qp, v, tau - robot.F @ v)) <= TOL


def _slots_are_unique_identifiers(robot):
    names = {"x": [f"z_{n}" for n in robot.joint_names], "y": [f"q_{n}" for n in robot.joint_names],
             "u": [f"tau_{n}" for n in robot.joint_names], "p": ["k0"],
             "est": [f"qd_hat_{n}" for n in robot.joint_names]}
    macros = [line.split()[1] for line in _slot_macros("P", names)]
    assert len(macros) == len(set(macros)), macros
    assert all(re.fullmatch(r"[A-Z_][A-Z0-9_]*", m) for m in macros), macros


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@pytest.mark.slow
@given(joints=chains())
def test_random_urdf_loads_and_matches_pinocchio_or_is_refused_naming_an_element(joints, tmp_path):
    path = write_chain(tmp_path / "random.urdf", joints)
    elements = {path.stem, "base"} | {j.name for j in joints} | {j.child.name for j in joints}
    try:
        robot = load_urdf(path, snap_tol=0.0)
    except ModelError as e:
        assert any(repr(name) in str(e) for name in elements), str(e)
        event("refused: " + re.sub(r"^.*?: (joint|link|robot) .*?(: |' )", r"\1 ", str(e))[:40])
        return
    event(f"loaded, n = {robot.n}")
    _matches_pinocchio(robot, path, seed=len(joints))
    _slots_are_unique_identifiers(robot)


# ------------------------------------------------------------------ long chains: the design scales
# Each chain of up to 50 joints is designed (the reduced-order gain, whose sups over
# configurations grow with n: codegen.families.design.configurations) or refused within a stated
# CPU budget: CHAIN_BUDGET_S (the design's DESIGN_BUDGET_S set to it) plus one batch of slack.
CHAIN_BUDGET_S, SLACK_S = 60.0, 5.0


@st.composite
def long_chains(draw, n_min, n_max):
    """n_min..n_max revolute, continuous or prismatic joints, unaligned axes and placements, good
    inertials (R diag R^T) with a few absent ones (a massless link: refused or carried)."""
    n = draw(st.integers(n_min, n_max))
    joints = []
    for i in range(n):
        jtype = draw(st.sampled_from(["revolute", "revolute", "continuous", "prismatic"]))
        axis = np.array(draw(st.lists(st.floats(0.2, 1.0), min_size=3, max_size=3)))
        axis *= draw(st.sampled_from([1, -1])) * np.array(draw(st.sampled_from([(1, 1, 1), (1, -1, 1), (-1, 1, 1)])))
        kind = draw(st.sampled_from(["good"] * 15 + ["none"]))
        moments = draw(st.lists(st.floats(0.01, 0.2), min_size=3, max_size=3))
        R = pin.rpy.rpyToMatrix(*draw(st.lists(st.floats(-math.pi, math.pi), min_size=3, max_size=3)))
        inertia = R @ np.diag(moments) @ R.T
        values = {k: repr(float(inertia[a, b])) for k, (a, b) in
                  zip(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)))}
        com = " ".join(repr(v) for v in draw(st.lists(st.floats(-0.2, 0.2), min_size=3, max_size=3)))
        mass = None if kind == "none" else repr(draw(st.floats(0.1, 5.0)))
        xyz, rpy = (" ".join(repr(v) for v in draw(st.lists(st.floats(-r, r), min_size=3, max_size=3)))
                    for r in (0.3, 3.0))
        joints.append(Joint(f"j{i}", jtype, Link(f"l{i}", mass=mass, com=com, inertia=values),
                            axis=" ".join(repr(float(a / np.linalg.norm(axis))) for a in axis), origin=xyz, rpy=rpy))
    return joints


def _designed_or_refused_within_budget(joints, tmp_path, monkeypatch):
    import time

    from codegen.families.design import configurations
    from codegen.families.design.reduced_order import reduced_order_gain
    path = write_chain(tmp_path / "long.urdf", joints)
    try:
        robot = load_urdf(path, snap_tol=0.0)
    except ModelError as e:
        assert any(repr(j.name) in str(e) or repr(j.child.name) in str(e) for j in joints) or "long" in str(e), str(e)
        event("refused by the loader")
        return
    monkeypatch.setattr(configurations, "DESIGN_BUDGET_S", CHAIN_BUDGET_S)
    monkeypatch.setenv("CODEGEN_CACHE", str(tmp_path / "cache"))
    t0 = time.process_time()
    try:
        k0 = reduced_order_gain(robot, samples=512, seed=robot.n).k0
    except configurations.DesignBudgetError as e:
        assert "--design k0=" in str(e) and "\n" not in str(e)
        event("refused: over budget")
    else:
        assert math.isfinite(k0) and k0 >= 0          # 0: one joint, no Coriolis term
        event(f"designed, n in {10 * (robot.n // 10)}..{10 * (robot.n // 10) + 9}")
    assert time.process_time() - t0 <= CHAIN_BUDGET_S + SLACK_S


CHAIN_SETTINGS = dict(deadline=None, derandomize=True,
                      suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@settings(max_examples=5, **CHAIN_SETTINGS)
@pytest.mark.slow
@given(joints=long_chains(1, 10))
def test_chains_up_to_10_joints_are_designed_or_refused_within_budget(joints, tmp_path, monkeypatch):
    _designed_or_refused_within_budget(joints, tmp_path, monkeypatch)


def _fifty_joints():
    """50 revolute joints, unaligned axes and placements (the explicit largest example)."""
    rng = np.random.default_rng(50)
    txt = lambda x: " ".join(repr(float(e)) for e in x)  # noqa: E731
    return [Joint(f"j{i}", "revolute", Link(f"l{i}", mass=repr(float(rng.uniform(0.5, 2))), com=txt(rng.uniform(-0.1, 0.1, 3))),
                  axis=txt(a / np.linalg.norm(a)), origin=txt(rng.uniform(-0.2, 0.2, 3)), rpy=txt(rng.uniform(-3, 3, 3)))
            for i, a in enumerate(rng.normal(size=(50, 3)))]


@settings(max_examples=3, **CHAIN_SETTINGS)
@pytest.mark.long
@given(joints=long_chains(11, 50))
@example(joints=_fifty_joints())
def test_chains_up_to_50_joints_are_designed_or_refused_within_budget(joints, tmp_path, monkeypatch):
    _designed_or_refused_within_budget(joints, tmp_path, monkeypatch)
