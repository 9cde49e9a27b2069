"""Scenarios of the seed papers: `python -m codegen simulate NAME`.

Each module of this package defines ``SCENARIOS = {name: function}``; a function takes
``reference`` (bool: run observers with the numpy reference instead of the C) and ``out``
(a folder for the CSV and PNGs), and its own options if it has any (the mujoco-* scenarios:
quantization, noise, mismatch, T), and returns a summary dict (also printed). Scenarios only
describe experiments: blocks come from sim/blocks.py, figures from sim/plots.py; the studies
behind docs/ are in sim/studies.py and the benchmarks in codegen/evaluate/bench.py.
"""
from __future__ import annotations

import importlib
import inspect
import json
import pkgutil
import re
from pathlib import Path


def registry():
    """{name: scenario function}: the ``SCENARIOS`` of every public module of this package."""
    reg = {}
    for m in pkgutil.iter_modules(__path__):
        if not m.name.startswith("_"):
            reg.update(getattr(importlib.import_module(f"{__name__}.{m.name}"), "SCENARIOS", {}))
    return reg


def run(name, reference=False, out="build/sim", **options):
    """Run scenario ``name`` (or print the list for "list") and write its summary.json.

    Parameters
    ----------
    name : str
        A key of ``registry()``, or "list".
    reference : bool
        Run the observers with the numpy reference instead of the compiled C.
    out : path-like
        Parent folder; the scenario writes into ``out/<name>``.
    **options
        Options (e.g. quantization, noise, mismatch, T of the mujoco-* scenarios) of scenarios
        that take them; SystemExit for an option the scenario does not take.

    Returns
    -------
    int
        0 (the CLI's exit code).
    """
    reg = registry()
    if name == "list":
        natural = lambda s: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", s)]  # noqa: E731
        print("\n".join(sorted(reg, key=natural)))
        return 0
    if name not in reg:
        raise SystemExit(f"unknown scenario {name!r}; known: {', '.join(sorted(reg)) or '(none)'}")
    takes = inspect.signature(reg[name]).parameters
    extra = sorted(set(options) - set(takes))
    if extra:
        raise SystemExit(f"scenario {name!r} takes no option {', '.join('--' + k for k in extra)}")
    out = Path(out) / name
    out.mkdir(parents=True, exist_ok=True)
    summary = reg[name](reference=reference, out=out, **options)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    print(f"{name}:")
    for k, v in summary.items():
        print(f"  {k}: {v}")
    print(f"  files in {out}")
    return 0
