"""Results that survive anything: a Parquet dataset, one file per batch, written atomically.

    <out>/sweep.toml (or sweep.json)   the sweep file as given
    <out>/fingerprints.json            fingerprint id -> targets' sha256 and metadata, code version
    <out>/results/part-<id>.parquet    the rows of one batch (temp file ``.part-<id>.tmp``, then
                                       rename: a file is complete or absent)
    <out>/.lock                        held (flock) by the one sweep writing the folder

Open with ``pandas.read_parquet(<out>/results)`` (files starting with "." are ignored) or
``Store(out).read()``. A cell's row is keyed by its id (column ``cell``); ``done()`` is the set of
ids on disk, so a restarted sweep computes only the others.

One writer per folder: ``lock()`` takes an exclusive ``fcntl.flock`` on ``<out>/.lock`` for the
whole run and a second sweep on the same folder is refused (``FolderBusy``) instead of writing
every cell again. Every part is checked against the row schema (``schema``) before it is read:
a Parquet file of another sweep or tool in ``results/`` is refused naming it (``ForeignPart``).
"""
from __future__ import annotations

import json
import os
from contextlib import contextmanager
from pathlib import Path

from .plan import AXES, digest

METRICS = (("rms", "float64"), ("max", "float64"), ("t_conv", "float64"), ("gain", "float64"),
           ("lag", "float64"), ("diverged", "bool"))


LOCK = ".lock"


class FolderBusy(ValueError):
    """Another sweep holds the output folder's lock."""


class ForeignPart(ValueError):
    """A Parquet file in results/ whose columns are not a sweep's rows (``schema``)."""


def schema(gains):
    """The Arrow schema of a row: ids, axes, gain-axis columns (one float64 column per name in
    ``gains``), metrics, runtime params (JSON), note, fingerprint, worker and CPU seconds."""
    import pyarrow as pa
    types = {"float64": pa.float64(), "bool": pa.bool_()}
    cols = [("cell", pa.string()), ("method", pa.string()), ("kind", pa.string()), ("family", pa.string())]
    cols += [(a, pa.int64() if a == "seed" else pa.float64()) for a in AXES]
    cols += [(g, pa.float64()) for g in gains]
    cols += [(m, types[t]) for m, t in METRICS]
    cols += [("params", pa.string()), ("note", pa.string()), ("fingerprint", pa.string()),
             ("worker", pa.int64()), ("cpu_s", pa.float64())]
    return pa.schema(cols)


class Store:
    """The output folder of a sweep (see the module docstring)."""

    def __init__(self, out):
        self.out = Path(out)
        self.results = self.out / "results"

    @contextmanager
    def lock(self):
        """Hold the folder's lock (an exclusive ``fcntl.flock`` on ``<out>/.lock``, released when
        the block ends or the process dies) for the block; FolderBusy (one line, naming the holder's
        pid) when another sweep holds it."""
        import fcntl
        self.out.mkdir(parents=True, exist_ok=True)
        path = self.out / LOCK
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
                raise FolderBusy(f"{self.out} is being written by another sweep (pid {holder}, lock {path}): "
                                 "wait for it to finish, or give another --out") from None
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
            yield self
        finally:
            os.close(fd)                   # releases the lock

    def parts(self, gains=None):
        """The finished result files (``part-*.parquet``), sorted, each checked to hold a sweep's
        rows: the columns of ``schema(gains)``, or with ``gains`` None those of ``schema`` with the
        part's own gain columns; ForeignPart names the first that does not."""
        import pyarrow.parquet as pq
        parts = sorted(self.results.glob("part-*.parquet"))
        fixed = set(schema(()).names)
        for f in parts:
            try:
                got = pq.read_schema(f).remove_metadata()
            except (OSError, ValueError) as e:           # not Parquet at all (ArrowInvalid is a ValueError)
                raise ForeignPart(f"{f}: not a sweep's results ({e}); move it out of {self.results}") from None
            want = schema(gains if gains is not None else [n for n in got.names if n not in fixed])
            if not got.equals(want):
                raise ForeignPart(f"{f}: not a part of this sweep: {_difference(got, want)}; move it out "
                                  f"of {self.results}, or give another --out")
        return parts

    def done(self, gains=None):
        """Ids of the cells on disk (a set); the parts checked as ``parts(gains)``."""
        import pyarrow.parquet as pq
        return {c for f in self.parts(gains) for c in pq.read_table(f, columns=["cell"]).column("cell").to_pylist()}

    def write(self, rows, gains, fingerprint):
        """Write a batch's rows as one Parquet file, atomically.

        Parameters
        ----------
        rows : list of dict
            Rows of ``work.run_batch`` (cell, axes, p, metrics, params, ...).
        gains : sequence of str
            Gain-axis columns (``schema``), taken from each row's p.
        fingerprint : str
            Fingerprint id (``start``) stored on every row.

        Returns
        -------
        Path
            ``results/part-<digest of the cell ids>.parquet``."""
        import pyarrow as pa
        import pyarrow.parquet as pq
        self.results.mkdir(parents=True, exist_ok=True)
        data = []
        for r in rows:
            d = {k: r.get(k) for k in schema(gains).names}
            d.update({g: r["p"].get(g) for g in gains},
                     params=json.dumps(r["params"], sort_keys=True, default=float),
                     fingerprint=fingerprint)
            data.append(d)
        path = self.results / f"part-{digest(sorted(r['cell'] for r in rows))}.parquet"
        tmp = self.results / f".{path.stem}.tmp"
        pq.write_table(pa.Table.from_pylist(data, schema=schema(gains)), tmp)
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
        return path

    def read(self):
        """All rows as a pandas DataFrame (empty if none), sorted by cell id."""
        import pandas as pd
        parts = self.parts()
        if not parts:
            return pd.DataFrame()
        return pd.concat([pd.read_parquet(f) for f in parts], ignore_index=True) \
            .sort_values("cell", kind="stable").reset_index(drop=True)

    def start(self, sweep, fingerprint):
        """Record the sweep file and a fingerprint (kept beside earlier ones); remove temp files
        of a killed writer. Returns the fingerprint's id."""
        self.results.mkdir(parents=True, exist_ok=True)
        for f in self.results.glob(".part-*.tmp"):
            f.unlink()
        name = "sweep.json" if sweep.source.lstrip().startswith("{") else "sweep.toml"
        _atomic_text(self.out / name, sweep.source)
        fid = digest(fingerprint, 12)
        known = self.fingerprints()
        if fid not in known:
            self.put("fingerprints.json", {**known, fid: fingerprint})
        return fid

    def put(self, name, value):
        """Write JSON ``value`` beside the results as the file ``name`` (atomically)."""
        _atomic_text(self.out / name, json.dumps(value, indent=1, sort_keys=True, default=float) + "\n")

    def get(self, name, default=None):
        """The JSON file ``name`` beside the results, or ``default``."""
        try:
            return json.loads((self.out / name).read_text())
        except FileNotFoundError:
            return default

    def fingerprints(self):
        """Fingerprint id -> fingerprint of every run so far (fingerprints.json, {} if none)."""
        return self.get("fingerprints.json", {})


def _difference(got, want):
    """What the Arrow schema ``got`` lacks, adds or types differently from ``want``, in words."""
    def names(xs):
        return ", ".join(xs[:5]) + (f", ... ({len(xs)})" if len(xs) > 5 else "")
    have, need = {x.name: x.type for x in got}, {x.name: x.type for x in want}
    words = [f"missing columns {names([n for n in need if n not in have])}" if set(need) - set(have) else "",
             f"unexpected columns {names([n for n in have if n not in need])}" if set(have) - set(need) else "",
             "; ".join(f"column {n} is {have[n]}, not {t}" for n, t in need.items() if n in have and have[n] != t)]
    return "; ".join(w for w in words if w) or "its columns are in another order"


def _atomic_text(path, text):
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
