"""The one sequence every target goes through: design, emit, compile, then load.

``compile_observer`` (Python), ``jobs.make`` (`generate`, `build`, `check`) and the cross-check
all run ``make``; ``STAGES`` names its steps in order (``report`` hears each as it starts).

    made = make(target, out_dir)                  # Made(target, spec, folder, lib)
    obs = compile_observer(spec, dt=1e-3)         # make, then load: a CompiledObserver

A target whose substeps are "auto" (the default of the targets file, the CLI and
``compile_observer`` when no substeps are given) is resolved after the design into the fewest
stable sub-steps (``resolve_substeps``): the folder, its metadata and the C hold that number.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

from ..core.cache import work_dir
from ..core.target import AUTO, Target
from .compile import compile_library
from .emit import FolderTaken, check_folder, emit, resolve_substeps, with_params
from .load import load
from .targets_file import build_spec

STAGES = ("design", "emit", "compile")


@dataclass(frozen=True)
class Made:
    """What ``make`` produced: the target, its spec (parameters applied), the generated folder
    and the compiled library."""

    target: Target
    spec: object
    folder: Path
    lib: Path


def make(target, out_dir, *, spec=None, force=True, native=False, cflags=(), check=True,
         report=lambda stage: None):
    """Design (unless ``spec`` is given), emit and compile ``target`` into ``out_dir/<prefix>/``.

    Parameters
    ----------
    target : codegen.core.target.Target
    out_dir : path
        Parent folder of the generated folder.
    spec : codegen.core.spec.ObserverSpec, optional
        The spec ``target`` describes, when already built.
    force : bool
        Replace a folder generated from another target; False: raise FolderTaken, before the
        (slow) design, and at the swap if another build wrote one meanwhile. Never anything
        this tool did not generate (``codegen.pipeline.emit.check_folder``).
    native : bool
        Compile with -march=native.
    cflags : sequence of str
        Extra compiler flags.
    check : bool
        Refuse discretely unstable parameters (False: emit records "not checked"; for tests and
        benchmarks of the C alone).
    report : callable
        Called with each stage's name as it starts.

    Returns
    -------
    Made
    """
    folder = Path(out_dir) / target.prefix
    check_folder(folder, _as_recorded(folder, target), force=force)
    report("design")
    spec = with_params(spec if spec is not None else build_spec(target), target.params,
                       target.sources, target.build)
    target = resolve_substeps(target, spec)
    report("emit")
    emit(target, out_dir, spec=spec, force=force, check=check)
    report("compile")
    lib = compile_library(folder, native=native, extra_flags=cflags)
    # the folder's own record (the cache's copy may name the same C differently: a catalog name,
    # a URDF path; pipeline/compile.py keys the library by what it is made of)
    built = json.loads((folder / f"{target.prefix}.json").read_text())["target"]
    if built != json.loads(json.dumps(target.to_dict())):       # a concurrent --force build swapped its folder in
        raise FolderTaken(f"{folder} was replaced by another build while this one compiled it; "
                          "build again (one build per folder at a time)")
    return Made(target, spec, folder, lib)


def _as_recorded(folder, target):
    """``target`` as a folder generated from it records it: substeps "auto" compares as the number
    the folder holds (what it was resolved into), and so does an undeclared dt_max (the auto
    resolution may declare it), everything else as it is."""
    if target.discretization.substeps != AUTO:
        return target
    try:
        recorded = json.loads((Path(folder) / f"{Path(folder).name}.json").read_text())
        substeps = recorded["target"]["discretization"]["substeps"]
        dt_max = recorded["target"]["discretization"].get("dt_max")
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return target
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        return target
    if target.discretization.dt_max is not None or not isinstance(dt_max, (int, float)):
        dt_max = None
    try:
        return target.with_discretization(None, substeps=substeps, dt_max=dt_max)
    except ValueError:
        return target


def compile_observer(spec, discretization=None, *, dt=None, method=None, substeps=None, hold=None,
                     dt_min=None, dt_max=None, out_dir=None, prefix=None, native=False, inline="auto",
                     precision=None, cflags=(), check=True):
    """Emit, compile and load an observer as C.

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec or codegen.core.target.Target
        What to build (a Target is built into its spec first).
    discretization : codegen.core.target.Discretization or dict, optional
        How to step it; default ``codegen.core.target.DEFAULT_DISCRETIZATION`` with substeps
        "auto" (or the Target's own). ``dt``, ``dt_min``, ``dt_max`` (s), ``method``, ``substeps``
        and ``hold`` override single fields; ``substeps="auto"`` (the default when neither
        ``discretization`` nor ``substeps`` is given): the fewest substeps that make the discrete
        observer stable over the elapsed times [dt_min, dt_max] (``resolve_substeps``); a number:
        exactly that many, refused when unstable.
    out_dir : path, optional
        Where the generated folder goes (default build/targets/<digest of the target> in the
        working folder: one folder per target).
    prefix : str, optional
        Symbol prefix and folder name (default ``<robot>_<family>[_<variant>]``).
    native : bool
        Add -march=native.
    inline : "auto" or bool
        Code shape of the step (see codegen.discrete.discretize).
    precision : {"double", "float"}, optional
        Real type of the C (default "double", or the Target's own).
    cflags : sequence of str
        Extra compiler flags (e.g. ("-O1",) to compile a very large kernel quickly).
    check : bool
        Refuse a discretely unstable observer (the default); False skips the check and records
        it as not done (to test or time the C alone).

    Returns
    -------
    codegen.pipeline.load.CompiledObserver
        Loaded from the content-hash cache: compiling the same target twice costs one generation.
        Its ``spec`` is attached, so ``obs.params = ...`` runs the full stability check.

    Raises
    ------
    codegen.discrete.stability.UnstableDiscretization
        (a ValueError) when the discretised observer is unstable for its parameters, naming the
        gain, dt and the fix.
    """
    if substeps is None and discretization is None and not isinstance(spec, Target):
        substeps = AUTO
    over = dict(dt=dt, method=method, substeps=substeps, hold=hold, dt_min=dt_min, dt_max=dt_max)
    if isinstance(spec, Target):
        changes = {k: v for k, v in (("name", prefix), ("precision", precision)) if v is not None}
        changes.update({} if inline == "auto" else {"inline": inline})
        target = replace(spec.with_discretization(discretization, **over), **changes)
        spec = build_spec(target)
    else:
        target = spec.target(discretization, name=prefix, inline=inline, precision=precision or "double",
                             **over)
    if out_dir is None:
        from ..core.cache import key_digest
        # a folder per target: two targets under one prefix compiled at once (two processes, two
        # test workers, a float and a double build) never replace each other's folder mid-build
        out_dir = work_dir() / "targets" / key_digest(target.to_dict())[:16]
    made = make(target, out_dir, spec=spec, native=native, cflags=cflags, check=check)
    obs = load(made.folder, made.lib)
    obs.spec = spec
    return obs
