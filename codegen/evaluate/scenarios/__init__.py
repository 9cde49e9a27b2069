"""Scenarios of the seed papers: `python -m codegen simulate NAME`.

Each module of this package defines ``SCENARIOS = {name: function}`` (and ``DESCRIPTIONS =
{name: one line}``: the paper, the experiment, its figures, for `simulate list`); a function takes
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


def descriptions():
    """{name: one line}: each module's ``DESCRIPTIONS``, else the first clause of the scenario
    function's docstring."""
    out = {}
    for name, f in registry().items():
        module = importlib.import_module(f.__module__)
        text = getattr(module, "DESCRIPTIONS", {}).get(name)
        if text is None:
            first = " ".join((f.__doc__ or "").split()).replace("``", "")
            text = re.split(r"(?<=[a-z)]): |\. ", first)[0].rstrip(".")
        out[name] = text
    return out


def _natural(s):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", s)]


def run(name, reference=False, out="build/sim", **options):
    """Run scenario ``name`` (or print the list for "list", one line each) and write its
    summary.json; the summary is printed as indented ``name: value`` lines, a line per stage on
    stderr while it runs.

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
    from ...core.spec import report_lines
    from ..sim.blocks import stage_lines
    reg = registry()
    if name == "list":
        lines = descriptions()
        w = max(map(len, lines))
        print("\n".join(f"{k:{w}s}  {lines[k]}" for k in sorted(lines, key=_natural)))
        return 0
    if name not in reg:
        raise SystemExit(f"unknown scenario {name!r}; known: {', '.join(sorted(reg)) or '(none)'}")
    takes = inspect.signature(reg[name]).parameters
    extra = sorted(set(options) - set(takes))
    if extra:
        raise SystemExit(f"scenario {name!r} takes no option {', '.join('--' + k for k in extra)}")
    out = Path(out) / name
    out.mkdir(parents=True, exist_ok=True)
    print(f"{name}: {descriptions()[name]}", flush=True)
    from ..sim.plots import citing
    # a line per compile, closed loop and run (stderr); every figure cites the paper it reproduces
    with stage_lines(), citing(f"{name}: {descriptions()[name]}"):
        summary = reg[name](reference=reference, out=out, **options)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    print("\n".join(report_lines(json.loads(json.dumps(summary, default=float)), "  ")))
    print(f"  files in {out} (summary.json: every number in full)")
    return 0
