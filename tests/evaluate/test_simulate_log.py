"""`simulate-log`: a realistic synthetic log of a URDF outside the catalog (its truth beside it),
read back as a log."""
import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the mujoco extra is not installed")

from codegen.cli import main                                   # noqa: E402
from codegen.core.columns import read_columns                  # noqa: E402
from codegen.logs.recording import read_log                    # noqa: E402
from models import load_robot                                  # noqa: E402

URDF = Path(__file__).resolve().parents[1] / "data" / "damped_arm.urdf"


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


@pytest.mark.parametrize("clock", ("receive", "jitter"))
def test_simulate_log_writes_a_log_of_ones_urdf_and_its_truth(tmp_path, clock):
    """The log reads as a log of the robot (its clock rebuilt on the 1 ms tick for receive times);
    each row's position is its truth's to the encoder and the logger's rounding (2^20 counts/rev,
    1e-6 rad: 6e-6 + 5e-7 rad); the command refuses a robot it cannot simulate."""
    out = tmp_path / "sub" / "log.csv"
    status, printed, err = _run(["simulate-log", "--urdf", str(URDF), "--out", str(out), "--seconds", "2",
                                 "--clock", clock])
    assert status == 0, err
    assert f"wrote {out}: " in printed and "log_truth.csv" in printed
    robot = load_robot(urdf=URDF)
    header, log = read_columns(out)
    th, truth = read_columns(out.with_name("log_truth.csv"))
    assert header == ["t"] + [f"{g}_{j}" for g in ("q", "tau") for j in robot.joint_names]
    assert len(log) == len(truth) and np.array_equal(log[:, 0], truth[:, th.index("t")])
    q = log[:, 1:1 + robot.n]
    q_true = truth[:, [th.index(f"q_{j}") for j in robot.joint_names]]
    assert np.max(np.abs(q - q_true)) <= 2 * np.pi / 2 ** 20 + 5e-7 + 1e-12
    rec, c = read_log(out, robot.joint_names, robot=robot)
    assert c.kind == ("ticks" if clock == "receive" else "stamps")
    assert rec.t[-1] - rec.t[0] == pytest.approx(2.0, abs=5e-3)
    status, _, err = _run(["simulate-log", "--robot", "seed000_2r", "--out", str(tmp_path / "x.csv")])
    assert status == 2 and "the real plant needs a URDF robot" in err
