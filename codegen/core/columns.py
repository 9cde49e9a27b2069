"""The one CSV module: header + rows of numbers, written exactly (shortest round-trip decimal
form) and atomically (a temporary file, then a rename), read back with every problem named by
file, row and column. A recorded run (codegen.logs.recording), the C harness's input and output and
a simulation's log are all such files.
"""
from __future__ import annotations

import csv
import os
from decimal import Decimal, InvalidOperation
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


CHUNK = 65536                   # rows parsed at once (a log is read in blocks of this many)
MAX_BYTES_ENV = "CODEGEN_MAX_LOG_BYTES"
MAX_BYTES = 2 ** 30             # the largest file read (1 GiB; the env variable above overrides it)


def max_bytes(limit=None):
    """The largest column file ``read_columns`` reads (bytes): ``limit``, else the environment's
    ``CODEGEN_MAX_LOG_BYTES``, else MAX_BYTES (1 GiB: its numbers, as float64, take about its size
    again in memory; a larger log is refused before it is read)."""
    if limit is not None:
        return int(limit)
    text = os.environ.get(MAX_BYTES_ENV)
    try:
        return int(float(text)) if text else MAX_BYTES
    except ValueError:
        raise ValueError(f"{MAX_BYTES_ENV}: expected a number of bytes, got {text!r}") from None


def _open(path, error, limit):
    """The checked ``path`` of a column file (exists, at most ``max_bytes(limit)``) or ``error``."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{path}: no such file")
    size, top = path.stat().st_size, max_bytes(limit)
    if size > top:
        raise error(f"{path}: {size / 1e6:.1f} MB, more than the {top / 1e6:.1f} MB a log may have "
                    f"(cut it, or raise the limit: {MAX_BYTES_ENV}=<bytes>)")
    return path


def read_header(path, error=ColumnsError, limit=None):
    """The names of the first row of the CSV file ``path`` (``error`` and ``limit`` as ``read_columns``)."""
    path = _open(path, error, limit)
    with open(path, newline="") as f:
        first = next(csv.reader(f), None)
    if first is None:
        raise error(f"{path}: empty file")
    return [h.strip() for h in first]


def read_columns(path, error=ColumnsError, limit=None, keep=None, origin=None):
    """(header, data): the names of the first row of the CSV file ``path`` and the numbers below
    it, (N, columns) float64 (N may be 0). Raises ``error`` (an exception class) naming the file
    for a missing or empty file, a file larger than ``max_bytes(limit)`` (its size and the limit,
    before reading it), a non-numeric value (its row and column) or a ragged row. The rows are
    parsed ``CHUNK`` at a time into float64 blocks: a long log never sits in memory as text.

    ``keep`` (names of the header): only these columns are parsed and returned, in this order
    (the others may hold text). ``origin`` (names among them): each is returned as its value minus
    its first row's, computed exactly from the digits and then rounded once (stamps of 1.7e18 ns,
    or 1.7e9 s with microseconds, keep every digit that float64 would lose)."""
    path = _open(path, error, limit)
    with open(path, newline="") as f:
        reader = csv.reader(f)
        first = next(_rows(reader, path, error), None)
        if first is None:
            raise error(f"{path}: empty file")
        header = [h.strip() for h in first]
        names = header if keep is None else list(keep)
        absent = [k for k in names if k not in header]
        if absent:
            raise error(f"{path}: no column {', '.join(map(repr, absent))}")
        index = [header.index(k) for k in names]
        origin = origin or {}
        exact = [i for i, k in enumerate(names) if k in origin]
        blocks, chunk, lines, zero = [], [], [], {}
        for r in _rows(reader, path, error):
            if not r:
                continue
            if len(r) != len(header):
                raise error(f"{path}: row {reader.line_num} has {len(r)} values, the header {len(header)}")
            r = [r[i] for i in index] if keep is not None else r
            for i in exact:
                r[i] = _difference(path, names[i], r[i], zero, origin[names[i]], reader.line_num, error)
            chunk.append(r)
            lines.append(reader.line_num)
            if len(chunk) == CHUNK:
                blocks.append(_numbers(path, names, chunk, lines, error))
                chunk, lines = [], []
        if chunk or not blocks:
            blocks.append(_numbers(path, names, chunk, lines, error))
    return names, np.concatenate(blocks) if len(blocks) > 1 else blocks[0]


def _difference(path, name, text, zero, divisor, line, error):
    """(``text`` - the first row's value of column ``name``, kept in ``zero``) / ``divisor``,
    exactly, as a float; ``error`` naming the row and column for a value that is not a finite
    number."""
    try:
        value = Decimal(text.strip())
    except InvalidOperation:
        raise error(f"{path}: row {line}, column {name!r}: {text.strip()!r} is not a number") from None
    if not value.is_finite():
        raise error(f"{path}: row {line}, column {name!r}: {text.strip()!r} is not a finite number")
    return float((value - zero.setdefault(name, value)) / Decimal(divisor))


def _rows(reader, path, error):
    """The rows of the csv ``reader`` of ``path``; ``error`` naming the row (its line) where the
    csv module refuses the text (a field over its limit, e.g. a NUL-padded tail; a NUL byte)."""
    while True:
        try:
            r = next(reader)
        except StopIteration:
            return
        except csv.Error as e:
            raise error(f"{path}: row {reader.line_num}: not a CSV row ({e}); a damaged or padded "
                        "tail (cut the file at its last good row)") from None
        yield r


def _numbers(path, header, rows, lines, error):
    """(len(rows), len(header)) float64 of the text ``rows`` (file lines ``lines``), or ``error``
    naming the first value that is not a number: its row and column."""
    try:
        return np.array(rows, dtype=float).reshape(len(rows), len(header))
    except ValueError:
        for r, line in zip(rows, lines):
            for name, v in zip(header, r):
                try:
                    float(v)
                except ValueError:
                    raise error(f"{path}: row {line}, column {name!r}: {v.strip()!r} is not a number") from None
        raise
