"""Stepped blocks of the simulator: the one place that decides compiled C or numpy reference.

Every observer, control law and plant of a scenario is a spec stepped under a stated
``Discretization``; ``block`` turns the pair into something with reset/step/estimate/state
(a ``CompiledObserver``, or the numpy ``ReferenceObserver`` with ``reference=True``), and
``bind`` gives the simulation loops buffer-bound step/estimate calls for either kind.
"""
from __future__ import annotations

import contextlib
import sys
import time

# RHS instructions above which a kernel is compiled with HUGE_FLAGS. -O1 keeps IEEE arithmetic
# (no -ffast-math, -ffp-contract=off): the same estimates to the bit, only the compile time and
# the run time change. ~100k instructions (I&I on ur5): -O3 takes > 8 min, -O1 about one;
# kalman_model's model variant on panda (8.2k; ur5 5.8k): gcc 36 -> 16 s of CPU and its run over
# a 10 s log 0.15 -> 0.09 s; the other families on panda (1.8-1.9k) run up to 2x slower at -O1
# (extended_state) and keep -O3.
HUGE_KERNEL = 4_000
HUGE_FLAGS = ("-O1",)


_started = None            # perf_counter() at the start of stage_lines, None outside


@contextlib.contextmanager
def stage_lines():
    """While inside, ``stage(text)`` prints a line on stderr with the seconds since entering (what
    `simulate` shows of a long scenario: each compile, closed loop and observer run)."""
    global _started
    outer, _started = _started, time.perf_counter()
    try:
        yield
    finally:
        _started = outer


def stage(text):
    """One progress line ``[  12.3 s] text`` on stderr inside ``stage_lines``, else nothing."""
    if _started is not None:          # through tqdm: a progress bar on the terminal stays whole
        from tqdm import tqdm
        tqdm.write(f"  [{time.perf_counter() - _started:6.1f} s] {text}", file=sys.stderr)


def staged():
    """True inside ``stage_lines`` (loops then show a progress bar too)."""
    return _started is not None


def compiler_flags(spec):
    """Extra compiler flags for a spec's kernel: HUGE_FLAGS above HUGE_KERNEL RHS instructions.

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec

    Returns
    -------
    tuple of str
    """
    return HUGE_FLAGS if spec.rhs.n_instructions() > HUGE_KERNEL else ()


def block(spec, disc, *, reference=False, prefix=None, inline="auto", out_dir=None):
    """A spec as a stepped block: compiled C (default) or the numpy reference.

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec
        Observer, control law or plant.
    disc : codegen.core.target.Discretization
        How it is stepped (dt in s, method, hold, substeps); stated by every caller, never
        the library default. substeps "auto": the fewest stable ones
        (codegen.discrete.stability.auto_substeps), for the C and the reference alike.
    reference : bool
        True: ``codegen.reference.reference_observer`` (numpy + pin), else emitted C.
    prefix : str, optional
        Symbol prefix of the C (two variants of one family in one run need two).
    inline : "auto" or bool
        Code shape of the C step (codegen.discrete.discretize).
    out_dir : path, optional
        Folder of the generated target (default: compile_observer's, one per target under build/targets).

    Returns
    -------
    codegen.pipeline.load.CompiledObserver or codegen.reference.ReferenceObserver
    """
    from ...core.target import Discretization
    if not isinstance(disc, Discretization):
        raise TypeError(f"disc must be a codegen.core.target.Discretization, got {type(disc).__name__}")
    stage(f"{'numpy reference of' if reference else 'compiling'} {prefix or spec.family} on "
          f"{spec.robot.name} (dt {disc.dt:g} s)")
    if disc.substeps == "auto":
        from ...discrete.stability import auto_substeps
        disc = auto_substeps(spec, disc)
    if reference:
        from ...reference import reference_observer
        return reference_observer(spec, disc)
    from ...pipeline.stages import compile_observer
    return compile_observer(spec, disc, prefix=prefix, inline=inline, out_dir=out_dir,
                            cflags=compiler_flags(spec))


def bind(block, y, u, est):
    """(step, estimate): calls without arguments that read the buffers ``y``, ``u`` and write
    the block's estimate into ``est[:nest]``.

    A compiled block calls its C entry points on the buffers (no per-call allocation or checks;
    a non-zero C status still raises); the reference calls its methods on ``y[:ny]``, ``u[:nu]``.
    """
    if hasattr(block, "bind"):
        return block.bind(y, u, est)
    ny, nu, nest = block.ny, block.nu, block.nest

    def step():
        est[:nest] = block.step(y[:ny], u[:nu])

    def estimate():
        est[:nest] = block.estimate(y[:ny], u[:nu])
    return step, estimate
