"""Results that survive anything: a Parquet dataset, one file per batch, written atomically.

    <out>/sweep.toml (or sweep.json)   the sweep file as given
    <out>/fingerprints.json            fingerprint id -> targets' sha256 and metadata, code version
    <out>/results/part-<id>.parquet    the rows of one batch (temp file ``.part-<id>.tmp``, then
                                       rename: a file is complete or absent)

Open with ``pandas.read_parquet(<out>/results)`` (files starting with "." are ignored) or
``Store(out).read()``. A cell's row is keyed by its id (column ``cell``); ``done()`` is the set of
ids on disk, so a restarted sweep computes only the others.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from .plan import AXES, digest

METRICS = (("rms", "float64"), ("max", "float64"), ("t_conv", "float64"), ("gain", "float64"),
           ("lag", "float64"), ("diverged", "bool"))


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

    def parts(self):
        """The finished result files (``part-*.parquet``), sorted."""
        return sorted(self.results.glob("part-*.parquet"))

    def done(self):
        """Ids of the cells on disk (a set)."""
        import pyarrow.parquet as pq
        return {c for f in self.parts() for c in pq.read_table(f, columns=["cell"]).column("cell").to_pylist()}

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


def _atomic_text(path, text):
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
