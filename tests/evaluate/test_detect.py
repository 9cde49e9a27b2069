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
