"""The recorded run (codegen.logs.recording): a real log's stamps (jitter, dropped samples) read
and written exactly, the optional true velocity and robot's velocity columns, and the stamps it
refuses (repeated, going back), named by their rows in the file."""
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
