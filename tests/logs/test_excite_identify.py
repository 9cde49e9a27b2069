"""`excite --urdf` on a robot outside the catalog, the trajectory played on a simulated plant of
it (pinocchio's inverse dynamics of the URDF, friction, an encoder, torque noise), then `identify`
on the log: it accepts it, prints a screen and keeps the full table in its report file; a log
that does not move is refused with the `excite` line of the user's own file."""
import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

from codegen.cli import main
from codegen.core.columns import read_columns, write_columns
from codegen.reference.robots.urdf import UrdfRobot

URDF = Path(__file__).resolve().parents[1] / "data" / "damped_arm.urdf"
SCREEN = 40                     # lines a terminal shows


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


def _play(traj_csv, log_csv, scale=1.0, seed=0):
    """The log of the URDF's plant along the trajectory file (its motion x ``scale``): pinocchio's
    rnea plus viscous and Coulomb friction, positions on a 2^16 counts/rev encoder, torque noise
    of 1 % of each joint's peak."""
    import pinocchio as pin
    header, data = read_columns(traj_csv)
    n = (len(header) - 1) // 3
    t, q, qd, qdd = data[:, 0], data[:, 1:1 + n], scale * data[:, 1 + n:1 + 2 * n], scale * data[:, 1 + 2 * n:]
    q = q[0] + scale * (q - q[0])
    model = UrdfRobot(URDF, None, {}, 0.0).model
    d = model.createData()
    tau = np.array([pin.rnea(model, d, *x) for x in zip(q, qd, qdd)]) + 0.3 * qd + 0.2 * np.tanh(qd / 0.02)
    rng = np.random.default_rng(seed)
    tau += 0.01 * np.abs(tau).max(axis=0) * rng.normal(size=tau.shape)
    step = 2 * np.pi / 2 ** 16
    joints = [h.removeprefix("q_") for h in header[1:1 + n]]
    write_columns(log_csv, {"t": t, **{f"q_{j}": step * np.round(q[:, k] / step) for k, j in enumerate(joints)},
                            **{f"tau_{j}": tau[:, k] for k, j in enumerate(joints)}})


@pytest.mark.slow
def test_excite_urdf_then_identify_accepts_its_log(tmp_path):
    traj = tmp_path / "traj.csv"
    status, out, err = _run(["excite", "--urdf", str(URDF), "--T", "10", "--harmonics", "3", "--out", str(traj)])
    assert status == 0, err
    assert f"python -m codegen identify LOG.csv --urdf {URDF}" in out
    _play(traj, tmp_path / "log.csv")
    status, out, err = _run(["identify", str(tmp_path / "log.csv"), "--urdf", str(URDF), "--out",
                             str(tmp_path / "ident")])
    assert status == 0, err
    lines = out.splitlines()
    assert len(lines) <= SCREEN, out
    assert "held-out torque residual" in out and "friction (value +- std)" in out
    full = (tmp_path / "ident" / "report.txt").read_text()
    assert f"the full report (links, base combinations, every parameter): {tmp_path / 'ident' / 'report.txt'}" in out
    assert "parameters (value +- std" in full and "parameters (value +- std" not in out
    assert len(full.splitlines()) > len(lines)
    # the same robot, a log that does not move: the remedy names the user's file, not a catalog robot
    _play(traj, tmp_path / "still.csv", scale=0.0)
    status, _, err = _run(["identify", str(tmp_path / "still.csv"), "--urdf", str(URDF), "--out",
                           str(tmp_path / "still")])
    assert status == 2 and f"(python -m codegen excite --urdf {URDF} --out traj.csv)" in err, err


def test_identify_help_lists_the_robots_it_takes():
    from models.catalog import urdf_names
    from codegen.cli import parser
    text = parser()._subparsers._group_actions[0].choices["identify"].format_help()
    assert "--robot" in text and all(name in " ".join(text.split()) for name in urdf_names())
    assert "(ur5, panda)" not in text
