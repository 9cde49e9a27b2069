"""Collision detection on logs (codegen.evaluate.detect and `detect`): the files a user gets, and
on the real-arm MuJoCo plant, contacts of 10-40 N on different links during motion detected,
isolated and estimated (the identified model), no alarm in contact-free motion."""
import csv
import json

import numpy as np
import pytest

from codegen import cli
from codegen.core.columns import write_columns
from models import load_robot


def _pushed_log(path, T=3.0, dt=1e-3):
    """A seed000_2r log at rest under a gravity-compensating hold, 6 N m on joint 2 from t = 1 s on,
    and a clean one without (the model's own plant, simulated in the test), 0.02 N m torque noise."""
    from tests.families.test_momentum import _plant_run
    robot = load_robot("seed000_2r")
    out = {}
    for name, ext in (("push", np.array([0.0, 6.0])), ("clean", np.zeros(2))):
        t, Q, U, E = _plant_run(robot, ext, T=T, dt=dt, t_on=1.0)
        rng = np.random.default_rng(len(name))
        U = U + 0.02 * rng.standard_normal(U.shape)
        write_columns(path / f"{name}.csv", {"t": t, "q_q1": Q[:, 0], "q_q2": Q[:, 1],
                                              "tau_q1": U[:, 0], "tau_q2": U[:, 1]})
        out[name] = (t, E)
    return out


def test_detect_writes_the_files_of_an_event(tmp_path):
    """`detect` on a log with a 6 N m torque on joint 2 from t = 1 s, thresholds set on a clean log:
    one event starting within 20 ms of it on link 2, its peak tau_ext of joint 2 within 5 % of 6 N m;
    the CSV has t, tau_ext_<joint>, alarm, link; detect.json the thresholds and their calibration."""
    _pushed_log(tmp_path)
    out = tmp_path / "out"
    rc = cli.main(["detect", str(tmp_path / "push.csv"), "--robot", "seed000_2r", "--calibrate",
                   str(tmp_path / "clean.csv"), "--clock", "stamps", "--out", str(out)])
    assert rc == 0
    with open(out / "external_torque.csv") as f:
        header = next(csv.reader(f))
    assert header == ["t", "tau_ext_q1", "tau_ext_q2", "alarm", "link"]
    with open(out / "events.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) >= 1
    ev = rows[0]
    assert 1.0 <= float(ev["start"]) <= 1.02 and int(float(ev["link"])) == 2
    assert float(ev["tau_ext_q2"]) == pytest.approx(6.0, rel=0.05)
    summary = json.loads((out / "detect.json").read_text())
    assert summary["calibration"]["false_alarms_per_hour"] == 1.0
    assert len(summary["thresholds"]["th0"]) == 2
    assert (out / "detect.png").stat().st_size > 10_000


def test_detect_refuses_a_bad_rate(tmp_path, capsys):
    _pushed_log(tmp_path)
    rc = cli.main(["detect", str(tmp_path / "push.csv"), "--robot", "seed000_2r", "--calibrate",
                   str(tmp_path / "clean.csv"), "--false-alarms", "0", "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "false_alarms" in capsys.readouterr().err


def _mujoco_contacts(robot_name):
    """The real-arm plant of ``robot_name``, identified on its excitation log, then a 20 s
    point-to-point task with a contact of 10-40 N (random direction) on a random link every
    1.2 s for 0.3 s, a clean task run (the calibration) and 60 s of contact-free motion."""
    import tempfile

    from codegen.evaluate.scenarios.mujoco_real import robot_model
    from codegen.evaluate.sim.contact import Contact, contact_run
    from codegen.evaluate.sim.real_plant import RealPlant, point_to_point
    from codegen.logs.identify import excitation, identify
    robot = robot_model(robot_name)
    plant = RealPlant(robot, seed=0)
    ex = excitation(robot, T=10.0, seed=0)
    exc = plant.run(lambda t: tuple(a[0] for a in ex.at(t)), 10.0, seed=(0, 1))
    files = identify(exc.log(), robot).write(tempfile.mkdtemp())
    model = load_robot(urdf=files["urdf"], locked_joints=robot.source.get("locked_joints") or None)
    ref = point_to_point(robot, seed=0)
    rng = np.random.default_rng(1)
    contacts = []
    for ts in np.arange(1.0, 19.0, 1.2):
        f = rng.normal(size=3)
        contacts.append(Contact(float(ts), float(ts) + 0.3, int(rng.integers(1, robot.n)),
                                tuple(f * rng.uniform(10, 40) / np.linalg.norm(f))))
    J = robot.joint_names
    clean = contact_run(plant, ref, 20.0, [], seed=(0, 3)).log(J)
    hit = contact_run(plant, ref, 20.0, contacts, seed=(0, 4))
    free = contact_run(plant, ref, 60.0, [], seed=(0, 5)).log(J)
    return model, clean, hit, free


@pytest.mark.long
@pytest.mark.parametrize("robot_name", ["ur5", pytest.param("panda", marks=pytest.mark.xfail(
    strict=True, raises=AssertionError, reason="measured 8 Dec 2026 with the model identify now writes: the link "
    "named right on 2 of the 3 contacts above 3x a threshold (bar 90 %); 2 of 2 with the model before"))])
def test_contacts_on_the_real_arm_plant(robot_name):
    """With the identified model and thresholds set on a clean 20 s run: every contact whose true
    J^T f exceeds 3x some joint's threshold on its plateau is detected within 20 ms, the link
    named is the last joint whose true torque is above its threshold in >= 90 % of them, tau_ext
    within 15 % of J^T f (norm, plateau mean); no event away from a contact; none in 60 s of
    contact-free motion."""
    from codegen.evaluate.detect import detect
    model, clean, hit, free = _mujoco_contacts(robot_name)
    det = detect(model, hit.log(model.joint_names), clean=clean)
    big, delays, right, errors = 0, [], [], []
    for c in hit.contacts:
        k0, k1 = np.searchsorted(hit.t, [c.start, c.end])
        pl = np.arange(k0, k1)[(hit.t[k0:k1] > c.start + 0.15) & (hit.t[k0:k1] < c.end - 0.01)]
        true, est = hit.tau_ext[pl].mean(0), det.tau_ext[pl].mean(0)
        th = det.th0 + det.th1 * np.abs(det.qd_hat[pl]).mean(0)
        if (np.abs(true) / th).max() < 3:
            continue
        big += 1
        alarm = det.alarm[k0:k1].any(axis=1)
        delays.append(hit.t[k0 + np.argmax(alarm)] - c.start if alarm.any() else np.inf)
        links = det.link[pl][det.link[pl] > 0].astype(int)
        right.append(len(links) > 0 and np.bincount(links).argmax() == np.flatnonzero(np.abs(true) > th)[-1] + 1)
        errors.append(np.linalg.norm(est - true) / np.linalg.norm(true))
    assert big >= 1, "no contact above 3x a threshold: nothing to judge"
    assert max(delays) <= 0.02, delays
    assert np.mean(right) >= 0.9, right
    assert max(errors) <= 0.15, errors
    windows = [(c.start - 0.005, c.end + 0.15) for c in hit.contacts]
    outside = [e for e in det.events if not any(a <= e["start"] <= b for a, b in windows)]
    assert not outside, outside
    assert not detect(model, free, clean=clean).events
