"""Observers generated as fast, verified C (docs/architecture.md §1).

    from codegen import observers, compile_observer, load
    spec = observers.build("reduced_order", robot, quantization=1e-4)   # noise-aware k0
    obs = compile_observer(spec, dt=1e-3)          # expmid1 (the model once per step), first-order hold: unbiased, checked stable
    obs = load("generated/ur5_reduced_order")      # a folder `build` or `generate` wrote

Imports are lazy so that ``codegen.reference`` (numpy + pin only) never loads CasADi.
"""
import os

# One BLAS thread per process, unless the caller chose: our matrices are small (a few joints), and
# on a shared machine OpenBLAS's threads wait on each other (an 8x8 solve 1 ms -> 31 ms, a 200x200
# product 0.5 -> 35 ms under load: docs/guide/speed.md). Read when numpy first loads, so set here,
# before any module imports it; parallel work is by processes (pytest -n, generate -j, Dask).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from .core.version import __version__  # noqa: E402,F401

# name -> (module, attribute or None for the module itself): imported on first use
_LAZY = {"observers": ("codegen.families.observers", None),
         "controllers": ("codegen.families.controllers", None),
         "compile_observer": ("codegen.pipeline.stages", "compile_observer"),
         "load": ("codegen.pipeline.load", "load"),
         "build_spec": ("codegen.pipeline.targets_file", "build_spec")}
__all__ = ["__version__", *_LAZY]


def __getattr__(name):
    """``codegen.observers``, ``codegen.controllers`` (the family packages), ``compile_observer``
    (codegen.pipeline.stages), ``load`` (codegen.pipeline.load) and ``build_spec``
    (codegen.pipeline.targets_file), imported on first use."""
    if name not in _LAZY:
        raise AttributeError(f"module 'codegen' has no attribute {name!r}")
    import importlib
    module, attr = _LAZY[name]
    value = importlib.import_module(module)
    return value if attr is None else getattr(value, attr)
