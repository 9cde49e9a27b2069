"""A log's own column names mapped onto a recording's (codegen.logs.mapping, read by
codegen.logs.recording.read_log): rules with ``*``, the time unit, joint-name lists, mapping files,
and refusals that name the rule or the column."""
import contextlib
import csv
import io
import json

import numpy as np
import pytest

from codegen.cli import main
from codegen.logs.mapping import ColumnMap, MappingError, parse
from codegen.logs.recording import Recording, RecordingError, log_joints, read_log
from codegen.verify.trajectory import demo_trajectory
from models import load_robot

ROBOT = "seed000_2r"
EPOCH_NS = 1_700_000_000_123_456_789           # a ROS-style stamp: float64 would lose its last digits


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """(recording CSV, ROS-style export of the same data, the data): 3 s of seed000_2r's demo
    motion at stamps jittered by whole microseconds; the export has a nanosecond epoch time
    column, indexed position/velocity/effort columns and text columns of the joint names (what
    `rostopic echo -p` writes)."""
    robot = load_robot(ROBOT)
    folder = tmp_path_factory.mktemp("mapped")
    t, Q, QD, TAU = demo_trajectory(robot, T=3.0, dt=1e-3, seed=1)
    rng = np.random.default_rng(3)
    us = 1000 * np.arange(len(t)) + rng.integers(-150, 150, len(t))
    us[0] = 0
    rec = Recording(t=us / 1e6, q=Q, tau=TAU, qd=None, joint_names=list(robot.joint_names),
                    qdm=QD + 1e-3 * rng.standard_normal(QD.shape))
    plain = rec.write_csv(folder / "log.csv")
    export = folder / "export.csv"
    with open(export, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["%time", "field.header.frame_id"] + [f"field.name{i}" for i in range(2)]
                   + [f"field.{g}{i}" for g in ("position", "velocity", "effort") for i in range(2)])
        for k in range(len(t)):
            w.writerow([EPOCH_NS + 1000 * int(us[k]), "base"] + list(robot.joint_names)
                       + [repr(float(v)) for v in (*rec.q[k], *rec.qdm[k], *rec.tau[k])])
    return plain, export, rec


ROS_EXPORT = "field.position*=q_*,field.velocity*=qdm_*,field.effort*=tau_*,%time=t,t_unit=ns,joints=[q1,q2]"


def test_a_ros_export_mapped_reads_as_the_recording(logs):
    """The export through the mapping is the recording CSV to the last bit: its nanosecond epoch
    stamps exact from the first row (float64 would round 1.7e18 ns to 256 ns), the indexed
    columns renamed by the joint list, the text columns not read."""
    plain, export, rec = logs
    joints = list(rec.joint_names)
    assert log_joints(export, ROS_EXPORT) == joints
    a, ca = read_log(plain, joints)
    b, cb = read_log(export, joints, columns=ROS_EXPORT)
    for name in ("t", "q", "tau", "qdm"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert ca.describe() == cb.describe()


def test_a_mapping_file_is_the_same_mapping(logs, tmp_path):
    plain, export, rec = logs
    rules = {"field.position*": "q_*", "field.velocity*": "qdm_*", "field.effort*": "tau_*", "%time": "t"}
    toml = tmp_path / "ros.toml"
    toml.write_text('t_unit = "ns"\njoints = ["q1", "q2"]\n[columns]\n'
                    + "".join(f'"{k}" = "{v}"\n' for k, v in rules.items()))
    js = tmp_path / "ros.json"
    js.write_text(json.dumps({"t_unit": "ns", "joints": {"0": "q1", "1": "q2"}, "columns": rules}))
    want = parse(ROS_EXPORT).resolve(["%time", "field.position0", "field.position1", "field.velocity0",
                                      "field.velocity1", "field.effort0", "field.effort1"])
    for path in (toml, js):
        got = parse(str(path))
        assert got.t_unit == "ns"
        assert got.resolve(list(want.values())) == want
    b, _ = read_log(export, list(rec.joint_names), "stamps", columns=str(toml))
    assert np.array_equal(b.t, rec.t)


@pytest.mark.parametrize("unit, scale", [("s", 1), ("ms", 1e3), ("us", 1e6), ("µs", 1e6), ("ns", 1e9)])
def test_the_time_unit_is_the_mappings(logs, tmp_path, unit, scale):
    """A time column in ms, µs or ns, as the mapping states it, gives the stamps in seconds from
    the first row: to 1e-12 s, the rounding of the written values (1e3 s + t, 17 digits: 1e-13 s)."""
    plain, _, rec = logs
    path = tmp_path / "u.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["stamp"] + [f"pos_{j}" for j in rec.joint_names] + [f"eff_{j}" for j in rec.joint_names])
        for k in range(len(rec.t)):
            w.writerow([repr(float(1e3 * scale + rec.t[k] * scale))] + [repr(float(v)) for v in (*rec.q[k], *rec.tau[k])])
    got, _ = read_log(path, list(rec.joint_names), "stamps", columns=f"stamp=t,pos_*=q_*,eff_*=tau_*,t_unit={unit}")
    assert np.allclose(got.t, rec.t - rec.t[0], rtol=0, atol=1e-12)
    assert got.qdm is None and np.array_equal(got.q, rec.q)


def test_refusals_name_the_rule_or_the_column(logs):
    plain, export, rec = logs
    joints = list(rec.joint_names)
    with pytest.raises(RecordingError, match="no q_<joint> column .* its columns: %time, field.header.frame_id"):
        read_log(export, joints)                                   # the export as it is
    with pytest.raises(RecordingError, match=r"rule field\.pos\.\*=q_\* matches no column"):
        read_log(export, joints, columns=ROS_EXPORT.replace("field.position*", r"field.pos.*"))
    with pytest.raises(RecordingError, match=r"no tau_q1, tau_q2 after the column mapping .* columns no rule "
                                             r"maps: field.header.frame_id, field.name0, field.name1, field.velocity0, field.velocity1, field.effort0"):
        read_log(export, joints, columns="field.position*=q_*,%time=t,t_unit=ns,joints=[q1,q2]")
    with pytest.raises(RecordingError, match="joints lists 3 names, the log has 2 joints"):
        read_log(export, joints, columns=ROS_EXPORT.replace("[q1,q2]", "[q1,q2,q3]"))
    with pytest.raises(RecordingError, match="row 2, column 'field.name0': 'q1' is not a number"):
        read_log(export, joints, columns=ROS_EXPORT + ",field.name*=qd_*")
    for text, match in (("a=b", "the target must be t, t_robot or q_"), ("a*=t_*", "the target must be t"),
                        ("a*=q_x", r"a '\*' on both sides"), ("a=q_x,b=q_x", "'q_x' is the target of two rules"),
                        ("stamp=t,t_unit=min", "t_unit: expected one of s, ms, us, µs, ns"),
                        ("a", "expected SOURCE=TARGET"), ("m.toml", "no such mapping file")):
        with pytest.raises(MappingError, match=match):
            parse(text)
    assert ColumnMap({"x_*": "q_*"}).resolve(["x_a", "y"]) == {"q_a": "x_a"}


def test_every_log_command_takes_the_mapping(logs, tmp_path):
    """describe and the targets file's tune read the mapped export as the plain CSV; a command
    refusing an unmapped log prints the flag that maps it."""
    plain, export, rec = logs
    status, want, err = _run(["describe", str(plain), "--robot", ROBOT])
    assert status == 0, err
    status, got, err = _run(["describe", str(export), "--robot", ROBOT, "--columns", ROS_EXPORT])
    assert status == 0, err
    assert got == want
    status, _, err = _run(["describe", str(export), "--robot", ROBOT])
    assert status == 2 and "--columns 'position_*=q_*,effort_*=tau_*,time=t" in err
    for cmd in (["identify", str(export), "--robot", ROBOT], ["design", str(export), "--robot", ROBOT, "--family",
                                                              "reduced_order"]):
        status, _, err = _run(cmd + ["--columns", "field.effort*=tau_*"])
        assert status == 2 and "no t, q_q1, q_q2, tau_q1, tau_q2 after the column mapping" in err, err
    (tmp_path / "lone.toml").write_text(f'[[target]]\nrobot = "{ROBOT}"\ntune_columns = "{ROS_EXPORT}"\n')
    status, _, err = _run(["build", "-c", str(tmp_path / "lone.toml")])
    assert status == 2 and "tune_columns: belongs with tune" in err


def test_a_targets_file_tunes_on_a_mapped_log(logs, tmp_path):
    plain, export, rec = logs
    tuned = []
    for name, extra in (("plain", ""), ("export", f'tune_columns = "{ROS_EXPORT}"\n')):
        log = plain if name == "plain" else export
        (tmp_path / f"{name}.toml").write_text(f'[[target]]\nrobot = "{ROBOT}"\nfamily = "reduced_order"\n'
                                               f'tune = "{log}"\n{extra}')
        status, _, err = _run(["build", "-c", str(tmp_path / f"{name}.toml"), "--out", str(tmp_path / name)])
        assert status == 0, err
        tuned.append(err.split("k0 = ")[1].split()[0])
    assert tuned[0] == tuned[1]
