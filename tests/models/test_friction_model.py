"""Joint friction of the robot model: tau_f(v) = viscous v + coulomb tanh(v / w) + offset.

Numbers against the equation written here in numpy and pinocchio's rnea/aba; the URDF's
<dynamics damping friction> (tests/data/friction_arm.urdf, example-robot-data's xarm7) and the
side file <stem>.friction.json; the source and fingerprint; and a robot without Coulomb friction
and offset keeps exactly the viscous model's expressions.
"""
import json
import pathlib
import shutil

import casadi as ca
import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from models import ModelError, from_source, load_robot  # noqa: E402
from models.algebra import dot, split, sub  # noqa: E402
from models.aba import aba  # noqa: E402
from models.catalog import load_elastic  # noqa: E402
from models.robot import DEFAULT_COULOMB_WIDTH  # noqa: E402
from models.urdf import FRICTION_FORMAT, example_robot_data_dir, friction_file_path, load_urdf  # noqa: E402

DATA = pathlib.Path(__file__).parents[1] / "data"
ARM = DATA / "friction_arm.urdf"
RNG = np.random.default_rng(20240611)


def _rel(a, b):
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


def _tau_f(v, viscous, coulomb, offset, width):
    """The friction equation, numpy."""
    return viscous * v + coulomb * np.tanh(v / width) + offset


def _pin_model(path):
    return pin.buildModelFromUrdf(str(path))


# ---------------------------------------------------------------- numbers
def test_friction_torque_is_the_equation():
    """tau_f (the Function and friction_torque on SX) against the equation, at speeds across the
    smooth sign (|v| from 0 to 50 w), for a closed-form robot given friction by with_friction."""
    r = load_robot("seed000_2r").with_friction(coulomb=[1.2, 0.7], offset=[0.3, -0.05], width=0.05)
    v_sym = ca.SX.sym("v", 2)
    f_sym = ca.Function("f", [v_sym], [r.friction_torque(v_sym)])
    for v in np.r_[RNG.normal(scale=0.05, size=(20, 2)), RNG.uniform(-2.5, 2.5, size=(20, 2)), [[0.0, 0.0]]]:
        want = _tau_f(v, np.array([0.1, 0.3]), np.array([1.2, 0.7]), np.array([0.3, -0.05]), 0.05)
        assert _rel(r.tau_f(v), want) < 1e-15
        assert _rel(f_sym(v), want) < 1e-15
    assert np.array_equal(r.F, np.diag([0.1, 0.3]))          # F stays the viscous matrix
    assert np.array_equal(r.viscous, [0.1, 0.3]) and r.coulomb_width == 0.05


def test_urdf_forward_dynamics_equals_pinocchio_aba_with_friction():
    """fd(q, v, tau) = pin.aba(q, v, tau - tau_f(v)) and the inverse: fd(q, v, rnea(q, v, a) +
    tau_f(v)) = a, on tests/data/friction_arm.urdf with its side file (Coulomb, damping, offsets,
    w = 0.1), tau_f from pinocchio's model.damping, model.friction and the file."""
    r = load_robot(urdf=ARM)
    m = _pin_model(ARM)
    d = m.createData()
    side = json.loads(friction_file_path(ARM).read_text())
    offset = np.array([side["offset"].get(j, 0.0) for j in list(m.names)[1:]])
    for q, v, tau, a in zip(r.sample_configurations(40, seed=3), RNG.normal(scale=0.3, size=(40, 3)),
                            RNG.normal(scale=5.0, size=(40, 3)), RNG.normal(size=(40, 3))):
        tf = _tau_f(v, m.damping, m.friction, offset, side["coulomb_width"])
        assert _rel(r.fd(q, v, tau), pin.aba(m, d, q, v, tau - tf)) < 1e-10
        assert _rel(r.fd(q, v, pin.rnea(m, d, q, v, a) + tf), a) < 1e-9
        assert _rel(r.tau_f(v), tf) < 1e-15


def test_base_class_forward_dynamics_uses_the_friction():
    """The closed-form (base-class) forward dynamics: M qdd = tau - C v - g - tau_f(v)."""
    r = load_robot("seed002_2r").with_friction(viscous=0.2, coulomb=[0.4, 0.3], offset=[0.1, 0.2])
    for q, v, tau in zip(RNG.uniform(-3, 3, (20, 2)), RNG.normal(size=(20, 2)), RNG.normal(size=(20, 2))):
        M, C, g = np.array(r.M(q)), np.array(r.C(q, v)), np.array(r.g(q)).ravel()
        tf = _tau_f(v, 0.2, np.array([0.4, 0.3]), np.array([0.1, 0.2]), DEFAULT_COULOMB_WIDTH)
        assert _rel(r.fd(q, v, tau), np.linalg.solve(M, tau - C @ v - g - tf)) < 1e-12


def test_demo_trajectory_torque_includes_the_friction():
    """The built-in trajectory's tau is the inverse dynamics with friction: tau - tau_f(qd) =
    pinocchio's rnea(q, qd, qdd), with qdd = -w^2 (q - centre) of its sines (centre 0 here: the
    arm's ranges are symmetric; w = 2 (1 + 0.25 k / (n - 1)) rad/s on joint k)."""
    from codegen.verify.trajectory import demo_trajectory
    r = load_robot(urdf=ARM)
    m = _pin_model(ARM)
    d = m.createData()
    t, Q, QD, TAU = demo_trajectory(r, T=1.0, dt=1e-3)
    w = 2.0 * (1.0 + 0.25 * np.arange(3) / 2)
    tf = np.array(r.tau_f.map(len(QD))(QD.T)).T
    for k in range(0, len(t), 37):
        assert _rel(TAU[k] - tf[k], pin.rnea(m, d, Q[k], QD[k], -w ** 2 * Q[k])) < 1e-12
    assert np.abs(tf).max() > 0.5          # the friction is a real part of tau here


# ---------------------------------------------------------------- the URDF and its side file
def test_urdf_dynamics_friction_is_read():
    """<dynamics damping friction> -> viscous, coulomb (as pinocchio reads them); the side file's
    offsets and width; without the side file no offset and the default width."""
    m = _pin_model(ARM)
    r = load_robot(urdf=ARM)
    assert np.array_equal(r.viscous, m.damping) and np.array_equal(r.coulomb, m.friction)
    assert np.array_equal(r.coulomb, [1.5, 1.0, 0.5]) and np.array_equal(r.viscous, [0.4, 0.3, 0.0])
    assert np.array_equal(r.offset, [0.25, 0.0, -0.12]) and r.coulomb_width == 0.1
    bare = load_urdf(ARM, friction_file=None)
    assert np.array_equal(bare.coulomb, [1.5, 1.0, 0.5]) and not bare.offset.any()
    assert bare.coulomb_width == DEFAULT_COULOMB_WIDTH


def test_xarm7_friction_from_example_robot_data():
    """xarm7 (damping 10/5/2, friction 1 on every joint): pinocchio's model.damping/friction."""
    path = example_robot_data_dir() / "xarm_description/urdf/xarm7.urdf"
    if not path.is_file():
        pytest.skip("example-robot-data has no xarm7")
    m = _pin_model(path)
    r = load_robot(urdf=path)
    assert np.array_equal(r.viscous, m.damping) and np.array_equal(r.coulomb, m.friction)
    assert np.array_equal(r.viscous, [10, 10, 5, 5, 5, 2, 2]) and np.array_equal(r.coulomb, [1] * 7)
    assert r.source["friction"] == {"coulomb_width": DEFAULT_COULOMB_WIDTH}
    v = RNG.normal(scale=0.3, size=7)
    assert _rel(r.tau_f(v), _tau_f(v, m.damping, m.friction, 0.0, DEFAULT_COULOMB_WIDTH)) < 1e-15


def test_locked_joint_keeps_the_others_friction_and_ignores_its_offset(tmp_path):
    """Locking j2: the reduced robot has j1, j3's damping and friction; the side file's offset of
    a locked joint is ignored (the lock holds it)."""
    urdf = _copy_arm(tmp_path, {"offset": {"j1": 0.25, "j2": 9.0, "j3": -0.12}})
    r = load_robot(urdf=urdf, locked_joints={"j2": 0.3})
    assert r.joint_names == ["j1", "j3"]
    assert np.array_equal(r.coulomb, [1.5, 0.5]) and np.array_equal(r.viscous, [0.4, 0.0])
    assert np.array_equal(r.offset, [0.25, -0.12])


def _copy_arm(tmp_path, side=None, text=None, name="arm_identified"):
    """friction_arm.urdf as tmp_path/<name>.urdf, with the side file ``side`` (a dict, JSON) or
    ``text`` (raw) beside it."""
    urdf = tmp_path / f"{name}.urdf"
    shutil.copy(ARM, urdf)
    if side is not None or text is not None:
        (tmp_path / f"{name}.friction.json").write_text(text if text is not None else json.dumps(side))
    return urdf


def test_side_file_is_found_by_stem(tmp_path):
    """arm_identified.urdf -> arm_identified.friction.json, read automatically; every key optional;
    friction_file=None skips it and a path reads another file."""
    assert friction_file_path(tmp_path / "arm_identified.urdf") == tmp_path / "arm_identified.friction.json"
    urdf = _copy_arm(tmp_path, {"format": FRICTION_FORMAT, "coulomb_width": 0.03, "offset": {"j2": 0.5}})
    r = load_robot(urdf=urdf)
    assert np.array_equal(r.offset, [0.0, 0.5, 0.0]) and r.coulomb_width == 0.03
    assert r.source["friction"] == {"offset": [0.0, 0.5, 0.0], "coulomb_width": 0.03}
    assert not load_urdf(urdf, friction_file=None).offset.any()
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"offset": {"j1": -1.0}}))
    r2 = load_urdf(urdf, friction_file=other)
    assert np.array_equal(r2.offset, [-1.0, 0.0, 0.0]) and r2.coulomb_width == DEFAULT_COULOMB_WIDTH
    for side in ({}, {"format": FRICTION_FORMAT}, {"coulomb_width": 0.2}, {"offset": {}}):
        r3 = load_robot(urdf=_copy_arm(tmp_path, side, name="partial"))
        assert not r3.offset.any()
    with pytest.raises(FileNotFoundError, match="friction file not found"):
        load_urdf(urdf, friction_file=tmp_path / "missing.json")


@pytest.mark.parametrize("text,match", [
    ('{"offset": {"j9": 0.1}}', "offset names joint 'j9', which is not a moving joint"),
    ('{"offsets": {"j1": 0.1}}', "unknown key 'offsets'"),
    ('{"format": "observer-codegen friction 2"}', "format 'observer-codegen friction 2' is not"),
    ('{"coulomb_width": 0}', "coulomb_width must be > 0"),
    ('{"coulomb_width": -0.1}', "coulomb_width must be > 0"),
    ('{"coulomb_width": "0.1"}', "coulomb_width must be a finite number"),
    ('{"coulomb_width": true}', "coulomb_width must be a finite number"),
    ('{"coulomb_width": NaN}', "coulomb_width must be a finite number"),
    ('{"offset": {"j1": Infinity}}', r"offset\['j1'\] must be a finite number"),
    ('{"offset": {"j1": [0.1]}}', r"offset\['j1'\] must be a finite number"),
    ('{"offset": [0.1, 0.2, 0.3]}', "offset must be an object joint name"),
    ('[0.1, 0.2]', "a friction file is a JSON object"),
    ('{"offset": {"j1": 0.1}', "not a readable friction file"),
])
def test_bad_side_files_are_refused(tmp_path, text, match):
    """A side file we cannot use raises one ModelError (a ValueError) naming the file and what."""
    urdf = _copy_arm(tmp_path, text=text)
    with pytest.raises(ModelError, match=match) as e:
        load_robot(urdf=urdf)
    assert "arm_identified.friction.json" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("old,new", [('friction="1.0"', 'friction="-1.0"'),
                                     ('damping="0.3"', 'damping="-0.3"')])
def test_negative_urdf_friction_is_refused(tmp_path, old, new):
    """A negative <dynamics> damping or friction is refused naming the joint."""
    urdf = tmp_path / "neg.urdf"
    urdf.write_text(ARM.read_text().replace(old, new))
    with pytest.raises(ModelError, match=r"joint 'j2': <dynamics> \w+ '-\S+' is negative"):
        load_robot(urdf=urdf)


# ---------------------------------------------------------------- with_friction, source, fingerprint
def test_with_friction_returns_a_new_robot_and_checks_its_arguments():
    r = load_robot("seed000_2r")
    r2 = r.with_friction(coulomb=1.0, offset=[0.1, -0.2], width=0.05)
    assert r2 is not r and type(r2) is type(r)
    assert not r.coulomb.any() and not r.offset.any() and r.coulomb_width == DEFAULT_COULOMB_WIDTH
    assert np.array_equal(r2.coulomb, [1.0, 1.0]) and np.array_equal(r2.viscous, r.viscous)
    assert _rel(r.fd([0.1, 0.2], [0.3, 0.4], [1, 2]), r2.fd([0.1, 0.2], [0.3, 0.4], [1, 2])) > 1e-3
    for kwargs, match in [({"coulomb": -1.0}, "coulomb must be >= 0"),
                          ({"viscous": [0.1, -0.1]}, "viscous must be >= 0"),
                          ({"offset": [0.1, 0.2, 0.3]}, "offset must be a number or 2 numbers"),
                          ({"coulomb": [1.0, np.nan]}, "coulomb must be finite"),
                          ({"coulomb": "1"}, "coulomb must be a number or 2 numbers"),
                          ({"coulomb": [1.0, "a"]}, "coulomb must be a number or 2 numbers"),
                          ({"offset": [[1.0], [1.0, 2.0]]}, "offset must be a number or 2 numbers"),
                          ({"viscous": 1j}, "viscous must be a number or 2 numbers"),
                          ({"width": 0.0}, "Coulomb width"), ({"width": np.inf}, "Coulomb width"),
                          ({"width": True}, "Coulomb width")]:
        with pytest.raises(ModelError, match=match):
            r.with_friction(**kwargs)
    with pytest.raises(ModelError, match="F must be diagonal"):
        r.F = np.array([[0.1, 0.01], [0.0, 0.3]])


def test_source_and_fingerprint_carry_the_friction():
    """Each friction value changes the fingerprint; the width matters only with Coulomb friction;
    no entry (source and fingerprint unchanged) without Coulomb friction and offset; from_source
    rebuilds the same robot (source and dynamics)."""
    r = load_robot("seed000_2r")
    seen = {r.fingerprint}
    variants = [r.with_friction(coulomb=1.0), r.with_friction(coulomb=1.0, width=0.05),
                r.with_friction(offset=[0.0, 0.1]), r.with_friction(viscous=[0.1, 0.4]),
                r.with_friction(coulomb=[0.0, 1.0])]
    for v in variants:
        assert v.fingerprint not in seen
        seen.add(v.fingerprint)
        rebuilt = from_source(v.source)
        assert rebuilt.source == v.source and rebuilt.fingerprint == v.fingerprint
        q, qd, tau = [0.3, -0.2], [0.05, -0.4], [1.0, 2.0]
        assert _rel(rebuilt.fd(q, qd, tau), v.fd(q, qd, tau)) < 1e-15
    assert variants[0].source["friction"] == {"coulomb": [1.0, 1.0], "coulomb_width": DEFAULT_COULOMB_WIDTH}
    assert variants[3].source["friction"] == {"viscous": [0.1, 0.4]}
    same = r.with_friction(width=0.05, viscous=[0.1, 0.3], offset=0.0)
    assert same.source == r.source and "friction" not in r.source and same.fingerprint == r.fingerprint


def test_urdf_source_round_trip_does_not_reread_the_side_file(tmp_path):
    """The source holds the side file's values: from_source gives them back even after the file
    changed or went away."""
    urdf = _copy_arm(tmp_path, {"coulomb_width": 0.08, "offset": {"j1": 0.3}})
    r = load_robot(urdf=urdf)
    src = r.source
    assert src["friction"] == {"offset": [0.3, 0.0, 0.0], "coulomb_width": 0.08}
    friction_file_path(urdf).write_text(json.dumps({"offset": {"j1": -5.0}}))
    again = from_source(src)
    assert again.source == src and np.array_equal(again.offset, [0.3, 0.0, 0.0])
    friction_file_path(urdf).unlink()
    assert from_source(src).fingerprint == r.fingerprint
    assert load_robot(urdf=urdf).fingerprint != r.fingerprint


def test_targets_file_urdf_source_reads_the_side_file(tmp_path):
    """A targets file's portable URDF source (no sha256) reads the side file when the robot is
    built; the robot's own (recorded) source then holds the values."""
    from codegen.pipeline.targets_file import robot_source
    urdf = _copy_arm(tmp_path, {"coulomb_width": 0.08, "offset": {"j3": 0.4}})
    portable = robot_source(urdf=str(urdf))
    assert "sha256" not in portable and "friction" not in portable
    r = from_source(portable)
    assert np.array_equal(r.offset, [0.0, 0.0, 0.4]) and r.coulomb_width == 0.08
    assert r.source["friction"] == {"offset": [0.0, 0.0, 0.4], "coulomb_width": 0.08}
    elastic = from_source(robot_source(urdf=str(urdf), elastic=True, J=0.5, K=200.0))
    assert np.array_equal(elastic.rigid.offset, [0.0, 0.0, 0.4])


def test_elastic_robot_carries_the_rigid_friction():
    e = load_elastic("seed004_2r")
    e2 = e.with_friction(coulomb=[0.5, 0.2], offset=[0.1, 0.0], width=0.1)
    assert e2.rigid.source["friction"]["coulomb"] == [0.5, 0.2]
    assert e2.source["rigid"] == e2.rigid.source and e2.fingerprint != e.fingerprint
    assert from_source(e2.source).source == e2.source
    x = e.sample_states(1, seed=2)[0]
    x1, x2, x3 = x[:2], x[2:4], x[4:6]
    rigid = e2.rigid
    want = np.linalg.solve(np.array(rigid.M(x1)), -e.K @ (x1 - x3) - np.array(rigid.C(x1, x2)) @ x2
                           - np.array(rigid.g(x1)).ravel() - np.array(rigid.tau_f(x2)).ravel())
    assert _rel(np.array(e2.f(x)).ravel()[2:4], want) < 1e-12


# ---------------------------------------------------------------- no friction: today's expressions
def _viscous_fd(robot):
    """The forward dynamics Function built as before friction had Coulomb and offset terms."""
    q, v, tau = ca.SX.sym("q", robot.n), ca.SX.sym("v", robot.n), ca.SX.sym("tau", robot.n)
    if hasattr(robot, "tree"):
        F = np.asarray(robot.F, dtype=float)
        vs, ts = split(v, robot.n, "v"), split(tau, robot.n, "tau")
        qdd = aba(robot.tree, q, vs, [sub(ts[i], dot(tuple(float(x) for x in F[i]), vs))
                                      for i in range(robot.n)])
    else:
        qdd = ca.solve(robot.mass_matrix(q), tau - robot.nle(q, v) - ca.mtimes(ca.DM(robot.F), v))
    return ca.Function("fd", [q, v, tau], [qdd], ["q", "v", "tau"], ["qdd"])


@pytest.mark.parametrize("name", ["seed000_2r", "seed002_2r", "ur5", "panda"])
def test_without_coulomb_and_offset_the_expressions_are_the_viscous_ones(name):
    """Same serialized forward dynamics as the viscous model (so the C of today's targets does not
    change), also after with_friction changed only the width; tau_f is mtimes(F, v)."""
    r = load_robot(name)
    for robot in (r, r.with_friction(width=0.05)):
        assert robot.fd.serialize() == _viscous_fd(robot).serialize()
        v = ca.SX.sym("v", robot.n)
        assert ca.Function("f", [v], [robot.friction_torque(v)]).serialize() == \
            ca.Function("f", [v], [ca.mtimes(ca.DM(robot.F), v)]).serialize()
    with_c = r.with_friction(coulomb=0.5)
    assert with_c.fd.serialize() != _viscous_fd(with_c).serialize()
