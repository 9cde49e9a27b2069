"""The one CSV module: header + rows of numbers, written exactly (shortest round-trip decimal
form) and atomically (a temporary file, then a rename), read back with every problem named by
file, row and column. A recorded run (codegen.logs.recording), the C harness's input and output and
a simulation's log are all such files.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np


class ColumnsError(ValueError):
    """A column file that cannot be read (the message names the file and what is wrong)."""


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


def read_columns(path, error=ColumnsError):
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
