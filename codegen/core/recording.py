"""The one CSV module: a recorded run (sample times, positions, applied torques and, when known,
true velocities), and the plain column files every other CSV of ours is (the C harness's input
and output, a simulation's log).

The recording form ``codegen compare`` reads and the MuJoCo scenarios write has a header row

    t, q_<joint>..., tau_<joint>...[, qd_<joint>...]

with the robot's joint names, one row per sample, uniform time stamps (column order free).
``write_columns`` / ``read_columns`` write and read any header + rows of numbers, exactly
(shortest round-trip decimal form) and atomically (a temporary file, then a rename).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np


class RecordingError(ValueError):
    """A recording that cannot be used (message names the file and what is wrong)."""


def write_columns(path, columns):
    """A CSV with one row per sample, written through a temporary file (nothing half-written).

    Parameters
    ----------
    path : path of the CSV (parent folders are created)
    columns : dict
        name -> (N,) array (one column ``name``) or (N, k) array (columns ``name0`` ..
        ``name{k-1}``); every array has the same N.

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names, blocks = [], []
    for name, a in columns.items():
        a = np.asarray(a, dtype=float)
        if a.ndim == 1:
            names.append(name)
            blocks.append(a[:, None])
        else:
            names.extend(f"{name}{i}" for i in range(a.shape[1]))
            blocks.append(a)
    lengths = {len(b) for b in blocks}
    if len(lengths) > 1:
        raise ValueError(f"columns: arrays of different lengths {sorted(lengths)} for {path}")
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        w.writerows(np.hstack(blocks).tolist() if blocks else [])
    tmp.replace(path)
    return path


def read_columns(path, error=RecordingError):
    """(header, data): the names of the first row of the CSV file ``path`` and the numbers below
    it, (N, columns) float64 (N may be 0). Raises ``error`` (an exception class) naming the file
    for a missing or empty file, a non-numeric value or a ragged row."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{path}: no such file")
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise error(f"{path}: empty file")
    header = [h.strip() for h in rows[0]]
    body = [r for r in rows[1:] if r]
    bad = next((i for i, r in enumerate(body) if len(r) != len(header)), None)
    if bad is not None:
        raise error(f"{path}: row {bad + 2} has {len(body[bad])} values, the header {len(header)}")
    try:
        data = np.array([[float(v) for v in r] for r in body], dtype=float).reshape(len(body), len(header))
    except ValueError as e:
        raise error(f"{path}: non-numeric value ({e})") from None
    return header, data


@dataclass
class Recording:
    """Samples of a run.

    Attributes
    ----------
    t : (N,) array
        Uniform sample times (s).
    q : (N, n) array
        Measured positions (rad or m), what an observer receives as y.
    tau : (N, n) array
        Torque applied over [t_k, t_k+1] (N m), the observer's u.
    qd : (N, n) array or None
        True velocities (rad/s), when known.
    joint_names : list of str
    """

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    qd: np.ndarray | None
    joint_names: list

    @property
    def dt(self):
        return float(self.t[1] - self.t[0])

    @property
    def n(self):
        return len(self.joint_names)

    def columns(self):
        """Header names in file order."""
        groups = ["q", "tau"] + (["qd"] if self.qd is not None else [])
        return ["t"] + [f"{g}_{j}" for g in groups for j in self.joint_names]

    def write_csv(self, path):
        """Write the CSV of the module docstring to ``path`` (atomically; parent folders
        created); returns the path."""
        names = self.columns()
        data = np.column_stack([self.t] + [a for a in (self.q, self.tau, self.qd) if a is not None])
        return write_columns(path, {name: data[:, i] for i, name in enumerate(names)})


def read_csv(path, joint_names, rtol=1e-6):
    """A Recording from a CSV with the header of the module docstring.

    Parameters
    ----------
    path : path-like
        The file.
    joint_names : list of str
        The robot's joints, in model order (q_<joint> and tau_<joint> must exist for each).
    rtol : float
        Largest relative deviation of a time step from the mean step.

    Raises
    ------
    RecordingError
        Missing file or columns, non-numeric or non-finite values, fewer than 2 rows,
        time stamps that are not increasing and uniform.
    """
    path = Path(path)
    header, data = read_columns(path)
    need = ["t"] + [f"{g}_{j}" for g in ("q", "tau") for j in joint_names]
    missing = [c for c in need if c not in header]
    if missing:
        raise RecordingError(f"{path}: missing columns {', '.join(missing)} (expected t, q_<joint>, "
                             f"tau_<joint>[, qd_<joint>] for joints {', '.join(joint_names)})")
    if data.ndim != 2 or len(data) < 2 or data.shape[1] != len(header):
        raise RecordingError(f"{path}: need at least 2 rows of {len(header)} values")
    if not np.all(np.isfinite(data)):
        r, c = np.argwhere(~np.isfinite(data))[0]
        raise RecordingError(f"{path}: NaN or Inf in column {header[c]!r}, row {r + 2}")
    col = {h: data[:, i] for i, h in enumerate(header)}
    t = col["t"]
    steps = np.diff(t)
    mean = (t[-1] - t[0]) / (len(t) - 1)
    bad = np.nonzero(~(np.abs(steps - mean) <= rtol * abs(mean)) | (steps <= 0))[0]
    if len(bad):
        k = bad[0]
        raise RecordingError(f"{path}: time stamps are not uniform: step {steps[k]:.6g} s between rows "
                             f"{k + 2} and {k + 3} (t = {t[k]:.6g}), mean step {mean:.6g} s")
    stack = lambda g: np.column_stack([col[f"{g}_{j}"] for j in joint_names])  # noqa: E731
    has_qd = all(f"qd_{j}" in col for j in joint_names)
    return Recording(t=t, q=stack("q"), tau=stack("tau"), qd=stack("qd") if has_qd else None,
                     joint_names=list(joint_names))
