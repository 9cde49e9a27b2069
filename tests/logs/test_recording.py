"""The recorded run (codegen.logs.recording): a real log's stamps (jitter, dropped samples) read
and written exactly, the optional true velocity and robot's velocity columns, and the stamps it
refuses (repeated, going back), named by their rows in the file."""
import re

import numpy as np
import pytest

from codegen.logs.recording import Recording, RecordingError, read_csv

JOINTS = ["shoulder", "elbow"]


def _log(N=400, seed=0, qd=True, qdm=True):
    """Stamps 1 ms +- 0.3 ms, every 10th step doubled (a dropped sample)."""
    rng = np.random.default_rng(seed)
    steps = 1e-3 + rng.uniform(-3e-4, 3e-4, N - 1)
    steps[::10] += 1e-3
    t = 12.5 + np.concatenate([[0.0], np.cumsum(steps)])          # a log need not start at 0
    q = np.column_stack([np.sin(t), np.cos(2 * t)])
    v = np.column_stack([np.cos(t), -2 * np.sin(2 * t)])
    return Recording(t=t, q=q, tau=3 * q, qd=v if qd else None, joint_names=list(JOINTS),
                     qdm=v + 1e-3 if qdm else None), steps


@pytest.mark.parametrize("qd, qdm", [(True, True), (False, True), (True, False), (False, False)])
def test_jittered_csv_round_trip(tmp_path, qd, qdm):
    rec, _ = _log(qd=qd, qdm=qdm)
    path = rec.write_csv(tmp_path / "log.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert header[:5] == ["t", "q_shoulder", "q_elbow", "tau_shoulder", "tau_elbow"]
    assert ("qd_elbow" in header) == qd and ("qdm_elbow" in header) == qdm
    back = read_csv(path, JOINTS)
    for name in ("t", "q", "tau", "qd", "qdm"):
        a, b = getattr(rec, name), getattr(back, name)
        assert (a is None and b is None) or np.array_equal(a, b), name


def test_the_stamps_a_user_wants_to_know():
    rec, steps = _log()
    assert rec.dt == pytest.approx(np.median(steps), rel=1e-11)
    assert (rec.dt_min, rec.dt_max) == pytest.approx((steps.min(), steps.max()), rel=1e-9)
    assert rec.gaps == len(steps[::10]) and not rec.uniform           # steps of 1.7..2.3 ms
    line = rec.describe()
    assert f"{len(rec.t)} samples" in line and f"{rec.gaps} gaps > 1.5 median" in line
    assert f"max {1e3 * steps.max():.4g} ms" in line


def test_a_uniform_log_has_the_decimal_step():
    """Differences of float stamps k * 1e-3 scatter by ulps; the median step is rounded to 12
    digits, so the observers are discretised at exactly 1e-3 s."""
    t = np.arange(20001) * 1e-3
    assert np.median(np.diff(t)) != 1e-3
    rec = Recording(t=t, q=np.zeros((len(t), 1)), tau=np.zeros((len(t), 1)), qd=None, joint_names=["j"])
    assert rec.dt == 1e-3 and rec.uniform and rec.gaps == 0


def _rewrite(path, out, row, value):
    """``path`` with the time stamp of file row ``row`` (the header is row 1) set to ``value``."""
    lines = path.read_text().splitlines()
    cells = lines[row - 1].split(",")
    cells[0] = repr(float(value))
    lines[row - 1] = ",".join(cells)
    out.write_text("\n".join(lines) + "\n")
    return out


def test_stamps_that_repeat_or_go_back_are_refused_by_row(tmp_path):
    rec, _ = _log()
    path = rec.write_csv(tmp_path / "log.csv")
    # sample k is file row k + 2
    with pytest.raises(RecordingError, match=r"time stamp repeats between rows 20 and 21: t = "):
        read_csv(_rewrite(path, tmp_path / "dup.csv", 21, rec.t[18]), JOINTS)
    with pytest.raises(RecordingError, match=r"time stamp goes back between rows 30 and 31"):
        read_csv(_rewrite(path, tmp_path / "back.csv", 31, rec.t[28] - 1e-4), JOINTS)
    with pytest.raises(RecordingError, match=r"NaN or Inf in column 't', row 7"):
        read_csv(_rewrite(path, tmp_path / "nan.csv", 7, float("nan")), JOINTS)


def test_partial_velocity_columns_are_refused(tmp_path):
    rec, _ = _log()
    path = rec.write_csv(tmp_path / "log.csv")
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    keep = [i for i, h in enumerate(header) if h != "qdm_elbow"]
    (tmp_path / "part.csv").write_text("\n".join(",".join(line.split(",")[i] for i in keep)
                                                 for line in lines) + "\n")
    with pytest.raises(RecordingError, match=r"has qdm_shoulder but not qdm_elbow \(qdm_<joint> for every joint"):
        read_csv(tmp_path / "part.csv", JOINTS)


def test_recording_checks_its_arrays():
    rec, _ = _log()
    with pytest.raises(ValueError, match=r"t: time stamps must increase; t\[5\] = "):
        Recording(t=np.r_[rec.t[:5], rec.t[3:]], q=np.zeros((len(rec.t) + 2, 2)),
                  tau=np.zeros((len(rec.t) + 2, 2)), qd=None, joint_names=JOINTS)
    with pytest.raises(ValueError, match=r"qdm: expected shape \(400, 2\)"):
        Recording(t=rec.t, q=rec.q, tau=rec.tau, qd=None, joint_names=JOINTS, qdm=rec.q[:, :1])
    with pytest.raises(ValueError, match="t: NaN or Inf at index 3"):
        Recording(t=np.r_[0.0, 1, 2, np.inf], q=np.zeros((4, 2)), tau=np.zeros((4, 2)), qd=None,
                  joint_names=JOINTS)


# ------------------------------------------------------------------ issue 34, R1 and R4: hostile logs
def _ur5_log(tmp_path, N=300):
    """A short ur5 log (a slow sine about mid-range, gravity-sized torques) as a CSV: (path,
    Recording, robot)."""
    from models import load_robot
    robot = load_robot("ur5")
    t = np.arange(N) * 1e-3
    q = 0.5 * (robot.q_lower + robot.q_upper) + 0.3 * np.sin(np.outer(t, np.arange(1, robot.n + 1)))
    rec = Recording(t=t, q=q, tau=np.tile([5.0, -40.0, 10.0, 1.0, 0.5, 0.1], (N, 1)), qd=None,
                    joint_names=list(robot.joint_names))
    return rec.write_csv(tmp_path / "ur5.csv"), rec, robot


@pytest.mark.parametrize("column, value, row", [("q_elbow_joint", 1e200, 42), ("q_shoulder_pan_joint", -8.0, 7),
                                                ("tau_wrist_2_joint", 1e300, 250), ("tau_shoulder_lift_joint", -1600.0, 3)])
def test_a_wild_value_is_refused_naming_row_column_and_range(tmp_path, column, value, row):
    """Issue 34: one row of y = 1e200 ran to the end (every method inf, "reference uncertainty: inf");
    torques of 1e300 N m ran and put reduced_order at its velocity bound for 2,999 samples. With the
    robot, the reader refuses a position beyond its URDF limits by a tenth of the range (ur5's
    elbow: [-3.77, 3.77] rad) or a torque beyond ten times the effort limit (1500 and 280 N m),
    naming the file's row, the column and the range; without it (as before) the log is read."""
    from codegen.logs.recording import read_log
    path, rec, robot = _ur5_log(tmp_path)
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[row - 1].split(",")
    cells[header.index(column)] = repr(value)
    lines[row - 1] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    for read in (lambda: read_csv(path, robot.joint_names, robot=robot),
                 lambda: read_log(path, robot.joint_names, robot=robot)):
        with pytest.raises(RecordingError, match=rf"ur5.csv: row {row}, column '{column}': {re.escape(f'{value:.6g}')} outside "
                                                 rf"\[-?[0-9.]+, [0-9.]+\] \(.*\): a wild sample"):
            read()
    assert read_csv(path, robot.joint_names).q.shape == rec.q.shape      # no robot: not checked


def test_a_robot_without_declared_limits_reads_any_value_a_motion_gives(tmp_path):
    """seed000_2r's closed form declares no limits: the default range (codegen.core.limits,
    |q| <= 1e4, |tau| <= 1e6) takes positions x 1e3 and torques x 1e3 and refuses x 1e6 (issue
    42: a 1e200 sample otherwise ran), naming the row and the column."""
    from models import load_robot
    robot = load_robot("seed000_2r")
    rec, _ = _log()
    big = Recording(t=rec.t, q=rec.q * 1e3, tau=rec.tau * 1e3, qd=None, joint_names=list(robot.joint_names))
    path = big.write_csv(tmp_path / "big.csv")
    assert np.array_equal(read_csv(path, robot.joint_names, robot=robot).q, big.q)
    wild = Recording(t=rec.t, q=rec.q * 1e6, tau=rec.tau, qd=None, joint_names=list(robot.joint_names))
    path = wild.write_csv(tmp_path / "wild.csv")
    with pytest.raises(RecordingError, match=r"row \d+, column 'q_q\d': .* outside \[-10000, 10000\] "
                                             r"\(joint 'q\d' declares no limits"):
        read_csv(path, robot.joint_names, robot=robot)


def test_a_log_larger_than_the_limit_is_refused_by_its_size(tmp_path, monkeypatch):
    """Issue 34, R4: a 200 MB log was untried (read whole into Python lists). Beyond the limit
    (codegen.core.columns.max_bytes: 1 GiB, or CODEGEN_MAX_LOG_BYTES) it is refused by its size,
    before a row is read; below it, it is read in blocks of CHUNK rows (the same numbers)."""
    from codegen.core import columns
    rec, _ = _log(N=1000)
    path = rec.write_csv(tmp_path / "log.csv")
    size = path.stat().st_size
    monkeypatch.setenv(columns.MAX_BYTES_ENV, str(size - 1))
    with pytest.raises(RecordingError, match=rf"log.csv: {size / 1e6:.1f} MB, more than the "
                                             rf"{(size - 1) / 1e6:.1f} MB a log may have .*CODEGEN_MAX_LOG_BYTES"):
        read_csv(path, JOINTS)
    monkeypatch.setenv(columns.MAX_BYTES_ENV, str(size))
    whole = read_csv(path, JOINTS)
    monkeypatch.setattr(columns, "CHUNK", 7)                       # 143 blocks of 7 rows
    blocks = read_csv(path, JOINTS)
    assert np.array_equal(whole.q, rec.q) and np.array_equal(blocks.q, rec.q) and np.array_equal(blocks.t, rec.t)
    lines = path.read_text().splitlines()
    lines[500] = lines[500].replace(lines[500].split(",")[2], "1.5x", 1)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match=r"row 501, column 'q_elbow': '1.5x' is not a number"):
        read_csv(path, JOINTS)


def test_compare_and_identify_refuse_a_wild_torque_in_one_line(tmp_path, capsys):
    """Issue 34, R4: `compare` on a log with torques of 1e300 N m ran and reported reduced_order
    DIVERGED; it and `identify` now stop at the reader, in one line naming the row and column."""
    from codegen.cli import main
    path, rec, robot = _ur5_log(tmp_path)
    tau = rec.tau.copy()
    tau[:, 1] = 1e300
    Recording(t=rec.t, q=rec.q, tau=tau, qd=None, joint_names=rec.joint_names).write_csv(path)
    for argv in (["compare", str(path), "--robot", "ur5", "--out", str(tmp_path / "c")],
                 ["identify", str(path), "--robot", "ur5", "--out", str(tmp_path / "i")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert "row 2, column 'tau_shoulder_lift_joint': 1e+300 outside [-1500, 1500]" in err and "\n" not in err
