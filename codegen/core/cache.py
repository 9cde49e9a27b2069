"""Where cached results live, and a small JSON memo on disk (no CasADi, no symbolic code).

    work_dir()                          $CODEGEN_BUILD, else build/ in the working folder
    cache_dir()                          $CODEGEN_CACHE, else work_dir()/cache
    package_data(name)                   a folder or file shipped with the package (c_harness, ...)
    cached_json(kind, key, compute)      compute() once per JSON key, kept in <cache>/<kind>/

Used by the compiles (codegen.pipeline.compile), the gain design (codegen.families.design) and the discrete
stability check (codegen.discrete.stability): each keys its entries by everything the result depends on
(content digests, fingerprints, inputs, a version of its own code).
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path


def work_dir():
    """Where outputs go unless told otherwise: $CODEGEN_BUILD, else ``build/`` in the working
    folder (never the package's own folder, which is read-only data once installed)."""
    return Path(os.environ.get("CODEGEN_BUILD") or "build").resolve()


def cache_dir():
    """$CODEGEN_CACHE, else ``work_dir()/cache``."""
    return Path(os.environ.get("CODEGEN_CACHE") or work_dir() / "cache").resolve()


def package_data(name):
    """A data folder or file shipped with the package: ``codegen/<name>`` once installed (package
    data), ``<checkout>/<name>`` in a source checkout (e.g. "c_harness").

    Parameters
    ----------
    name : str
        Path relative to the package (or to the checkout).
    """
    here = Path(__file__).resolve().parents[1]          # the codegen package
    for path in (here / name, here.parent / name):
        if path.exists():
            return path
    raise FileNotFoundError(f"package data {name!r} not found in {here} or {here.parent}")


def key_digest(key):
    """sha256 hex digest of a JSON-able key (dicts with sorted keys)."""
    return hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()


def cached_json(kind, key, compute):
    """``compute()`` (JSON-able) once per ``key``: read from ``<cache>/<kind>/<digest>.json`` when
    there, else computed and written atomically (a concurrent writer can only replace it by the
    same content). An unreadable entry is recomputed; an entry that cannot be written (no
    space, no permission) is skipped, nothing half-written left: the value is still returned."""
    path = cache_dir() / kind / f"{key_digest(key)[:32]}.json"
    try:
        return json.loads(path.read_text())["value"]
    except (OSError, ValueError, KeyError):
        pass
    value = json.loads(json.dumps(compute(), allow_nan=True))   # plain JSON data, or TypeError
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".", suffix=".json", dir=path.parent)
        with os.fdopen(fd, "w") as fh:
            json.dump({"key": key, "value": value}, fh, default=str)
        os.replace(tmp, path)
    except OSError:               # a memo only: computed again next time
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
    return value
