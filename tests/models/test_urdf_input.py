"""URDF input the parser underneath would misread: inertial values it cannot parse
(the link would be dropped silently), and locking a joint whose name is also a link's name."""
import numpy as np
import pytest

from codegen.reference.robots import UrdfRobot as ReferenceUrdf
from models.robot import ModelError
from models.urdf import load_urdf
from urdf_chain import Joint, Link, revolute_chain, write_chain

pin = pytest.importorskip("pinocchio")


def _with_fixed_tip(tip):
    """j1, j2 revolute, then the link ``tip`` attached to l1 by the fixed joint jf."""
    return revolute_chain(["j1", "j2"]) + [Joint("jf", "fixed", tip)]


def _gravity(robot, q):
    return np.array(robot.g(q)).ravel()


@pytest.mark.parametrize("tip, words", [
    (Link("tip", mass="1_5"), "mass '1_5'"),
    (Link("tip", mass="abc"), "mass 'abc'"),
    (Link("tip", mass="inf"), "mass 'inf'"),
    (Link("tip", mass="nan"), "mass 'nan'"),
    (Link("tip", mass=" 2 "), "mass ' 2 '"),
    (Link("tip", inertia={"ixx": "abc", "ixy": "0", "ixz": "0", "iyy": "1", "iyz": "0", "izz": "1"}),
     "inertia ixx 'abc'"),
    (Link("tip", inertia={"ixx": "1", "ixy": "0", "ixz": "0", "iyy": "inf", "iyz": "0", "izz": "1"}),
     "inertia iyy 'inf'"),
    (Link("tip", inertia={"ixx": "1", "ixy": "0", "ixz": "0", "iyy": "1", "izz": "1"}),
     "inertia iyz missing"),
    (Link("tip", com="0.1 0 nan"), "origin xyz '0.1 0 nan'"),
    (Link("tip", com="0.1 0"), "origin xyz '0.1 0'"),
])
def test_bad_inertial_of_a_fixed_child_is_refused_naming_the_link(tmp_path, tip, words):
    """urdfdom drops an <inertial> it cannot parse with a line on stderr (gravity torque -0.63
    instead of -8.53 N m in the issue); we refuse it, naming the link and the value."""
    path = write_chain(tmp_path / "r.urdf", _with_fixed_tip(tip))
    with pytest.raises(ModelError, match=f"link 'tip': <inertial> {words}"):
        load_urdf(path)


def test_bad_inertial_of_a_moving_link_is_refused_naming_it(tmp_path):
    joints = revolute_chain(["j1", "j2"])
    joints[1].child.mass = "1_5"
    with pytest.raises(ModelError, match="link 'l1': <inertial> mass '1_5'"):
        load_urdf(write_chain(tmp_path / "r.urdf", joints))


def test_decimal_forms_the_parser_reads_are_accepted(tmp_path):
    """+2., .5 and 1e1 parse both here and in urdfdom: the fixed child's mass is in g(q)."""
    q = np.array([0.3, 0.2])
    ref = load_urdf(write_chain(tmp_path / "a.urdf", _with_fixed_tip(Link("tip", mass="2.0"))))
    same = load_urdf(write_chain(tmp_path / "b.urdf", _with_fixed_tip(Link("tip", mass="+2."))))
    assert np.allclose(_gravity(same, q), _gravity(ref, q), rtol=1e-14)
    light = load_urdf(write_chain(tmp_path / "c.urdf", _with_fixed_tip(Link("tip", mass=".5"))))
    heavy = load_urdf(write_chain(tmp_path / "d.urdf", _with_fixed_tip(Link("tip", mass="1e1"))))
    assert abs(_gravity(heavy, q)[0]) > abs(_gravity(ref, q)[0]) > abs(_gravity(light, q)[0])


def test_total_mass_is_compared_with_the_parsed_model(tmp_path, monkeypatch):
    """The second line of defence: should a value slip past our reading of it, the total mass
    of the URDF's <inertial> elements differs from the parsed model's, and we refuse."""
    import models.urdf as urdf
    monkeypatch.setattr(urdf, "_check_inertials", lambda root, path: None)
    path = write_chain(tmp_path / "r.urdf", _with_fixed_tip(Link("tip", mass="1_5")))
    with pytest.raises(ModelError, match=r"masses total 17\.0 kg, the parsed model 2\.0 kg"):
        load_urdf(path)


# ------------------------------------------------------------------ locking by joint
@pytest.mark.parametrize("names, links, lock", [
    (["j1", "gripper", "j3"], ["l1", "gripper", "l3"], {"gripper": 0.1}),     # joint = its link
    (["gripper", "j2", "j3"], ["gripper", "l2", "l3"], {"j3": -0.2}),        # another joint
    (["j1", "j2", "gripper"], ["l1", "gripper", "tip"], {"j2": 0.3}),        # joint = other link
])
def test_locking_a_joint_named_like_a_link(tmp_path, names, links, lock):
    """"Several frames match the filter" was pinocchio looking the frame up by name: locking
    goes by joint whatever the frame names, here and in the independent reference."""
    path = write_chain(tmp_path / "arm.urdf", revolute_chain(names, links))
    robot = load_urdf(path, locked_joints=lock)
    assert robot.joint_names == [n for n in names if n not in lock]
    assert robot.link_names == [ln for n, ln in zip(names, links) if n not in lock]
    ref = ReferenceUrdf(path, locked_joints=lock)
    for q in robot.sample_configurations(5, seed=2):
        M = np.array(robot.M(q))
        assert np.linalg.norm(M - ref.M(q)) <= 1e-10 * np.linalg.norm(M)
        assert np.allclose(_gravity(robot, q), ref.g(q), rtol=1e-10, atol=1e-12)
