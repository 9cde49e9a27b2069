"""The commands that read a log as a measurement: `describe` (its clock, noise, band, torque),
`design LOG --family F` (gains tuned on it), `compare` (the clock's line first, estimates.csv at
the log's rows) and a targets file's ``tune = "log.csv"``, on a receive-time log of seed000_2r."""
import contextlib
import io
import json

import numpy as np
import pytest

from codegen.cli import main
from codegen.core.columns import read_columns, write_columns
from codegen.verify.trajectory import demo_trajectory
from models import load_robot
from receive_log import receive_time

ROBOT = "seed000_2r"


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    """(path, rows' true ticks, repeated rows, true qd of each row): 6 s of seed000_2r's demo
    motion, its model's torques, positions to 1e-6 rad, stamps 0.4 ms behind a 1 ms tick."""
    robot = load_robot(ROBOT)
    t, Q, QD, TAU = demo_trajectory(robot, T=6.0, dt=1e-3, seed=2)
    stamps, source, repeated = receive_time(len(t), seed=4)
    cols = {"t": stamps, **{f"q_{j}": np.round(Q[source, i] / 1e-6) * 1e-6 for i, j in enumerate(robot.joint_names)},
            **{f"tau_{j}": TAU[source, i] for i, j in enumerate(robot.joint_names)}}
    path = write_columns(tmp_path_factory.mktemp("log") / "log.csv", cols)
    return path, source, repeated, QD[source]


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


def test_describe_says_what_the_log_is(log, tmp_path):
    path, _, repeated, _ = log
    status, out, err = _run(["describe", str(path), "--robot", ROBOT, "--json", str(tmp_path / "d.json")])
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("clock: receive-time stamps") and f"{repeated.sum()} repeated rows" in lines[0]
    assert "position resolution per joint: 1e-06, 1e-06 rad" in out and "torque vs the model" in out
    data = json.loads((tmp_path / "d.json").read_text())
    assert data["clock"]["kind"] == "ticks" and data["noise"]["resolution"] == pytest.approx([1e-6, 1e-6])
    status, out, _ = _run(["describe", str(path)])               # joints from the header, no torque
    assert status == 0 and "joints: q1, q2" in out and "torque vs the model" not in out


@pytest.mark.slow
def test_design_tunes_a_family_on_the_log(log, tmp_path):
    path, _, _, _ = log
    status, out, err = _run(["design", str(path), "--robot", ROBOT, "--family", "reduced_order",
                             "--json", str(tmp_path / "design.json")])
    assert status == 0, err
    data = json.loads((tmp_path / "design.json").read_text())
    k0 = data["tuned"]["params"]["k0"]
    assert data["params"]["k0"] == pytest.approx(k0) and data["tuned"]["rms_estimate"] > 0
    assert f"reduced_order: k0 = {k0:.4g}" in out and "forward-validation error" in out
    assert "build it: python -m codegen build seed000_2r --family reduced_order" in out
    assert f"--param k0={k0:.6g}" in out and "--design quantization=1e-06" in out


@pytest.mark.slow
def test_compare_writes_the_estimates_at_the_logs_rows(log, tmp_path):
    """compare's first line is the clock's; estimates.csv has the log's t and one column per method
    and joint at every row of the file (a repeated row: the estimate of the row it repeats); the
    tuned observer's error against the kept truth is its forward validation's estimate within
    50 %."""
    path, source, repeated, qd = log
    status, out, err = _run(["compare", str(path), "--robot", ROBOT, "--observers", "reduced_order",
                             "--baselines", "kalman", "--out", str(tmp_path)])
    assert status == 0, err
    assert out.splitlines()[1].startswith("clock: receive-time stamps")
    header, data = read_columns(tmp_path / "estimates.csv")
    t, _ = read_columns(path)[1][:, 0], None
    assert header == ["t", "reduced_order.qd_q1", "reduced_order.qd_q2", "kalman.qd_q1", "kalman.qd_q2"]
    assert np.array_equal(data[:, 0], read_columns(path)[1][:, 0])
    k = np.flatnonzero(repeated)
    assert np.array_equal(data[k, 1:], data[k - 1, 1:])
    row = {r["name"]: r for r in json.loads((tmp_path / "compare.json").read_text())["rows"]}["reduced_order"]
    w = data[:, 0] >= json.loads((tmp_path / "compare.json").read_text())["t_ss"]
    true = np.sqrt(np.mean(np.sum((data[:, 1:3] - qd)[w & ~repeated] ** 2, axis=1)))
    assert row["validation_rms"] == pytest.approx(true, rel=0.5)


@pytest.mark.slow
def test_a_targets_file_tunes_on_its_log(log, tmp_path):
    path, _, _, _ = log
    (tmp_path / "targets.toml").write_text(f'[[target]]\nrobot = "{ROBOT}"\nfamily = "reduced_order"\n'
                                           f'tune = "{path}"\n')
    status, out, err = _run(["build", "-c", str(tmp_path / "targets.toml"), "--out", str(tmp_path / "gen")])
    assert status == 0, err
    assert "seed000_2r_reduced_order: tuned on log.csv: k0 = " in err
    meta = json.loads(next((tmp_path / "gen").rglob("seed000_2r_reduced_order.json")).read_text())
    k0 = float(err.split("k0 = ")[1].split()[0].rstrip(";"))
    assert meta["p_default"][0] == pytest.approx(k0, rel=1e-3)
    assert meta["target"]["build"]["quantization"] == pytest.approx(1e-6)
    (tmp_path / "bad.toml").write_text(f'[[target]]\nrobot = "{ROBOT}"\ntune = "nothere.csv"\n')
    status, _, err = _run(["build", "-c", str(tmp_path / "bad.toml")])
    assert status == 2 and "tune: log not found" in err
