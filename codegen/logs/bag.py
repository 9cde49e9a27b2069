"""A ROS bag's joint states as a log's columns: ROS 1 ``.bag`` files and ROS 2 bag folders
(``.db3`` or ``.mcap`` storage, with their ``metadata.yaml``), read through the ``rosbags``
package (an optional extra: ``ros``).

One ``sensor_msgs/JointState`` topic is read (the only one, or the one named): each message is a
row, its ``name`` the joints, and the columns are

    header.stamp        the message's header stamp (ns, from the first message's)
    bag.time            when the bag recorded it (ns, from the first message's)
    position_<joint>    position (rad or m)
    velocity_<joint>    velocity (rad/s; the robot's own signal), when the messages carry one
    effort_<joint>      effort (N m or N)

mapped onto a recording's by ``DEFAULT`` (header stamp -> t, position -> q, velocity -> qdm,
effort -> tau; codegen.logs.mapping), which a user's mapping overrides rule by rule.
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from .mapping import ColumnMap

JOINT_STATE = "sensor_msgs/msg/JointState"
DEFAULT = ColumnMap({"header.stamp": "t", "position_*": "q_*", "velocity_*": "qdm_*", "effort_*": "tau_*"},
                    t_unit="ns")
OPTIONAL = ("velocity_*",)           # rules of DEFAULT a bag without the field goes without
STORAGE = (".db3", ".mcap")          # a ROS 2 bag's storage files


class BagError(ValueError):
    """A bag that cannot be read as a log (the message names the bag and what is wrong); ``option``
    names the choice that would fix it (``"topic"``) and ``choices`` its values, when one would."""

    def __init__(self, message, option=None, choices=()):
        super().__init__(message)
        self.option, self.choices = option, list(choices)


def is_bag(path):
    """True when ``path`` is a ROS 1 ``.bag`` file, a ROS 2 bag folder (it holds ``metadata.yaml``) or a ROS 2
    storage file (``.db3``, ``.mcap``)."""
    path = Path(path)
    return (path.suffix == ".bag" or path.suffix in STORAGE
            or (path.is_dir() and (path / "metadata.yaml").is_file()))


def _bag_path(path):
    """The path rosbags opens: the file of a ROS 1 bag, the folder of a ROS 2 bag (a storage
    file's folder). BagError when there is none."""
    path = Path(path)
    if path.suffix in STORAGE and path.is_file():
        path = path.parent
    if path.suffix == ".bag" and path.is_file():
        return path
    if path.is_dir() and (path / "metadata.yaml").is_file():
        return path
    if not path.exists():
        raise BagError(f"{path}: no such bag")
    raise BagError(f"{path}: not a ROS bag (a ROS 1 .bag file, or a ROS 2 bag folder with its metadata.yaml)")


def joint_state_topics(reader):
    """{topic: message count} of the JointState topics of an open rosbags reader."""
    topics = {}
    for c in reader.connections:
        if c.msgtype == JOINT_STATE:
            topics[c.topic] = topics.get(c.topic, 0) + c.msgcount
    return topics


def read(path, topic=None):
    """(columns, topic): {column: (N,) float64} of the bag at ``path`` (module docstring) and the
    topic read. ``topic``: a JointState topic's name; None takes the only one.

    Raises
    ------
    BagError
        No bag; no JointState topic, several (``option`` "topic", the candidates in ``choices``)
        or an unknown one; fewer than two messages; messages whose joints differ, or without
        effort.
    ImportError
        The ``rosbags`` package is not installed (name ``rosbags``).
    """
    bag = _bag_path(path)
    stat = bag.stat() if bag.is_file() else max((f.stat() for f in bag.iterdir()), key=lambda st: st.st_mtime_ns)
    col, topic = _read(str(bag.resolve()), topic, stat.st_mtime_ns, stat.st_size)
    return dict(col), topic


@functools.lru_cache(maxsize=2)
def _read(bag, topic, mtime, size):
    """``read``'s columns of the bag ``bag`` (a resolved path), read once for its ``mtime`` and
    ``size`` (a command reads the joints, then the log)."""
    from rosbags.highlevel import AnyReader
    bag = Path(bag)
    with AnyReader([bag]) as reader:
        topics = joint_state_topics(reader)
        listed = ", ".join(f"{k} ({v} messages)" for k, v in topics.items())
        if not topics:
            others = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            raise BagError(f"{bag}: no {JOINT_STATE} topic (its topics: {', '.join(others) or 'none'})")
        if topic is None and len(topics) > 1:
            raise BagError(f"{bag}: {len(topics)} {JOINT_STATE} topics, {listed}: name the one to read",
                           option="topic", choices=topics)
        if topic is not None and topic not in topics:
            raise BagError(f"{bag}: no {JOINT_STATE} topic {topic!r} (its JointState topics: {listed})",
                           option="topic", choices=topics)
        topic = topic or next(iter(topics))
        rows = [(t, reader.deserialize(raw, c.msgtype)) for c, t, raw in
                reader.messages(connections=[c for c in reader.connections if c.topic == topic])]
    return _columns(bag, topic, rows), topic


def check(col, to, where):
    """BagError naming ``where`` when the time ``to["t"]`` (a recording's column -> the bag's) is the
    header stamp of a publisher that leaves it unset (every stamp zero in the bag's columns ``col``)."""
    if to.get("t") == "header.stamp" and np.isnan(col["header.stamp"]).all():
        raise BagError(f"{where}: every header stamp is zero (the publisher does not stamp its messages): "
                       f"map the bag's record time instead, the rule bag.time=t")


def _columns(bag, topic, rows):
    """The columns of ``rows`` ((record time ns, JointState message), in the bag's order)."""
    where = f"{bag}, topic {topic}"
    if len(rows) < 2:
        raise BagError(f"{where}: {len(rows)} message{'s' * (len(rows) != 1)}, a log needs at least 2")
    names = [tuple(m.name) for _, m in rows]
    lists = {}
    for n in names:
        lists[n] = lists.get(n, 0) + 1
    if len(lists) > 1:
        seen = "; ".join(f"[{', '.join(k)}] in {v}" for k, v in lists.items())
        raise BagError(f"{where}: its messages carry different joint lists ({seen}): a log is one list "
                       f"(record each publisher on its own topic)")
    joints = list(names[0])
    if not joints:
        raise BagError(f"{where}: its messages name no joint")
    stamp = np.array([m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec for _, m in rows], dtype=np.int64)
    record = np.array([t for t, _ in rows], dtype=np.int64)
    col = {"header.stamp": (stamp - stamp[0]).astype(float), "bag.time": (record - record[0]).astype(float)}
    if not stamp.any():
        col["header.stamp"] = np.full(len(rows), np.nan)        # unset: refused if it is the time (``check``)
    for field in ("position", "velocity", "effort"):
        sizes = {len(getattr(m, field)) for _, m in rows}
        if sizes == {0} and field == "velocity":
            continue
        if sizes != {len(joints)}:
            what = "no effort (the joint torques every command needs)" if sizes == {0} else \
                f"{field} of {sorted(sizes)} values for {len(joints)} joints"
            raise BagError(f"{where}: its messages carry {what}")
        values = np.array([getattr(m, field) for _, m in rows], dtype=float)
        col.update({f"{field}_{j}": values[:, i] for i, j in enumerate(joints)})
    return col
