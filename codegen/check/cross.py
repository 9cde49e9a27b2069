"""The cross-check: compiled C against the independent reference, on random inputs and a run.

Owned by neither side: it imports the pipeline (``compile_observer``) and the reference, and
compares them with ``measure.relative_error``.
"""
from __future__ import annotations

import numpy as np

from .. import compile_observer
from ..reference import reference_observer
from ..target import discretization as as_discretization
from .inputs import random_inputs, run_inputs
from .measure import relative_error


def cross_check(spec, discretization=None, count=1000, seed=0, **overrides):
    """Worst relative errors of the compiled C against the independent reference (DESIGN §3).

    From each of ``count`` random (x, y, u) (``random_inputs``): two samples (the second with
    another random y, u, so a first-order hold integrates a real interval), comparing estimates
    and states; the RHS at (x, y, u); and a run of ``count`` samples along the built-in
    trajectory with noise (y = q, u = tau families) or on random inputs (the others).

    Parameters
    ----------
    spec : codegen.spec.ObserverSpec
    discretization : codegen.target.Discretization or dict, optional
        Default: codegen.target.DEFAULT_DISCRETIZATION; ``overrides`` (dt in s, method,
        substeps, hold) replace single fields.
    count : int
        Random samples, and the length of the run.
    seed : int

    Returns
    -------
    dict
        "step_est", "step_state", "rhs", "run": worst relative error (``relative_error``,
        NaN if anything is not finite); "samples": ``count``.
    """

    disc = as_discretization(discretization, **overrides)
    dt = disc.dt
    obs = compile_observer(spec, disc)
    ref = reference_observer(spec, disc)
    X, Y, U = random_inputs(spec, count, seed)
    _, Y2, U2 = random_inputs(spec, count, seed + 7)
    errs = {"step_est": [], "step_state": [], "rhs": []}
    for x, y, u, y2, u2 in zip(X, Y, U, Y2, U2):
        for o in (obs, ref):
            o.reset(y)
            o.state = x
        for yk, uk in ((y, u), (y2, u2)):
            errs["step_est"].append(relative_error(obs.step(yk, uk), ref.step(yk, uk)))
            errs["step_state"].append(relative_error(obs.state, ref.state))
        errs["rhs"].append(relative_error(obs.rhs(x, y, u), ref.rhs(x, y, u)))
    worst = {k: float(np.max(v)) for k, v in errs.items()}  # np.max keeps a NaN: it must fail
    Yn, Un = run_inputs(spec, count, dt, seed)
    obs.reset(Yn[0]), ref.reset(Yn[0])
    worst["run"] = relative_error(obs.run(Yn, Un), ref.run(Yn, Un))
    worst["samples"] = count
    return worst
