"""ROS bags read as logs (codegen.logs.bag): bags written here with rosbags' own writers (ROS 1,
ROS 2 with sqlite3 and mcap storage) from a synthetic log read as the CSV of the same data, in
Python and through `describe` and `compare`; the topic chosen or asked for; refusals."""
import contextlib
import io
import json

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the ros extra (rosbags) is not installed")

from rosbags.rosbag1 import Writer as Writer1                 # noqa: E402
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore            # noqa: E402

from codegen.cli import main                                 # noqa: E402
from codegen.logs.recording import Recording, RecordingError, log_joints, read_log   # noqa: E402
from codegen.verify.trajectory import demo_trajectory        # noqa: E402
from models import load_robot                                # noqa: E402

ROBOT = "seed000_2r"
EPOCH_NS = 1_733_500_000_000_000_000          # the bag's stamps: wall-clock nanoseconds
KINDS = ("ros1", "db3", "mcap")


def write_bag(path, kind, rec, topics=("/joint_states",), stamp=True, names=None, effort=True, record_delay=250_000):
    """A bag of ``kind`` (ros1, db3, mcap) at ``path`` holding ``rec`` as sensor_msgs/JointState
    messages on each of ``topics`` (header stamp EPOCH_NS + t, recorded ``record_delay`` ns later);
    ``names``: per-message joint names (default the recording's), ``stamp``/``effort`` False leave
    those empty."""
    store = get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)
    JointState = store.types["sensor_msgs/msg/JointState"]
    Header, Time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    writer = Writer1(path) if kind == "ros1" else Writer2(
        path, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3)
    serialize = store.serialize_ros1 if kind == "ros1" else store.serialize_cdr
    ns = EPOCH_NS + np.rint(rec.t * 1e9).astype(np.int64)
    empty = np.zeros(0)
    with writer:
        connections = [writer.add_connection(t, JointState.__msgtype__, typestore=store) for t in topics]
        for k in range(len(rec.t)):
            at = int(ns[k]) if stamp else 0
            header = Header(**({"seq": k} if kind == "ros1" else {}),
                            stamp=Time(sec=at // 10 ** 9, nanosec=at % 10 ** 9), frame_id="")
            msg = JointState(header=header, name=list(names[k] if names else rec.joint_names), position=rec.q[k],
                             velocity=rec.qdm[k] if rec.qdm is not None else empty,
                             effort=rec.tau[k] if effort else empty)
            for c in connections:
                writer.write(c, int(ns[k]) + record_delay, serialize(msg, JointState.__msgtype__))
    return path


def _bag_path(folder, kind):
    return folder / ("log.bag" if kind == "ros1" else f"log_{kind}")


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


def synthetic(T, seed=0):
    """seed000_2r's demo motion for ``T`` s at stamps jittered by whole microseconds (exact in a
    bag's nanoseconds), a 2^16 counts/rev encoder, its model's torques with noise, and the robot's
    own velocity signal (qdm) with noise."""
    robot = load_robot(ROBOT)
    t, Q, QD, TAU = demo_trajectory(robot, T=T, dt=1e-3, seed=seed)
    rng = np.random.default_rng(seed + 11)
    us = 1000 * np.arange(len(t)) + rng.integers(-200, 200, len(t))
    us[0] = 0
    step = 2 * np.pi / 2 ** 16
    return Recording(t=us / 1e6, q=step * np.round(Q / step), tau=TAU + 0.01 * rng.standard_normal(TAU.shape),
                     qd=None, joint_names=list(robot.joint_names), qdm=QD + 2e-3 * rng.standard_normal(QD.shape))


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """(folder, recording): a 3 s synthetic log as log.csv and as a bag of each kind."""
    folder = tmp_path_factory.mktemp("bags")
    rec = synthetic(3.0)
    rec.write_csv(folder / "log.csv")
    for kind in KINDS:
        write_bag(_bag_path(folder, kind), kind, rec)
    return folder, rec


@pytest.mark.parametrize("kind", KINDS)
def test_a_bag_reads_as_the_csv_of_the_same_data(logs, kind):
    """Every array of the bag's recording equals the CSV's to the last bit (the wall-clock
    nanosecond stamps exact from the first message's), and so does the clock found on it."""
    folder, rec = logs
    joints = list(rec.joint_names)
    bag = _bag_path(folder, kind)
    assert log_joints(bag) == joints
    a, ca = read_log(folder / "log.csv", joints)
    b, cb = read_log(bag, joints)
    for name in ("t", "q", "tau", "qdm"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert cb.describe() == ca.describe()
    if kind != "ros1":                           # a ROS 2 bag's storage file names its folder
        storage = next(bag.glob(f"*.{kind}"))
        assert np.array_equal(read_log(storage, joints)[0].q, a.q)


@pytest.mark.parametrize("kind", ("ros1", "db3"))
def test_describe_prints_the_same_for_the_bag_and_the_csv(logs, kind):
    folder, _ = logs
    status, want, err = _run(["describe", str(folder / "log.csv"), "--robot", ROBOT])
    assert status == 0, err
    for robot in (["--robot", ROBOT], []):
        status, got, err = _run(["describe", str(_bag_path(folder, kind))] + robot)
        assert status == 0, err
        assert got == want if robot else "joints: q1, q2" in got


def test_a_bag_mapping_overrides_the_default(logs, tmp_path):
    """The user's rules go over the bag's default: the record time as t, velocity as the true qd,
    joints renamed."""
    folder, rec = logs
    bag = _bag_path(folder, "db3")
    got, _ = read_log(bag, ["a", "b"], "stamps", columns="velocity_*=qd_*,joints=[a,b]")
    assert got.qdm is None and np.array_equal(got.qd, rec.qdm) and np.array_equal(got.t, rec.t)
    got, _ = read_log(bag, list(rec.joint_names), "stamps", columns="bag.time=t")
    assert np.array_equal(got.t, rec.t)                          # recorded a constant 0.25 ms later


def test_the_topic_is_chosen_or_asked_for(tmp_path):
    rec = synthetic(0.3)
    bag = write_bag(tmp_path / "two.bag", "ros1", rec, topics=("/arm/joint_states", "/joint_states"))
    with pytest.raises(RecordingError, match=r"2 sensor_msgs/msg/JointState topics, /arm/joint_states \(301 "
                                             r"messages\), /joint_states \(301 messages\): name the one to read"):
        read_log(bag, rec.joint_names)
    assert np.array_equal(read_log(bag, rec.joint_names, "stamps", topic="/arm/joint_states")[0].q, rec.q)
    with pytest.raises(RecordingError, match="no sensor_msgs/msg/JointState topic '/js'"):
        read_log(bag, rec.joint_names, topic="/js")
    status, _, err = _run(["describe", str(bag)])
    assert status == 2 and err.strip().endswith("--topic /arm/joint_states"), err
    status, out, err = _run(["describe", str(bag), "--topic", "/joint_states"])
    assert status == 0 and "joints: q1, q2" in out, err
    with pytest.raises(RecordingError, match="a topic is read from a ROS bag; this is a CSV"):
        read_log(rec.write_csv(tmp_path / "x.csv"), rec.joint_names, topic="/joint_states")


def test_refusals_name_what_the_bag_lacks(tmp_path):
    rec = synthetic(0.3)
    joints = rec.joint_names
    bag = write_bag(tmp_path / "nostamp.bag", "ros1", rec, stamp=False)
    with pytest.raises(RecordingError, match="every header stamp is zero .* the rule bag.time=t"):
        read_log(bag, joints)
    assert np.array_equal(read_log(bag, joints, "stamps", columns="bag.time=t")[0].t, rec.t)
    bag = write_bag(tmp_path / "noeffort.bag", "ros1", rec, effort=False)
    with pytest.raises(RecordingError, match="its messages carry no effort"):
        read_log(bag, joints)
    names = [joints if k % 2 else ["gripper", "finger"] for k in range(len(rec.t))]
    bag = write_bag(tmp_path / "mixed.bag", "ros1", rec, names=names)
    with pytest.raises(RecordingError, match=r"different joint lists \(\[gripper, finger\] in 151; \[q1, q2\] in 150\)"):
        read_log(bag, joints)
    for path, match in ((tmp_path / "none.bag", "no such bag"), (tmp_path, "a folder, not a log")):
        with pytest.raises(RecordingError, match=match):
            read_log(path, joints)
    rec.write_csv(tmp_path / "log.csv")
    status, _, err = _run(["describe", str(tmp_path / "noeffort.bag"), "--robot", "ur5"])
    assert status == 2 and "no effort" in err


@pytest.mark.slow
@pytest.mark.parametrize("kind", ("ros1", "mcap"))
def test_compare_gives_the_csvs_table_on_the_bag(logs, tmp_path, kind):
    """compare on the bag and on the CSV of the same data: the same table, line for line, and
    the same compare.json rows."""
    folder, _ = logs
    tables = []
    for name, source in (("csv", folder / "log.csv"), (kind, _bag_path(folder, kind))):
        status, out, err = _run(["compare", str(source), "--robot", ROBOT, "--observers",
                                 "reduced_order,kalman_model", "--baselines", "kalman,butterworth",
                                 "--out", str(tmp_path / name)])
        assert status == 0, err
        lines = out.splitlines()
        assert lines[0] == f"{source.name} ({ROBOT})" and lines[-1].startswith("figures, estimates.csv")
        tables.append(lines[1:-1])                  # but the title (the file's name) and the output folder
        tables[-1].append(json.dumps(json.loads((tmp_path / name / "compare.json").read_text())["rows"]))
    assert len(tables[0]) > 5
    assert tables[0] == tables[1]
