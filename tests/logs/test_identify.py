"""Identification against a simulated user's robot: pinocchio's inverse dynamics (rnea) of a
PERTURBED copy of the URDF (each body's mass, centre of mass and inertia x (1 +- up to 20 %), a
1 kg payload on the last body) plus viscous, Coulomb and offset friction, along the excitation
trajectory; the log a user would record: stamps jittered 0.7-1.6 ms, 1 % of the samples dropped,
an encoder of 2^16 counts/rev, torque noise of std 1 % of each joint's peak torque, no velocity."""
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from codegen.logs.recording import Recording
from codegen.logs import identify as idf
from codegen.reference.robots.urdf import UrdfRobot
from models import load_robot

DATA = Path(__file__).resolve().parents[1] / "data"
GRIPPER = DATA / "gripper_arm.urdf"
LOCK = {"finger_left": 0.01, "finger_right": 0.01}


def pin_model(robot_or_path, locked=None):
    """pinocchio's reduced model of a robot (its source) or of a URDF file."""
    if isinstance(robot_or_path, (str, Path)):
        return UrdfRobot(robot_or_path, None, locked or {}, 0.0).model
    src = robot_or_path.source
    return UrdfRobot(src["path"], src["sha256"], src["locked_joints"], src["snap_tol"]).model


def perturbed(model, rng, payload=1.0, rel=0.2):
    """A copy of ``model`` with mass, CoM and inertia about the CoM of each body times
    1 + U(-rel, rel) (one factor for the inertia: it stays physically consistent), and a
    ``payload`` kg sphere (radius 3 cm) at (5, 2, 3) cm in the last body's frame."""
    import pinocchio as pin
    m = model.copy()
    for i in range(1, m.njoints):
        Y = m.inertias[i]
        k = 1 + rng.uniform(-rel, rel, 3)
        m.inertias[i] = pin.Inertia(Y.mass * k[0], Y.lever * k[1], Y.inertia * k[2])
    last = m.njoints - 1
    m.inertias[last] = m.inertias[last] + pin.Inertia(payload, np.array([0.05, 0.02, 0.03]),
                                                      np.eye(3) * 0.4 * payload * 0.03 ** 2)
    return m


def torque(model, q, qd, qdd, friction, width):
    """Plant torque: rnea + f_v qd + f_c tanh(qd / width) + f_o."""
    import pinocchio as pin
    d = model.createData()
    fv, fc, fo = friction
    tau = np.array([pin.rnea(model, d, *x) for x in zip(q, qd, qdd)])
    return tau + fv * qd + fc * np.tanh(qd / width) + fo


def simulate(model, traj, friction, width, rng, noise=0.01, counts=2 ** 16, sigma=None):
    """(Recording, torque noise std (n,)) of the plant (Coulomb width ``width``) along ``traj``:
    the noise's std ``sigma`` (n,) N m, where NaN or not given ``noise`` x the joint's peak torque."""
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.7e-3, 1.6e-3, int(traj.T / 0.7e-3) + 2))])
    t = t[t <= traj.T]
    t = t[rng.random(len(t)) > 0.01]
    q, qd, qdd = traj.at(t)
    tau = torque(model, q, qd, qdd, friction, width)
    sigma = noise * np.abs(tau).max(axis=0) if sigma is None else \
        np.where(np.isnan(sigma), noise * np.abs(tau).max(axis=0), np.asarray(sigma, float))
    step = 2 * np.pi / counts
    rec = Recording(t=t, q=step * np.round(q / step), tau=tau + rng.normal(size=tau.shape) * sigma,
                    qd=None, joint_names=list(traj.joint_names))
    return rec, sigma


def plant_friction(robot):
    """Friction of the simulated robot from its torque scale tau_s (RMS rigid-body torque on
    random states): f_v = 0.2 tau_s / v_limit, f_c = 0.1 tau_s, f_o = +-0.05 tau_s."""
    ts = idf._Arm(robot).torque_scale
    sign = (-1.0) ** np.arange(robot.n)
    return 0.2 * ts / np.asarray(robot.v_limit), 0.1 * ts, 0.05 * ts * sign


def identified_plant(paths, locked):
    """(pin model, (f_v, f_c, f_o), w) of written files: the URDF's <inertial>s and <dynamics>,
    the side file's offsets and Coulomb width."""
    model = pin_model(paths["urdf"], locked)
    side = json.loads(Path(paths["friction"]).read_text())
    names = list(model.names)[1:]
    return model, (np.array(model.damping), np.array(model.friction),
                   np.array([side["offset"][j] for j in names])), side["coulomb_width"]


def check(robot, traj, ident, plant, friction, sigma, out, check_traj):
    """What a user of the identified model relies on (module docstring; asserts)."""
    n = robot.n
    rep = ident.report
    after = np.array([rep["residual_rms"]["after"][j] for j in robot.joint_names])
    before = np.array([rep["residual_rms"]["before"][j] for j in robot.joint_names])
    # held-out tail: within 2x the torque noise, and better than the URDF as shipped everywhere
    assert np.all(after < 2 * sigma), (after, sigma)
    assert np.all(before > after)
    # the noise estimate is the simulated one
    noise = np.array([rep["noise_std"][j] for j in robot.joint_names])
    np.testing.assert_allclose(noise, sigma, rtol=0.15)
    # friction within 10 %, and within 4 of its reported standard deviations
    f = ident.friction
    for k, true in zip(idf.FRICTION, friction):
        np.testing.assert_allclose(f[k], true, rtol=0.10, err_msg=k)
    std = ident.std[10 * n:].reshape(3, n)
    assert np.all(np.abs(np.concatenate([f[k] for k in idf.FRICTION]) - np.concatenate(friction))
                  < 4 * std.ravel())
    # the files: the identified URDF loads (ours and pinocchio), its inverse dynamics with the
    # side file's friction matches the plant's on another trajectory within 2x the noise
    _inside_bounds(ident)
    paths = ident.write(out)
    assert all(Path(p).is_file() for p in paths.values())
    locked = robot.source["locked_joints"]
    width = robot.coulomb_width
    model, fr, w = identified_plant(paths, locked)
    assert w == width
    q, qd, qdd = check_traj.at(np.linspace(0, check_traj.T, 2000))
    err = torque(model, q, qd, qdd, fr, w) - torque(plant, q, qd, qdd, friction, width)
    assert np.all(np.sqrt(np.mean(err ** 2, axis=0)) < 2 * sigma), (np.sqrt(np.mean(err ** 2, axis=0)), sigma)
    side = json.loads(Path(paths["friction"]).read_text())
    assert side["format"] == "observer-codegen friction 1" and sorted(side["offset"]) == sorted(robot.joint_names)
    # our loader reads the URDF and its side file: the identified friction, masses as written
    ours = load_robot(urdf=paths["urdf"], locked_joints=locked or None)
    assert ours.joint_names == robot.joint_names and ours.coulomb_width == w
    for k, v in zip(("viscous", "coulomb", "offset"), fr):
        np.testing.assert_allclose(getattr(ours, k), v, rtol=1e-12, err_msg=k)
    np.testing.assert_allclose(ours.masses, [model.inertias[i].mass for i in range(1, n + 1)], rtol=1e-9)
    report = json.loads(Path(paths["report_json"]).read_text())
    assert report["robot"] == robot.name and len(report["parameters"]) == 13 * n
    assert "held-out torque residual" in Path(paths["report_txt"]).read_text()
    return paths


# ------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def gripper():
    return load_robot(urdf=GRIPPER, locked_joints=LOCK)


@pytest.fixture(scope="module")
def gripper_traj(gripper):
    return idf.excitation(gripper, T=10.0, starts=1, maxiter=20)


@pytest.fixture(scope="module")
def gripper_case(gripper, gripper_traj):
    rng = np.random.default_rng(1)
    plant = perturbed(pin_model(gripper), rng)
    friction = plant_friction(gripper)
    rec, sigma = simulate(plant, gripper_traj, friction, gripper.coulomb_width, rng)
    return plant, friction, rec, sigma


# ------------------------------------------------------------------------------- units
def test_log_cholesky_round_trip_and_derivative():
    rng = np.random.default_rng(0)
    theta = rng.normal(size=(4, 10))
    pi, dpi = idf.from_log_cholesky(theta)
    h = 1e-6
    for k in range(4):
        assert np.linalg.eigvalsh(idf.pseudo_inertia(pi[k]))[0] > 0       # consistent by construction
        np.testing.assert_allclose(idf.log_cholesky(pi[k]), theta[k], atol=1e-9)
        fd = np.array([(idf.from_log_cholesky(theta[k] + h * e)[0] - idf.from_log_cholesky(theta[k] - h * e)[0])
                       / (2 * h) for e in np.eye(10)]).T
        np.testing.assert_allclose(dpi[k], fd, atol=1e-6 * np.abs(fd).max())
    # mass, CoM, inertia about it: the URDF form round-trips; a rod beyond the triangle
    # inequality (I_xx > I_yy + I_zz) is refused
    m, c, Ic = idf.inertial_to_urdf(pi[0])
    np.testing.assert_allclose(idf.urdf_to_inertial(m, c, Ic), pi[0], atol=1e-12)
    with pytest.raises(ValueError, match="not physically consistent"):
        idf.log_cholesky(idf.urdf_to_inertial(1.0, [0, 0, 0], np.diag([1.0, 0.4, 0.4])))


def test_base_parameters_of_a_known_dependency():
    rng = np.random.default_rng(0)
    W = rng.normal(size=(50, 3))
    W = np.column_stack([W, W[:, 0] - 2 * W[:, 2]])              # column 3 = col 0 - 2 col 2
    indep, dep, K = idf.base_parameters(W)
    assert len(indep) == 3 and len(dep) == 1
    x = rng.normal(size=4)
    beta = x[indep] + K @ x[dep]
    np.testing.assert_allclose(W[:, indep] @ beta, W @ x)


def test_excitation_within_limits_at_rest_and_better_conditioned(gripper, gripper_traj, tmp_path):
    tr = gripper_traj
    assert tr.f0 == pytest.approx(0.1) and tr.a.shape == (3, 5)
    t, q, qd, qdd = tr.sample(1e-3)
    lo, hi, v = gripper.q_lower, gripper.q_upper, np.asarray(gripper.v_limit)
    margin = 0.05 * (hi - lo)
    assert np.all(q >= lo + margin - 1e-3) and np.all(q <= hi - margin + 1e-3)
    assert np.all(np.abs(qd) <= 0.8 * v * (1 + 1e-3))
    assert np.all(np.abs(qdd) <= 1.6 * v * (1 + 1e-3))
    # at rest at both ends, periodic
    np.testing.assert_allclose(qd[[0, -1]], 0, atol=1e-9)
    np.testing.assert_allclose(qdd[[0, -1]], 0, atol=1e-9)
    np.testing.assert_allclose(q[-1], q[0], atol=1e-9)
    # the optimiser lowered the condition number below that of its starting coefficients
    start = idf.excitation(gripper, T=10.0, starts=1, maxiter=0)
    assert tr.condition < 0.8 * start.condition
    # the CSV a user plays
    from codegen.core.columns import read_columns
    header, data = read_columns(tr.write_csv(tmp_path / "traj.csv"))
    assert header == ["t"] + [f"{g}_{j}" for g in ("q", "qd", "qdd") for j in gripper.joint_names]
    np.testing.assert_allclose(data[:, 1:4], q)
    with pytest.raises(ValueError, match="T: 7 s is not a whole number of periods"):
        idf.excitation(gripper, T=7.0, base_frequency=0.1)


def test_identifies_the_gripper_arm(gripper, gripper_traj, gripper_case, tmp_path):
    plant, friction, rec, sigma = gripper_case
    ident = idf.identify(rec, gripper)
    check_traj = idf.excitation(gripper, T=10.0, starts=1, maxiter=0, seed=7)
    paths = check(gripper, gripper_traj, ident, plant, friction, sigma, tmp_path / "out", check_traj)
    # the default width ("auto") is the plant's, chosen among idf.WIDTHS by the held-out residual
    assert ident.report["coulomb_width"] == gripper.coulomb_width
    assert ident.report["coulomb_width_source"].startswith("selected by the held-out residual")
    # the locked gripper and everything but the identified <inertial>s and <dynamics> as they were
    old, new = ET.parse(GRIPPER).getroot(), ET.parse(paths["urdf"]).getroot()
    same = lambda e: ET.tostring(e)  # noqa: E731
    for kind, name in (("joint", "finger_left"), ("joint", "finger_right"), ("joint", "wrist_mount"),
                       ("link", "finger_l"), ("link", "finger_r"), ("link", "hand"), ("link", "base")):
        assert same(old.find(f"{kind}[@name='{name}']")) == same(new.find(f"{kind}[@name='{name}']"))
    assert len(new.findall("joint")) == len(old.findall("joint"))


def test_selects_the_plant_coulomb_width(gripper, gripper_traj, gripper_case):
    """A plant whose dry friction switches 10x faster than the model's width (0.02 rad/s against
    0.2): "auto" finds 0.02, and its friction within 10 %; the model's own width leaves a held-out
    residual above the noise and the friction further off."""
    plant, friction, _, _ = gripper_case
    rec, sigma = simulate(plant, gripper_traj, friction, 0.02, np.random.default_rng(5))
    auto = idf.identify(rec, gripper)
    fixed = idf.identify(rec, gripper, coulomb_width=gripper.coulomb_width)
    assert auto.report["coulomb_width"] == 0.02 and fixed.report["coulomb_width_source"] == "given"
    held_out = auto.report["selection"]["held_out_rms"]
    assert {k.split(", ")[1] for k in held_out} == {f"{w:g} rad/s" for w in idf.WIDTHS}
    for k, true in zip(idf.FRICTION[:2], friction[:2]):
        np.testing.assert_allclose(auto.friction[k], true, rtol=0.10, err_msg=k)

    def residual(ident):
        return np.array([ident.report["residual_rms"]["after"][j] for j in gripper.joint_names])
    assert np.all(residual(auto) <= residual(fixed) * (1 + 1e-9))
    assert np.max(residual(fixed) / sigma) > 1.2 * np.max(residual(auto) / sigma)


def test_round_trip_recovers_the_identified_urdf(gripper, gripper_traj, gripper_case, tmp_path):
    """A log of the identified URDF (its friction included) identifies to it again, from the
    original URDF as the starting point and prior."""
    _, _, rec0, _ = gripper_case
    first = idf.identify(rec0, gripper)
    paths = first.write(tmp_path / "first")
    model, friction, w = identified_plant(paths, LOCK)
    rec, _ = simulate(model, gripper_traj, friction, w, np.random.default_rng(2))
    second = idf.identify(rec, gripper)
    n = gripper.n
    f1 = np.concatenate(friction)
    f2 = np.concatenate([second.friction[k] for k in idf.FRICTION])
    np.testing.assert_allclose(f2, f1, rtol=0.10)
    assert np.all(np.abs(f2 - f1) < 4 * second.std[10 * n:])
    # every identifiable combination within 4 standard deviations
    b1 = np.array([b["value"] for b in first.report["base_parameters"]])
    b2 = np.array([b["value"] for b in second.report["base_parameters"]])
    s2 = np.array([b["std"] for b in second.report["base_parameters"]])
    assert np.all(np.abs(b2 - b1) < 4 * s2)
    # and the written links, parameter by parameter, within 5 % of their scale
    scale = np.array([p["scale"] for p in first.report["parameters"]])
    assert np.all(np.abs(second.x - first.x)[:10 * n] < 0.05 * scale[:10 * n])


def test_accepts_a_log_where_a_joint_does_not_move(gripper, gripper_traj, gripper_case, tmp_path):
    """The elbow held still: identify accepts; what only the elbow's motion tells (its friction,
    its link's own combinations) keeps the URDF's values, the rest is identified, and the URDF
    written loads as every command loads one."""
    plant, friction, _, _ = gripper_case
    still = idf.Excitation(gripper_traj.joint_names, gripper_traj.f0, gripper_traj.a.copy(),
                           gripper_traj.b.copy(), gripper_traj.q0, gripper_traj.T)
    still.a[2], still.b[2] = 0.0, 0.0                     # the elbow held at q0
    rec, sigma = simulate(plant, still, friction, gripper.coulomb_width, np.random.default_rng(3))
    ident = idf.identify(rec, gripper)
    rep = ident.report
    by = {b["combination"]: b for b in rep["base_parameters"]}
    kept = [b for b in by.values() if b["determined_by"] == "urdf"]
    fixed = [b for b in by.values() if b["determined_by"] == "log"]
    assert kept and fixed, [b["determined_by"] for b in by.values()]
    # the elbow's friction is among what the log left to the URDF, at the URDF's value
    for k in ("viscous", "coulomb"):
        b = by[f"elbow.{k}"]
        assert b["determined_by"] == "urdf" and abs(b["value"] - b["urdf"]) < 0.1 * b["prior_std"], b
    for b in kept:
        assert abs(b["value"] - b["urdf"]) < 0.5 * b["prior_std"], b
        assert math.isfinite(b["relative_std"])
    # what the moving joints tell is identified: their held-out residual within 2x the noise
    after = np.array([rep["residual_rms"]["after"][j] for j in gripper.joint_names])
    assert np.all(after[:2] < 2 * sigma[:2]), (after, sigma)
    paths = ident.write(tmp_path / "out")
    robot = load_robot(urdf=paths["urdf"], locked_joints=LOCK)
    assert robot.joint_names == gripper.joint_names
    assert "kept the URDF's values" in Path(paths["report_txt"]).read_text()


def test_refuses_only_a_log_that_does_not_move(gripper, gripper_traj, gripper_case, tmp_path, capsys):
    """No joint moves: the one refusal, its remedy as data (an excitation trajectory of this
    robot), which the CLI renders as the command to run."""
    plant, friction, _, _ = gripper_case
    still = idf.Excitation(gripper_traj.joint_names, gripper_traj.f0, 0 * gripper_traj.a,
                           0 * gripper_traj.b, gripper_traj.q0, gripper_traj.T)
    rec, _ = simulate(plant, still, friction, gripper.coulomb_width, np.random.default_rng(3))
    with pytest.raises(idf.IdentificationError) as e:
        idf.identify(rec, gripper)
    msg = str(e.value)
    assert "the log does not move" in msg and "--" not in msg and "python -m" not in msg
    assert e.value.remedy["excite"]["locked_joints"] == LOCK
    from codegen.cli import main
    rec.write_csv(tmp_path / "still.csv")
    assert main(["identify", str(tmp_path / "still.csv"), "--urdf", str(GRIPPER), "--lock", "finger_left=0.01",
                 "--lock", "finger_right=0.01", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"python -m codegen excite --urdf {GRIPPER} --lock finger_left=0.01 --lock finger_right=0.01" in err
    assert not (tmp_path / "out").exists()


def test_bad_input(gripper, gripper_case):
    _, _, rec, _ = gripper_case
    with pytest.raises(ValueError, match="test_fraction"):
        idf.identify(rec, gripper, test_fraction=1.0)
    with pytest.raises(ValueError, match="robot: identification needs a URDF robot"):
        idf.identify(rec, load_robot("seed000_2r"))
    short = Recording(t=rec.t, q=rec.q[:, :2], tau=rec.tau[:, :2], qd=None, joint_names=rec.joint_names[:2])
    with pytest.raises(ValueError, match="recording: no columns for joints elbow"):
        idf.identify(short, gripper)


def test_cli_identify(gripper_case, tmp_path, capsys):
    from codegen.cli import main
    lock = ["--lock", "finger_left=0.01", "--lock", "finger_right=0.01"]
    _, _, rec, _ = gripper_case
    rec.write_csv(tmp_path / "log.csv")                       # jittered stamps
    assert main(["identify", str(tmp_path / "log.csv"), "--urdf", str(GRIPPER), *lock,
                 "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "held-out torque residual" in out and "gripper_arm_identified.urdf" in out
    # the next step, runnable as printed: compare with the identified URDF and its residual
    assert (f"python -m codegen compare LOG.csv --urdf {tmp_path / 'out' / 'gripper_arm_identified.urdf'} "
            f"--lock finger_left=0.01 --lock finger_right=0.01 --torque-uncertainty "
            f"{tmp_path / 'out' / 'report.json'}") in out
    assert "left out of the fit where a joint sticks (|qd| <= 0.05 rad/s)" in out
    assert (tmp_path / "out" / "gripper_arm_identified.friction.json").is_file()
    listed = json.loads((tmp_path / "out" / ".codegen-outputs.json").read_text())["files"]
    assert sorted(listed) == sorted(["gripper_arm_identified.urdf", "gripper_arm_identified.friction.json",
                                     "report.json", "report.txt"])        # its own: the next run replaces them
    # a file without torques: one line, status 2
    (tmp_path / "q.csv").write_text("t,q_shoulder_yaw,q_shoulder_pitch,q_elbow\n0,0,0,0\n0.001,0,0,0\n")
    assert main(["identify", str(tmp_path / "q.csv"), "--urdf", str(GRIPPER), *lock]) == 2
    assert "missing columns tau_shoulder_yaw" in capsys.readouterr().err


@pytest.mark.slow
def test_cli_excite(tmp_path, capsys):
    from codegen.cli import main
    from codegen.core.columns import read_columns
    assert main(["excite", "--urdf", str(GRIPPER), "--lock", "finger_left=0.01", "--lock", "finger_right=0.01",
                 "--T", "5", "--harmonics", "2", "--out", str(tmp_path / "traj.csv")]) == 0
    header, data = read_columns(tmp_path / "traj.csv")
    assert header[:4] == ["t", "q_shoulder_yaw", "q_shoulder_pitch", "q_elbow"] and len(header) == 10
    assert data[-1, 0] == pytest.approx(5.0) and np.all(data[[0, -1], 4:] == pytest.approx(0.0, abs=1e-9))
    assert "f0 = 0.2 Hz" in capsys.readouterr().out


@pytest.mark.slow
def test_friction_of_a_joint_that_moves_almost_no_inertia(tmp_path):
    """A wrist roll whose slim link hardly loads it (rigid-body torque scale ~1e-4 N m) but whose
    friction is 0.3 N m, its sensor's noise 0.05 N m (0.5 % of the effort limit), as on kinova's last
    joint: its friction within 10 % (the prior, in units of that joint's rigid-body torque, held
    its Coulomb friction near 0) and the held-out residual within 2x the noise."""
    from urdf_chain import Joint, Link, write_chain
    slim = {"ixx": "6e-5", "ixy": "0", "ixz": "0", "iyy": "4e-4", "iyz": "0", "izz": "4e-4"}
    path = write_chain(tmp_path / "roll_arm.urdf", [
        Joint("shoulder", "revolute", Link("arm"), origin="0 0 0.1"),
        Joint("elbow", "revolute", Link("forearm")),
        Joint("roll", "revolute", Link("hand", mass="0.3", com="0.04 0 0", inertia=slim), axis="1 0 0",
              origin="0.25 0 0")], robot="roll_arm")
    path.write_text(path.read_text().replace('lower="-1" upper="1"', 'lower="-2.5" upper="2.5"'))
    robot = load_robot(urdf=path)
    arm = idf._Arm(robot)
    assert arm.torque_scale[2] < 1e-3 * arm.torque_scale.max()
    traj = idf.excitation(robot, T=10.0, starts=1, maxiter=20)
    rng = np.random.default_rng(3)
    plant = perturbed(pin_model(robot), rng, payload=0.0)
    fv, fc, fo = plant_friction(robot)
    fv[2], fc[2], fo[2] = 0.2, 0.3, 0.05
    rec, sigma = simulate(plant, traj, (fv, fc, fo), robot.coulomb_width, rng, sigma=[np.nan, np.nan, 0.05])
    ident = idf.identify(rec, robot)
    for k, true in zip(("viscous", "coulomb"), (fv, fc)):
        np.testing.assert_allclose(ident.friction[k], true, rtol=0.10, err_msg=k)
    after = np.array([ident.report["residual_rms"]["after"][j] for j in robot.joint_names])
    assert np.all(after < 2 * sigma), after


def test_identifies_ur5(tmp_path):
    robot = load_robot("ur5")
    traj = idf.excitation(robot, T=10.0, starts=1, maxiter=30)
    rng = np.random.default_rng(4)
    plant = perturbed(pin_model(robot), rng)
    friction = plant_friction(robot)
    rec, sigma = simulate(plant, traj, friction, robot.coulomb_width, rng)
    ident = idf.identify(rec, robot)
    check(robot, traj, ident, plant, friction, sigma, tmp_path / "out",
          idf.excitation(robot, T=10.0, starts=1, maxiter=0, seed=7))
    assert math.isfinite(ident.report["condition_number"])


def _inside_bounds(ident):
    """Every primary link of the identification within its bounds (mass, centre of mass, second
    moments), the written inertia positive definite within the triangle inequalities."""
    from codegen.logs.identify.parametrisation import inside
    arm = ident.arm
    for i, b in enumerate(arm.bounds):
        pi = ident.x[10 * i:10 * i + 10] - arm.attached[10 * i:10 * i + 10]
        assert inside(pi, b), (arm.links[i], idf.inertial_to_urdf(pi), b)
        _, _, Ic = idf.inertial_to_urdf(pi)
        lam = np.linalg.eigvalsh(Ic)
        assert lam[0] > 0 and lam[0] + lam[1] > lam[2], (arm.links[i], lam)


def test_a_urdf_that_is_not_physical_is_projected_first(tmp_path):
    """A forearm whose inertia breaks the triangle inequality (I_xx > I_yy + I_zz): the prior is
    its projection into the physical bounds, the report says so, and the identified model, fitted
    on a log of the physical arm, is physical and loads."""
    from urdf_chain import Joint, Link, write_chain
    bad = {"ixx": "0.05", "ixy": "0", "ixz": "0", "iyy": "0.01", "iyz": "0", "izz": "0.01"}
    good = dict(bad, ixx="0.015")

    def arm(path, forearm):
        p = write_chain(path, [
            Joint("shoulder", "revolute", Link("upper", mass="2.0", com="0.15 0 0"), origin="0 0 0.1", axis="0 0 1"),
            Joint("elbow", "revolute", Link("forearm", mass="1.0", com="0.12 0 0", inertia=forearm)),
            Joint("wrist", "revolute", Link("hand", mass="0.5", com="0.05 0 0"), axis="1 0 0")], robot="bad_arm")
        p.write_text(p.read_text().replace('lower="-1" upper="1"', 'lower="-2.5" upper="2.5"'))
        return p
    robot = load_robot(urdf=arm(tmp_path / "bad_arm.urdf", bad))
    (tmp_path / "plant").mkdir()
    plant = pin_model(arm(tmp_path / "plant" / "bad_arm.urdf", good))
    traj = idf.excitation(robot, T=10.0, starts=1, maxiter=20)
    rng = np.random.default_rng(6)
    friction = plant_friction(robot)
    rec, sigma = simulate(plant, traj, friction, robot.coulomb_width, rng)
    ident = idf.identify(rec, robot)
    assert list(ident.report["prior"]["projected"]) == ["forearm"]
    assert "the URDF is not physical" in ident.text and "forearm: principal second moments" in ident.text
    _inside_bounds(ident)
    after = np.array([ident.report["residual_rms"]["after"][j] for j in robot.joint_names])
    assert np.all(after < 2 * sigma), (after, sigma)
    paths = ident.write(tmp_path / "out")
    loaded = load_robot(urdf=paths["urdf"])
    np.testing.assert_allclose(loaded.masses, [ident.x[10 * i] for i in range(3)], rtol=1e-9)


def test_the_margin_holds_where_the_log_pulls_past_it(gripper, gripper_traj, tmp_path):
    """A plant whose elbow body weighs 2 % of the URDF's (less than what the URDF attaches to it:
    the forearm's own mass would be negative, outside every physical bound): every link stays
    within its bounds, the fit still beats the URDF on the held-out tail, and the URDF written
    loads."""
    import pinocchio as pin
    plant = pin_model(gripper)
    Y = plant.inertias[3]
    plant.inertias[3] = pin.Inertia(0.02 * Y.mass, Y.lever, 0.02 * Y.inertia)
    rec, _ = simulate(plant, gripper_traj, plant_friction(gripper), gripper.coulomb_width, np.random.default_rng(8))
    ident = idf.identify(rec, gripper)
    _inside_bounds(ident)
    r = ident.report["residual_rms"]
    assert all(r["after"][j] < r["before"][j] for j in gripper.joint_names), r
    paths = ident.write(tmp_path / "out")
    assert load_robot(urdf=paths["urdf"], locked_joints=LOCK).joint_names == gripper.joint_names


def test_write_refuses_a_urdf_that_would_not_load(gripper, gripper_case, tmp_path):
    """The written URDF is loaded back as every command loads one before it is kept: a model whose
    link has an inertia below the loaders' snapping (1e-12 kg m^2: zero after snapping) is not
    written, and nothing is left behind."""
    _, _, rec, _ = gripper_case
    ident = idf.identify(rec, gripper)
    arm = ident.arm
    pi = idf.urdf_to_inertial(0.5, [0.1, 0, 0], np.diag([1e-12, 1e-12, 1e-12]))
    ident.x = ident.x.copy()
    ident.x[10:20] = arm.attached[10:20] + pi
    with pytest.raises(RuntimeError, match="does not load"):
        ident.write(tmp_path / "out")
    assert list((tmp_path / "out").iterdir()) == []


def test_a_torque_column_that_is_not_measured(gripper, gripper_case):
    """Some real logs carry a joint's torque as zeros: that joint's rows are left out (its torque
    is not known) and the report names it; what only it tells keeps the URDF's values. A log with no
    torque at all is refused in one line."""
    from dataclasses import replace
    _, _, rec, _ = gripper_case
    tau = rec.tau.copy()
    tau[:, 2] = 0.0
    ident = idf.identify(replace(rec, tau=tau), gripper)
    assert ident.report["log"]["torque_not_measured"] == ["elbow"]
    assert "torque not measured" in ident.text
    by = {b["combination"]: b for b in ident.report["base_parameters"]}
    assert by["elbow.viscous"]["determined_by"] == "urdf"
    with pytest.raises(ValueError, match="every torque column is constant"):
        idf.identify(replace(rec, tau=0 * tau), gripper)
