"""Observers generated as fast, verified C (DESIGN §1).

    from codegen import observers, compile_observer
    spec = observers.build("reduced_order", robot, quantization=1e-4)   # noise-aware k0
    obs = compile_observer(spec, dt=1e-3)          # ETD-RK4, first-order hold: unbiased, checked stable

Imports are lazy so that ``codegen.reference`` (numpy + pin only) never loads CasADi.
"""
from .version import __version__  # noqa: F401


def build_spec(target):
    """The ObserverSpec that ``target`` (a codegen.target.Target) describes: see
    ``codegen.targets.build_spec``."""
    from .targets import build_spec as _build_spec
    return _build_spec(target)


def compile_observer(spec, discretization=None, *, dt=None, method=None, substeps=None, hold=None,
                     out_dir=None, prefix=None, native=False, inline="auto", precision=None, cflags=()):
    """Emit, build and load an observer as C.

    Parameters
    ----------
    spec : codegen.spec.ObserverSpec or codegen.target.Target
        What to build (a Target is built into its spec first).
    discretization : codegen.target.Discretization or dict, optional
        How to step it; default ``codegen.target.DEFAULT_DISCRETIZATION`` (or the Target's own).
        ``dt`` (s), ``method``, ``substeps`` and ``hold`` override single fields;
        ``substeps="auto"``: the fewest substeps that make the discrete observer stable.
    out_dir : path, optional
        Where the generated folder goes (default build/targets in the working folder).
    prefix : str, optional
        Symbol prefix and folder name (default ``<robot>_<family>[_<variant>]``).
    native : bool
        Add -march=native.
    inline : "auto" or bool
        Code shape of the step (see codegen.discretize).
    precision : {"double", "float"}, optional
        Real type of the C (default "double", or the Target's own).
    cflags : sequence of str
        Extra compiler flags (e.g. ("-O1",) to compile a very large kernel quickly).

    Returns
    -------
    codegen.runtime.CompiledObserver
        Loaded from the content-hash cache: compiling the same target twice costs one generation.
        Its ``spec`` is attached, so ``obs.params = ...`` runs the full stability check.

    Raises
    ------
    codegen.stability.UnstableDiscretization
        (a ValueError) when the discretised observer is unstable for its parameters, naming the
        gain, dt and the fix.
    """
    from dataclasses import replace

    from .build import build, build_dir
    from .emit import emit, with_params
    from .runtime import load
    from .stability import auto_substeps
    from .target import Target

    auto = substeps == "auto"
    over = dict(dt=dt, method=method, substeps=None if auto else substeps, hold=hold)
    if isinstance(spec, Target):
        changes = {k: v for k, v in (("name", prefix), ("precision", precision)) if v is not None}
        changes.update({} if inline == "auto" else {"inline": inline})
        target = replace(spec.with_discretization(discretization, **over), **changes)
        spec = build_spec(target)
    else:
        target = spec.target(discretization, name=prefix, inline=inline, precision=precision or "double",
                             **over)
    if auto:
        checked = with_params(spec, target.params) if target.params else spec
        target = replace(target, discretization=auto_substeps(checked, target.discretization))
    out_dir = out_dir or (build_dir() / "targets")
    folder = emit(target, out_dir, spec=spec)
    obs = load(folder, build(folder, native=native, extra_flags=cflags))
    obs.spec = spec
    return obs
