"""Observers generated as fast, verified C (DESIGN §1).

    from codegen import observers, compile_observer
    spec = observers.build("reduced_order", robot, eta=1.0, v_max=2.0)
    obs = compile_observer(spec, dt=1e-3, method="rk4")

Imports are lazy so that ``codegen.reference`` (numpy + pin only) never loads CasADi.
"""
__version__ = "0.1.0"


def compile_observer(spec, dt=1e-3, method="rk4", substeps=1, out_dir=None, prefix=None,
                     native=False, hold="zoh", inline="auto", cflags=()):
    """Emit, build and load ``spec`` as C; returns a CompiledObserver.

    The target goes to ``out_dir`` (default <repo>/build/targets) and the library to the
    content-hash cache, so compiling the same spec twice costs one generation only. ``cflags``
    are appended to the compiler flags (e.g. ("-O1",) to compile a very large kernel quickly)."""
    from .build import build, repo_root
    from .emit import emit
    from .runtime import load

    out_dir = out_dir or (repo_root() / "build" / "targets")
    target = emit(spec, out_dir, dt=dt, method=method, substeps=substeps, prefix=prefix, hold=hold,
                  inline=inline)
    return load(target, build(target, native=native, extra_flags=cflags))
