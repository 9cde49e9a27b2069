"""models.urdf and the spatial algorithms it runs (models.rnea, crba, aba, kinematics) against
pinocchio's own; URDF fixtures in tests/data/.

Tolerances: 1e-10 relative to the norm of pinocchio's value (pinocchio run on the SNAPPED
model, the one our algorithms read), as docs/architecture.md §4 states.
"""
import hashlib
import json
import math
import pathlib
import xml.etree.ElementTree as ET

import casadi as ca
import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from models.algebra import dot, mul, split  # noqa: E402
from models.rnea import rnea  # noqa: E402
from models.robot import ModelError, RobotModel  # noqa: E402
from models.urdf import UrdfRobot, example_robot_data_dir, load_urdf  # noqa: E402

TOL = 1e-10
N_SAMPLES = 200
PANDA_LOCKED = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
DATA = pathlib.Path(__file__).parents[1] / "data"


def _rel(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.size == b.size, (a.shape, b.shape)
    a = a.reshape(b.shape)
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


@pytest.fixture(scope="module")
def erd():
    return example_robot_data_dir()


@pytest.fixture(scope="module")
def ur5(erd):
    return load_urdf(erd / "ur_description/urdf/ur5_robot.urdf")


@pytest.fixture(scope="module")
def panda(erd):
    return load_urdf(erd / "panda_description/urdf/panda.urdf", locked_joints=PANDA_LOCKED)


# ------------------------------------------------------------------ test robots (tests/data)
def _two_link(tmp_path, j2_type="revolute", axis="0 1 0", mimic=None, mass2=1.0, ixx2=0.01):
    """tests/data/two_link.urdf with joint j2 (type, axis, mimic) and link l2 (mass, ixx)
    edited, written to tmp_path."""
    root = ET.parse(DATA / "two_link.urdf").getroot()
    j2 = root.find("joint[@name='j2']")
    j2.set("type", j2_type)
    j2.find("axis").set("xyz", axis)
    if mimic is not None:
        ET.SubElement(j2, "mimic", joint=mimic)
    inertial = root.find("link[@name='l2']/inertial")
    inertial.find("mass").set("value", str(mass2))
    inertial.find("inertia").set("ixx", str(ixx2))
    path = tmp_path / "two_link.urdf"
    ET.ElementTree(root).write(path)
    return path


@pytest.fixture(scope="module")
def cpr():
    return load_urdf(DATA / "cpr.urdf")


# ------------------------------------------------------------------ helpers
def _pin_terms(robot, q, v, tau):
    m = robot.pin_model
    d = m.createData()
    qp = robot.pin_configuration(q)
    M = pin.crba(m, d, qp)
    return dict(
        M=np.triu(M) + np.triu(M, 1).T,
        nle=pin.nonLinearEffects(m, d, qp, v).copy(),
        g=pin.computeGeneralizedGravity(m, d, qp).copy(),
        C=np.array(pin.computeCoriolisMatrix(m, d, qp, v)),
        aba=pin.aba(m, d, qp, v, tau - robot.F @ v).copy(),
    )


def _compare_with_pinocchio(robot, count, seed):
    """Worst relative error of each term over `count` random samples."""
    rng = np.random.default_rng(seed)
    Q = robot.sample_configurations(count, seed=seed)
    V = rng.normal(scale=2.0, size=(count, robot.n))
    T = rng.normal(scale=20.0, size=(count, robot.n))
    fM, fC, fg, ffd = robot.M, robot.C, robot.g, robot.fd      # built once
    worst = dict(M=0.0, nle=0.0, g=0.0, Cv=0.0, C=0.0, aba=0.0)
    for q, v, tau in zip(Q, V, T):
        ref = _pin_terms(robot, q, v, tau)
        Cq = np.array(fC(q, v))
        gq = np.array(fg(q)).ravel()
        err = dict(M=_rel(fM(q), ref["M"]), g=_rel(gq, ref["g"]),
                   nle=_rel(Cq @ v + gq, ref["nle"]), Cv=_rel(Cq @ v, ref["C"] @ v),
                   C=_rel(Cq, ref["C"]), aba=_rel(np.array(ffd(q, v, tau)).ravel(), ref["aba"]))
        worst = {k: max(worst[k], err[k]) for k in worst}
    return worst


# ------------------------------------------------------------------ against pinocchio
@pytest.mark.parametrize("name", ["ur5", "panda", "cpr"])
def test_dynamics_match_pinocchio(name, request):
    robot = request.getfixturevalue(name)
    worst = _compare_with_pinocchio(robot, N_SAMPLES, seed=7)
    assert max(worst.values()) <= TOL, worst


@pytest.mark.parametrize("name", ["ur5", "panda", "cpr"])
def test_rnea_and_com_match_pinocchio(name, request):
    """rnea(q, v, a) vs pin.rnea; CoM positions and their Jacobian vs pinocchio kinematics."""
    robot = request.getfixturevalue(name)
    m = robot.pin_model
    d = m.createData()
    q_s, v_s, a_s = (ca.SX.sym(s, robot.n) for s in "qva")
    frnea = ca.Function("rnea", [q_s, v_s, a_s], [robot.rnea(q_s, v_s, a_s)])
    rng = np.random.default_rng(3)
    for q in robot.sample_configurations(30, seed=3):
        v, a = rng.normal(size=robot.n), rng.normal(size=robot.n)
        qp = robot.pin_configuration(q)
        assert _rel(frnea(q, v, a), pin.rnea(m, d, qp, v, a)) <= TOL
        pin.computeJointJacobians(m, d, qp)          # also runs forward kinematics
        com, J = [], []
        for i in range(1, m.njoints):
            c_w = d.oMi[i].act(m.inertias[i].lever)
            Ji = pin.getJointJacobian(m, d, i, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            # point velocity: v_origin + w x (c_w - p_i)
            r = c_w - d.oMi[i].translation
            J.append(Ji[:3] - np.cross(r, Ji[3:].T).T)
            com.append(c_w)
        com, J = np.concatenate(com), np.vstack(J)
        assert _rel(robot.com(q), com) <= TOL
        Jc = np.array(robot.Jcom(q))
        # joint columns of pin's Jacobian are ordered by idx_v = our order
        assert np.linalg.norm(Jc - J) <= TOL * np.linalg.norm(J)


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_christoffel_properties(name, request):
    """Mdot = C + C^T and C(q, a) b = C(q, b) a (docs/papers/seed000.md §0) on random samples."""
    robot = request.getfixturevalue(name)
    q, v = ca.SX.sym("q", robot.n), ca.SX.sym("v", robot.n)
    Mdot = ca.Function("Mdot", [q, v], [ca.jtimes(robot.mass_matrix(q), q, v)])
    fC = robot.C
    rng = np.random.default_rng(11)
    for qi in robot.sample_configurations(50, seed=11):
        a, b = rng.normal(size=robot.n), rng.normal(size=robot.n)
        Ca = np.array(fC(qi, a))
        assert _rel(Ca + Ca.T, Mdot(qi, a)) <= TOL
        assert _rel(np.array(fC(qi, a)) @ b, np.array(fC(qi, b)) @ a) <= TOL


def test_nle_gravity_forward_dynamics_symbolic(panda):
    """The overridden blocks are the recursive ones and agree with M, C, g."""
    q, v, tau = (ca.SX.sym(s, panda.n) for s in ("q", "v", "tau"))
    f = ca.Function("f", [q, v, tau], [panda.nle(q, v), panda.gravity(q),
                                       panda.forward_dynamics(q, v, tau), panda.aba(q, v, tau)])
    rng = np.random.default_rng(5)
    for qi in panda.sample_configurations(20, seed=5):
        vi, ti = rng.normal(size=panda.n), rng.normal(size=panda.n)
        nle, g, fd, a = (np.array(x).ravel() for x in f(qi, vi, ti))
        M, C = np.array(panda.M(qi)), np.array(panda.C(qi, vi))
        assert _rel(nle, C @ vi + g) <= TOL
        assert _rel(fd, np.linalg.solve(M, ti - C @ vi - g - panda.F @ vi)) <= 1e-9
        assert _rel(a, np.linalg.solve(M, ti - C @ vi - g)) <= 1e-9
    # numeric and MX arguments go through cached SX Functions
    qi = panda.sample_configurations(1, seed=1)[0]
    assert _rel(panda.crba(ca.DM(qi)), panda.M(qi)) == 0.0
    qm = ca.MX.sym("q", panda.n)
    assert ca.Function("gm", [qm], [panda.gravity(qm)])(qi).shape == (panda.n, 1)


def test_rnea_without_gravity(cpr):
    """rnea(..., gravity=False) = M a + C v; with v = a = None it is exactly zero (folded)."""
    q, v, a = (ca.SX.sym(s, cpr.n) for s in "qva")
    assert rnea(cpr.tree, q, None, None, gravity=False).is_zero()
    f = ca.Function("f", [q, v, a], [rnea(cpr.tree, q, v, a, gravity=False)])
    rng = np.random.default_rng(6)
    for qi in cpr.sample_configurations(10, seed=6):
        vi, ai = rng.normal(size=(2, cpr.n))
        assert _rel(f(qi, vi, ai), np.array(cpr.M(qi)) @ ai + np.array(cpr.C(qi, vi)) @ vi) <= TOL


def test_folding_scalars():
    """Exact zeros and unit factors never reach CasADi (what keeps the generated ABA small);
    bad argument sizes name the argument."""
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    assert mul(0.0, x) == 0.0 and isinstance(mul(x, 0.0), float)
    assert ca.is_equal(mul(1.0, x), x) and ca.is_equal(mul(x, -1.0), -x, 1)
    assert ca.is_equal(dot((0.0, -1.0, 2.0), (y, x, y)), -x + 2.0 * y, 2)
    assert split(None, 3, "v") == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="tau: expected shape \\(2, 1\\)"):
        split(ca.SX.sym("t", 3), 2, "tau")
    with pytest.raises(ValueError, match="q: expected 2 entries"):
        split([x], 2, "q")


# ------------------------------------------------------------------ snapping
def test_snapping_ur5(ur5):
    raw, snapped = ur5.pin_model_raw, ur5.pin_model
    i = raw.getJointId("shoulder_lift_joint")
    assert abs(raw.jointPlacements[i].rotation[0, 0]) == pytest.approx(4.89664e-12, rel=1e-3)
    assert snapped.jointPlacements[i].rotation[0, 0] == 0.0
    assert raw.jointPlacements[i].rotation[0, 0] != 0.0      # the raw model is untouched


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_snapping_effect_bounded(name, request):
    """Entries move by < snap_tol = 1e-9 on O(0.1..1) data, so M moves by ~1e-9 relative:
    bounded by 1e-8 here (pinocchio on the raw and the snapped model)."""
    robot = request.getfixturevalue(name)
    raw, snapped = robot.pin_model_raw, robot.pin_model
    dr, ds = raw.createData(), snapped.createData()
    worst = 0.0
    for q in robot.sample_configurations(100, seed=2):
        qp = robot.pin_configuration(q)
        Mr, Ms = pin.crba(raw, dr, qp), pin.crba(snapped, ds, qp)
        Mr, Ms = np.triu(Mr) + np.triu(Mr, 1).T, np.triu(Ms) + np.triu(Ms, 1).T
        worst = max(worst, _rel(Ms, Mr))
    assert worst <= 1e-8


def test_snapping_unaligned_axis(tmp_path):
    """A joint axis within snap_tol of a coordinate axis is snapped (and pin_model agrees)."""
    robot = load_urdf(_two_link(tmp_path, axis="1e-12 1 -2e-12"))
    raw_j = robot.pin_model_raw.joints[2]
    assert raw_j.shortname() == "JointModelRevoluteUnaligned"
    assert list(robot.pin_model.joints[2].extract().axis) == [0.0, 1.0, 0.0]
    assert _compare_with_pinocchio(robot, 20, seed=1)["aba"] <= TOL


# ------------------------------------------------------------------ the 3-link robot
def test_custom_robot_attributes(cpr):
    assert cpr.n == 3 and cpr.dim == 3
    assert cpr.joint_names == ["j_cont", "j_pris", "j_rev"]
    kinds = [cpr.pin_model.joints[i].shortname() for i in (1, 2, 3)]
    assert kinds == ["JointModelRevoluteUnboundedUnaligned", "JointModelPrismaticUnaligned",
                     "JointModelRevoluteUnaligned"]
    np.testing.assert_array_equal(np.diag(cpr.F), [0.2, 1.5, 0.0])
    np.testing.assert_array_equal(cpr.q_lower, [-math.pi, -0.2, -2.0])
    np.testing.assert_array_equal(cpr.q_upper, [math.pi, 0.3, 2.0])
    np.testing.assert_allclose(cpr.masses, [2.0, 1.2, 1.1])       # tool merged into l3
    qp = cpr.pin_configuration([0.7, 0.1, -0.3])
    np.testing.assert_allclose(qp, [math.cos(0.7), math.sin(0.7), 0.1, -0.3])
    with pytest.raises(ValueError, match="3 entries"):
        cpr.pin_configuration([0.0, 0.0])


def test_generation_is_lean(panda):
    """The generated ABA stays small (constants folded: ~1.8k SX instructions for 7 DoF); the
    time to build it is a benchmark, not asserted here."""
    robot = load_urdf(panda.source["path"], locked_joints=PANDA_LOCKED)   # builds M (check)
    fM, ffd = robot.M, robot.fd
    assert fM.n_instructions() < 1000 and ffd.n_instructions() < 2500


def test_branching_tree():
    """Two branches off l1 (revolute, continuous about -z; prismatic): M has zeros
    between branches and every term matches pinocchio."""
    robot = load_urdf(DATA / "tree.urdf")
    assert robot.joint_names == ["j1", "j2a", "j3", "j2b"]
    assert max(_compare_with_pinocchio(robot, 50, seed=9).values()) <= TOL
    Mq = np.array(robot.M(robot.sample_configurations(1)[0]))
    assert Mq[1, 3] == 0.0 and Mq[2, 3] == 0.0


def test_locked_continuous_joint():
    """Locking a continuous joint uses (cos, sin) of the value in the reference q."""
    path = DATA / "cpr.urdf"
    robot = load_urdf(path, locked_joints={"j_cont": 0.7})
    assert robot.joint_names == ["j_pris", "j_rev"]
    full = load_urdf(path)
    rng = np.random.default_rng(8)
    for q in robot.sample_configurations(10, seed=8):
        v = rng.normal(size=2)
        qf, vf = np.r_[0.7, q], np.r_[0.0, v]
        assert _rel(robot.M(q), np.array(full.M(qf))[1:, 1:]) <= TOL
        assert _rel(robot.g(q), np.array(full.g(qf))[1:]) <= TOL
        assert _rel(np.array(robot.C(q, v)) @ v, (np.array(full.C(qf, vf)) @ vf)[1:]) <= TOL


# ------------------------------------------------------------------ attributes, source
def test_ur5_panda_attributes(ur5, panda, erd):
    assert ur5.name == "ur5_robot" and ur5.n == 6 and panda.n == 7
    assert panda.joint_names == [f"panda_joint{k}" for k in range(1, 8)]
    np.testing.assert_array_equal(np.diag(panda.F), [0.003] * 7)
    assert np.all(ur5.masses > 0) and ur5.masses.shape == (6,)
    np.testing.assert_allclose(ur5.q_upper, [2 * math.pi] * 2 + [math.pi] + [2 * math.pi] * 3,
                               rtol=1e-12)
    np.testing.assert_array_equal(ur5.q_lower, -ur5.q_upper)
    np.testing.assert_array_equal(panda.v_limit, [2.175] * 4 + [2.61] * 3)
    src = panda.source
    assert json.loads(json.dumps(src)) == src
    assert src["kind"] == "urdf" and pathlib.Path(src["path"]).is_absolute()
    assert src["locked_joints"] == PANDA_LOCKED and src["snap_tol"] == 1e-9
    assert src["sha256"] == hashlib.sha256(pathlib.Path(src["path"]).read_bytes()).hexdigest()
    assert (erd / "ur_description").is_dir()
    assert load_urdf(src["path"], PANDA_LOCKED, name="panda").name == "panda"


# ------------------------------------------------------------------ errors
def test_missing_file(tmp_path):
    missing = tmp_path / "nope" / "robot.urdf"
    with pytest.raises(FileNotFoundError, match="nope/robot.urdf"):
        load_urdf(missing)


@pytest.mark.parametrize("jtype, words", [
    ("floating", "unsupported type 'floating'"),
    ("planar", "unsupported type 'planar'"),
    ("spherical", "unknown type 'spherical'"),
    ("banana", "unknown type 'banana'"),
])
def test_unsupported_urdf_joint_types(tmp_path, jtype, words):
    with pytest.raises(ModelError, match=f"joint 'j2' has {words}"):
        load_urdf(_two_link(tmp_path, j2_type=jtype))


def test_mimic_joint(tmp_path):
    path = _two_link(tmp_path, mimic="j1")
    with pytest.raises(ModelError, match="joint 'j2' is a mimic joint"):
        load_urdf(path)
    robot = load_urdf(path, locked_joints={"j2": 0.25})        # a locked mimic joint is fine
    assert robot.n == 1 and robot.source["locked_joints"] == {"j2": 0.25}


def test_unknown_locked_joint(tmp_path):
    with pytest.raises(ModelError, match="locked joint 'j9'"):
        load_urdf(_two_link(tmp_path), locked_joints={"j9": 0.0})


@pytest.mark.parametrize("joint", [pin.JointModelFreeFlyer(), pin.JointModelSpherical(),
                                   pin.JointModelPlanar(), pin.JointModelTranslation()])
def test_unsupported_pin_joint_types(joint):
    m = pin.Model()
    jid = m.addJoint(0, joint, pin.SE3.Identity(), "odd_joint")
    m.appendBodyToJoint(jid, pin.Inertia.Random(), pin.SE3.Identity())
    msg = f"joint 'odd_joint' has unsupported type {joint.shortname()}"
    with pytest.raises(ModelError, match=msg):
        UrdfRobot(m, name="odd")


def test_floating_base_root_joint(erd):
    m = pin.buildModelFromUrdf(str(erd / "ur_description/urdf/ur5_robot.urdf"),
                               pin.JointModelFreeFlyer())
    with pytest.raises(ModelError, match="JointModelFreeFlyer"):
        UrdfRobot(m, name="ur5_floating")


def test_zero_mass_link(tmp_path):
    with pytest.raises(ModelError, match="link 'l2' \\(moved by joint 'j2'\\) has mass 0.0"):
        load_urdf(_two_link(tmp_path, mass2=0.0))


def test_negative_mass_link(tmp_path):
    with pytest.raises(ModelError, match="link 'l2' has negative mass"):
        load_urdf(_two_link(tmp_path, mass2=-1.0))


@pytest.mark.parametrize("ixx", [-0.01, 0.0])
def test_inertia_not_positive_definite(tmp_path, ixx):
    with pytest.raises(ModelError, match="link 'l2' .*not positive definite"):
        load_urdf(_two_link(tmp_path, ixx2=ixx))


def test_inertia_snapped_to_singular(tmp_path):
    with pytest.raises(ModelError, match="link 'l2' .*after snapping"):
        load_urdf(_two_link(tmp_path, ixx2=1e-10))
    assert load_urdf(_two_link(tmp_path, ixx2=1e-10), snap_tol=1e-12).n == 2


def test_singular_mass_matrix():
    """Masses and inertias all fine, but a negative armature cancels the joint's inertia:
    M(q) = 0 and check_mass_matrix (run by the constructor) raises."""
    m = pin.Model()
    jid = m.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "j1")
    m.appendBodyToJoint(jid, pin.Inertia(1.0, np.zeros(3), np.diag([0.1, 0.1, 0.1])),
                        pin.SE3.Identity())
    m.armature[:] = -0.1
    with pytest.raises(ModelError, match="robot 'armless': M\\(q\\) is singular"):
        UrdfRobot(m, name="armless")


def test_check_mass_matrix_subclass():
    class Singular(RobotModel):
        name, n, q_lower, q_upper = "sing", 2, np.zeros(2), np.ones(2)

        def mass_matrix(self, q):
            return ca.vertcat(ca.horzcat(1.0, 1.0), ca.horzcat(1.0, 1.0)) * (1 + q[0] ** 2)

    with pytest.raises(ModelError, match="robot 'sing': M\\(q\\) is singular"):
        Singular().check_mass_matrix(count=3)


def test_armature_matches_pinocchio(erd):
    """pinocchio adds the armature to M's diagonal, to rnea and to aba; so do we."""
    m = pin.buildModelFromUrdf(str(erd / "ur_description/urdf/ur5_robot.urdf"))
    m.armature[:] = [0.5, 0.4, 0.3, 0.1, 0.1, 0.05]
    robot = UrdfRobot(m, name="ur5_armature")
    assert max(_compare_with_pinocchio(robot, 20, seed=4).values()) <= TOL
