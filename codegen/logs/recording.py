"""A recorded run: sample times, positions, applied torques and, when known, true velocities or
the robot's own velocity signal (the CSV itself through codegen.core.columns).

The recording form ``codegen compare`` reads and the MuJoCo scenarios write has a header row

    t, q_<joint>..., tau_<joint>...[, qd_<joint>...][, qdm_<joint>...]

with the robot's joint names, one row per sample (column order free). ``qd`` is the true
velocity (a simulation has it, a real log does not), ``qdm`` the velocity the robot itself logs
(its drive's or controller's estimate). Time stamps are what a real log has: jitter and dropped
samples are allowed, they must be finite and strictly increasing (what the stamps are, a sample
clock or when a logger received each row, is found by codegen.logs.clock).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.columns import ColumnsError, read_columns, read_header, write_columns


class RecordingError(ColumnsError):
    """A recording that cannot be used (message names the file and what is wrong); ``option``
    names the choice that would fix it ("columns": a column mapping, "topic": a bag's topic) and
    ``choices`` its values, when one would."""

    def __init__(self, message, option=None, choices=()):
        super().__init__(message)
        self.option, self.choices = option, list(choices)


@dataclass
class Recording:
    """Samples of a run.

    Attributes
    ----------
    t : (N,) array
        Sample times (s), strictly increasing; jitter and gaps allowed.
    q : (N, n) array
        Measured positions (rad or m), what an observer receives as y.
    tau : (N, n) array
        Torque applied over [t_k, t_k+1] (N m), the observer's u.
    qd : (N, n) array or None
        True velocities (rad/s), when known (a simulation).
    joint_names : list of str
    qdm : (N, n) array or None
        The robot's own velocity signal (rad/s), when it logs one.
    """

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    qd: np.ndarray | None
    joint_names: list
    qdm: np.ndarray | None = None

    def __post_init__(self):
        self.t = np.asarray(self.t, dtype=float)
        n, N = len(self.joint_names), len(self.t)
        if self.t.ndim != 1 or N < 2:
            raise ValueError(f"t: expected (N,) sample times with N >= 2, got shape {self.t.shape}")
        for name in ("q", "tau", "qd", "qdm"):
            a = getattr(self, name)
            if a is None:
                continue
            a = np.asarray(a, dtype=float)
            if a.shape != (N, n):
                raise ValueError(f"{name}: expected shape ({N}, {n}) (samples, joints), got {a.shape}")
            setattr(self, name, a)
        if not np.all(np.isfinite(self.t)):
            raise ValueError(f"t: NaN or Inf at index {int(np.argmax(~np.isfinite(self.t)))}")
        back = np.nonzero(np.diff(self.t) <= 0)[0]
        if len(back):
            k = back[0]
            raise ValueError(f"t: time stamps must increase; t[{k + 1}] = {self.t[k + 1]:.9g} <= "
                             f"t[{k}] = {self.t[k]:.9g}")

    @property
    def steps(self):
        """The time steps t_k+1 - t_k (N-1,) (s)."""
        return np.diff(self.t)

    @property
    def dt(self):
        """The median step (s), rounded to 12 significant digits (the float noise of differencing
        decimal stamps: a uniform 1 kHz log gives exactly 1e-3). What the observers and the
        baselines' filters are designed at."""
        return float(f"{np.median(self.steps):.12g}")

    @property
    def dt_min(self):
        """The shortest step (s)."""
        return float(np.min(self.steps))

    @property
    def dt_max(self):
        """The longest step (s)."""
        return float(np.max(self.steps))

    @property
    def gaps(self):
        """Number of steps longer than 1.5 median steps (dropped samples)."""
        return int(np.sum(self.steps > 1.5 * self.dt))

    @property
    def uniform(self):
        """True when every step is the median step to 1e-6 relative (a simulated or a
        hardware-timed log)."""
        return bool(np.all(np.abs(self.steps - self.dt) <= 1e-6 * self.dt))

    @property
    def n(self):
        """Number of joints."""
        return len(self.joint_names)

    def describe(self):
        """One line about the time stamps: samples, span, median/min/max step and the gaps."""
        return (f"{len(self.t)} samples over {self.t[-1] - self.t[0]:.6g} s; step median "
                f"{1e3 * self.dt:.4g} ms ({1 / self.dt:.6g} Hz), min {1e3 * self.dt_min:.4g} ms, "
                f"max {1e3 * self.dt_max:.4g} ms; {self.gaps} gap{'s' * (self.gaps != 1)} > 1.5 median"
                + ("" if not self.uniform else " (uniform)"))

    def columns(self):
        """Header names in file order."""
        groups = ["q", "tau"] + [g for g in ("qd", "qdm") if getattr(self, g) is not None]
        return ["t"] + [f"{g}_{j}" for g in groups for j in self.joint_names]

    def write_csv(self, path):
        """Write the CSV of the module docstring to ``path`` (atomically; parent folders
        created); returns the path."""
        names = self.columns()
        data = np.column_stack([self.t] + [a for a in (self.q, self.tau, self.qd, self.qdm) if a is not None])
        return write_columns(path, {name: data[:, i] for i, name in enumerate(names)})


def _table(path, columns=None, topic=None):
    """(path, header, {recording column: (N,) values}) of the log at ``path``: a recording CSV as it
    is (``columns`` None), a CSV whose own names the mapping ``columns`` maps (codegen.logs.mapping:
    its text, a mapping file or a ColumnMap), or a ROS bag's JointState topic (codegen.logs.bag,
    ``topic``; its default mapping under ``columns``). ``header``: the log's own column names (a
    message lists the unmapped ones)."""
    from . import bag, mapping
    path = Path(path)
    try:
        cmap = mapping.parse(columns)
        if bag.is_bag(path):
            raw, _ = bag.read(path, topic)
            rules = bag.DEFAULT.updated(cmap)
            header = list(raw)
            optional = [s for s in bag.OPTIONAL if s not in (cmap.rules if cmap else {})]
            to = rules.resolve(header, f"{path}", optional=optional)
            bag.check(raw, to, f"{path}")
            return path, header, {name: raw[src] / (rules.scale if name in mapping.TIMES else 1)
                                  for name, src in to.items()}
        if path.is_dir():
            raise RecordingError(f"{path}: a folder, not a log (a CSV file, a ROS 1 .bag file or a ROS 2 bag "
                                 f"folder with its metadata.yaml)")
        if topic is not None:
            raise RecordingError(f"{path}: a topic is read from a ROS bag; this is a CSV")
        if cmap is None:
            header = read_header(path, RecordingError)
            if not any(h.startswith("q_") for h in header):
                raise RecordingError(f"{path}: no q_<joint> column (expected t, q_<joint>, tau_<joint>[, qd_<joint>]"
                                     f"[, qdm_<joint>]; a log with other names needs a column mapping; its columns: "
                                     f"{mapping.some(header)})", option="columns")
            header, data = read_columns(path, RecordingError)
            return path, header, {h: data[:, i] for i, h in enumerate(header)}
        header = read_header(path, RecordingError)
        to = cmap.resolve(header, f"{path}")
        times = {src: cmap.scale for name, src in to.items() if name in mapping.TIMES}
        names, data = read_columns(path, RecordingError, keep=list(to.values()), origin=times)
    except (mapping.MappingError, bag.BagError) as e:
        raise RecordingError(str(e), option=getattr(e, "option", None), choices=getattr(e, "choices", ())) from None
    return path, header, {name: data[:, names.index(src)] for name, src in to.items()}


def log_joints(path, columns=None, topic=None):
    """The joints of the log at ``path`` (its q_<joint> columns after the mapping ``columns``; the
    JointState names of a bag's ``topic``), in file order. RecordingError when there are none."""
    from . import mapping
    path, header, col = _table(path, columns, topic)
    joints = [h[2:] for h in col if h.startswith("q_")]
    if not joints:
        raise RecordingError(f"{path}: no q_<joint> columns (expected t, q_<joint>, tau_<joint>; a log with "
                             f"other names needs a column mapping; its columns: {mapping.some(header)})",
                             option="columns")
    return joints


def _columns(path, joint_names, robot=None, columns=None, topic=None):
    """(path, {column: (N,) values}) of a recording (``_table``: a CSV, mapped or not, or a bag),
    every column there and finite, at least two rows, positions and torques within the ``robot``'s
    declared ranges when it is given (``check_ranges``; the stamps not yet checked): ``read_csv``
    and ``read_log``."""
    path, header, col = _table(path, columns, topic)
    need = ["t"] + [f"{g}_{j}" for g in ("q", "tau") for j in joint_names]
    missing = [c for c in need if c not in col]
    if missing:
        if columns is None and not _is_bag(path):
            raise RecordingError(f"{path}: missing columns {', '.join(missing)} (expected t, q_<joint>, "
                                 f"tau_<joint>[, qd_<joint>][, qdm_<joint>] for joints {', '.join(joint_names)}; "
                                 f"a log with other names needs a column mapping)", option="columns")
        mapped = set(_sources(path, header, columns, topic))
        unmapped = [h for h in header if h not in mapped]
        raise RecordingError(f"{path}: no {', '.join(missing)} after the column mapping (joints "
                             f"{', '.join(joint_names)} wanted; the log's joints {', '.join(h[2:] for h in col if h.startswith('q_')) or 'none'}"
                             + (f"; columns no rule maps: {', '.join(unmapped[:12])}" if unmapped else "") + ")",
                             option="columns")
    for g in ("qd", "qdm"):
        have = [f"{g}_{j}" for j in joint_names if f"{g}_{j}" in col]
        if have and len(have) < len(joint_names):
            lack = [f"{g}_{j}" for j in joint_names if f"{g}_{j}" not in col]
            raise RecordingError(f"{path}: has {', '.join(have)} but not {', '.join(lack)} "
                                 f"({g}_<joint> for every joint or none)")
    data = np.column_stack(list(col.values())) if col else np.zeros((0, 0))
    names = list(col)
    if len(data) < 2:
        raise RecordingError(f"{path}: need at least 2 rows of {len(names)} values")
    if not np.all(np.isfinite(data)):
        r, c = np.argwhere(~np.isfinite(data))[0]
        raise RecordingError(f"{path}: NaN or Inf in column {names[c]!r}, row {r + 2}")
    if robot is not None:
        check_ranges(path, col, joint_names, robot)
    return path, col


def _is_bag(path):
    from .bag import is_bag
    return is_bag(path)


def _sources(path, header, columns, topic):
    """The log's column names that the mapping of ``_table`` reads (for a message)."""
    from . import bag, mapping
    cmap = mapping.parse(columns)
    rules = bag.DEFAULT.updated(cmap) if bag.is_bag(path) else cmap
    out = []
    for h in header:
        if any(mapping.match(s, h) is not None for s in rules.rules):
            out.append(h)
    return out


def check_ranges(path, col, joint_names, robot):
    """RecordingError naming the file ``path``, the row, the column and the range at the first
    position ``q_<joint>`` or torque ``tau_<joint>`` of the columns ``col`` ({name: (N,) values})
    outside the ``robot``'s declared ranges (codegen.core.limits.joint_ranges: its URDF limits with
    a tenth of the range beyond either end, ten times its effort limit; a joint without one is not
    checked): a wild sample (1e200, 1e300 N m) would otherwise run, silently ruin every later
    estimate, or put an observer at its velocity bound for the rest of the log. ``joint_names``
    the log's joints, in the robot's order."""
    from ..core.limits import POSITION_MARGIN, TORQUE_MARGIN, joint_ranges
    lower, upper, tau = joint_ranges(robot)
    limited = np.asarray(getattr(robot, "position_limited", np.zeros(robot.n, bool)), dtype=bool).reshape(-1)
    effort = np.asarray(getattr(robot, "effort_limit", np.full(robot.n, np.inf)), dtype=float).reshape(-1)
    if limited.size != robot.n:
        limited = np.zeros(robot.n, bool)
    if effort.size != robot.n:
        effort = np.full(robot.n, np.inf)
    bad = []
    for j, name in enumerate(joint_names):
        q_what = (f"joint {name!r}'s limits and {POSITION_MARGIN:g} x its range beyond either end" if limited[j]
                  else f"joint {name!r} declares no limits: the range of a reading any motion gives")
        tau_what = (f"{TORQUE_MARGIN:g} x joint {name!r}'s effort limit" if np.isfinite(effort[j]) and effort[j] > 0
                    else f"joint {name!r} declares no effort limit: the bound of any drive's torque")
        for column, lo, hi, what in ((f"q_{name}", lower[j], upper[j], q_what),
                                     (f"tau_{name}", -tau[j], tau[j], tau_what)):
            v = col[column]
            out = np.flatnonzero((v < lo) | (v > hi))
            if len(out):
                bad.append((int(out[0]), column, float(v[out[0]]), lo, hi, what, len(out)))
    if bad:
        k, column, value, lo, hi, what, count = min(bad)
        raise RecordingError(f"{path}: row {k + 2}, column {column!r}: {value:.6g} outside [{lo:.6g}, {hi:.6g}] "
                             f"({what}; {count} such row{'s' * (count > 1)} in this column): a wild sample; "
                             f"remove it, or give the robot the range it has")


def _recording(col, joint_names, rows=slice(None), t=None):
    """The Recording of the columns ``col`` at ``rows`` (sample times ``t``, default col["t"])."""
    stack = lambda g: np.column_stack([col[f"{g}_{j}"][rows] for j in joint_names])  # noqa: E731
    has = {g: all(f"{g}_{j}" in col for j in joint_names) for g in ("qd", "qdm")}
    return Recording(t=col["t"][rows] if t is None else t, q=stack("q"), tau=stack("tau"),
                     qd=stack("qd") if has["qd"] else None, joint_names=list(joint_names),
                     qdm=stack("qdm") if has["qdm"] else None)


def read_csv(path, joint_names, robot=None, columns=None, topic=None):
    """A Recording from a CSV with the header of the module docstring, its stamps taken as the
    sample times (``read_log`` finds out what they are).

    Parameters
    ----------
    path : path-like
        The file (refused above codegen.core.columns.max_bytes(), 1 GiB by default).
    joint_names : list of str
        The robot's joints, in model order (q_<joint> and tau_<joint> must exist for each;
        qd_<joint> and qdm_<joint> for all joints or none).
    robot : models.RobotModel, optional
        Its declared ranges are checked (``check_ranges``); None: not checked.
    columns : str, path or codegen.logs.mapping.ColumnMap, optional
        The log's own column names mapped onto these (codegen.logs.mapping).
    topic : str, optional
        A ROS bag's JointState topic (codegen.logs.bag; None: its only one).

    Raises
    ------
    RecordingError
        Missing file or columns, a file too large, non-numeric or non-finite values, fewer than
        2 rows, time stamps that repeat or go back, a position or torque outside the robot's
        declared ranges (the message names the file's rows).
    """
    path, col = _columns(path, joint_names, robot, columns, topic)
    t = col["t"]
    steps = np.diff(t)
    bad = np.nonzero(steps <= 0)[0]
    if len(bad):
        k = bad[0]                  # file rows: the header is row 1, sample k is row k + 2
        what = "repeats" if steps[k] == 0 else "goes back"
        raise RecordingError(f"{path}: time stamp {what} between rows {k + 2} and {k + 3}: t = "
                             f"{t[k]:.9g} then {t[k + 1]:.9g} s (stamps must strictly increase"
                             f"{f'; {len(bad)} such rows' if len(bad) > 1 else ''}; --clock auto rebuilds "
                             f"the sample clock of a logger's receive times)")
    return _recording(col, joint_names)


def read_log(path, joint_names, clock="auto", robot=None, columns=None, topic=None):
    """(Recording on the log's sample clock, Clock): a recording CSV read as a measurement
    (codegen.logs.clock): a logger's receive-time stamps rebuilt on the robot's fixed tick and its
    repeated rows dropped, a robot-time column ``t_robot`` used when the log has one, the stamps
    kept for a sampler that really jitters.

    Parameters
    ----------
    path : path-like
    joint_names : list of str
        As ``read_csv``.
    clock : str
        "auto" (default), "stamps", "ticks" or "ticks=PERIOD" (s) (``codegen.logs.clock.parse_mode``).
    robot, columns, topic : optional
        As ``read_csv``.

    Raises
    ------
    RecordingError
        As ``read_csv``, and stamps that go back (or, as sample times, repeat).
    """
    from . import clock as clocks
    mode, period = clocks.parse_mode(clock)
    path, col = _columns(path, joint_names, robot, columns, topic)
    t = col["t"]
    qdm = (np.column_stack([col[f"qdm_{j}"] for j in joint_names])
           if all(f"qdm_{j}" in col for j in joint_names) else None)
    wrapped = [j for j in joint_names if unwrap(col, f"q_{j}")]
    Q = np.column_stack([col[f"q_{j}"] for j in joint_names])
    try:
        c = clocks.rebuild(t, Q, qdm, mode=mode, period=period,
                           t_robot=col.get(clocks.ROBOT_TIME))
    except ValueError as e:
        raise RecordingError(f"{path}: {e}") from None
    c.unwrapped = wrapped
    return _recording(col, joint_names, c.kept, c.t), c


def unwrap(col, name):
    """Unwrap the column ``col[name]`` in place where it jumps by a whole number of turns (2 pi k,
    to within an eighth of a turn) between consecutive rows: a continuous joint reported in
    [-pi, pi) (no arm moves half a turn in one sample). True when it did."""
    q = col[name]
    d = np.diff(q)
    turns = np.rint(d / (2 * np.pi))
    jump = (turns != 0) & (np.abs(d - 2 * np.pi * turns) < np.pi / 4)
    if not jump.any():
        return False
    col[name] = q - 2 * np.pi * np.concatenate([[0.0], np.cumsum(np.where(jump, turns, 0.0))])
    return True
