"""The cross-check: compiled C against the independent reference, on random inputs and a run.

Owned by neither side: it imports the pipeline (``compile_observer``) and the reference, and
compares them with ``measure.relative_error``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..pipeline.stages import compile_observer
from ..reference import reference_observer
from ..core.target import discretization as as_discretization
from .inputs import jittered_stamps, random_inputs, run_inputs
from .measure import relative_error


def cross_check(spec, discretization=None, count=1000, seed=0, folder=None, **overrides):
    """Worst relative errors of the compiled C against the independent reference (docs/architecture.md §3).

    From each of ``count`` random (x, y, u) (``random_inputs``): two samples (the second with
    another random y, u, so a first-order hold integrates a real interval), comparing estimates
    and states; from the same (x, y, u) again, one sample after a random elapsed time (``step_dt``:
    uniform in [dt_min, dt_max], one in five in (dt_max, 2 dt_max], split into two sub-intervals)
    a twentieth of the way from (y, u) to another random one (two unrelated random measurements
    an interval apart are a velocity of thousands of rad/s, a flow stiffer than the sub-steps
    of dt_max integrate: both sides then diverge alike and compare nothing; longer gaps are
    covered by the jittered run); the RHS at (x, y, u); and a run of
    ``count`` samples along the built-in trajectory with noise (y = q, u = tau families) or on
    random inputs (the others), at the designed rate and over jittered time stamps
    (``jittered_stamps``: 0.7-1.6 dt, every 100th interval 10 dt).

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec
    discretization : codegen.core.target.Discretization or dict, optional
        Default: codegen.core.target.DEFAULT_DISCRETIZATION; ``overrides`` (dt in s, method,
        substeps, hold) replace single fields.
    count : int
        Random samples, and the length of the run.
    seed : int
    folder : path, optional
        A folder ``codegen.pipeline.emit`` generated from ``spec``: its C is checked against the
        reference rebuilt from its metadata JSON alone (discretisation and parameters as
        recorded), instead of compiling ``spec``.

    Returns
    -------
    dict
        "step_est", "step_state", "step_dt_est", "step_dt_state", "rhs", "run", "run_t": worst
        relative error (``relative_error``, NaN if anything is not finite); "samples": ``count``.
    """

    if folder is None:
        disc = as_discretization(discretization, **overrides)
        obs, ref = compile_observer(spec, disc), reference_observer(spec, disc)
    else:
        from ..pipeline.compile import compile_library
        from ..pipeline.load import load
        folder = Path(folder)
        obs = load(folder, compile_library(folder))
        ref = reference_observer(json.loads((folder / f"{folder.name}.json").read_text()))
        disc = ref.disc
    dt = disc.dt
    X, Y, U = random_inputs(spec, count, seed)
    _, Y2, U2 = random_inputs(spec, count, seed + 7)
    _, Y3, U3 = random_inputs(spec, count, seed + 11)
    lo, hi = disc.dt_range
    rng = np.random.default_rng(seed + 13)
    H = np.where(rng.uniform(size=count) < 0.8, rng.uniform(lo, hi, count), rng.uniform(hi, 2 * hi, count))
    errs = {"step_est": [], "step_state": [], "step_dt_est": [], "step_dt_state": [], "rhs": []}
    for x, y, u, y2, u2, y3, u3, h in zip(X, Y, U, Y2, U2, Y3, U3, H):
        for o in (obs, ref):
            o.reset(y)
            o.state = x
        for yk, uk in ((y, u), (y2, u2)):
            errs["step_est"].append(relative_error(obs.step(yk, uk), ref.step(yk, uk)))
            errs["step_state"].append(relative_error(obs.state, ref.state))
        y3, u3 = y + 0.05 * (y3 - y), u + 0.05 * (u3 - u)
        for o in (obs, ref):
            o.reset(y)
            o.state = x
            o.step(y, u)
        errs["step_dt_est"].append(relative_error(obs.step(y3, u3, h), ref.step(y3, u3, h)))
        errs["step_dt_state"].append(relative_error(obs.state, ref.state))
        errs["rhs"].append(relative_error(obs.rhs(x, y, u), ref.rhs(x, y, u)))
    worst = {k: float(np.max(v)) for k, v in errs.items()}  # np.max keeps a NaN: it must fail
    Yn, Un = run_inputs(spec, count, dt, seed)
    obs.reset(Yn[0]), ref.reset(Yn[0])
    worst["run"] = relative_error(obs.run(Yn, Un), ref.run(Yn, Un))
    t = jittered_stamps(count, dt, seed)
    obs.reset(Yn[0]), ref.reset(Yn[0])
    worst["run_t"] = relative_error(obs.run(Yn, Un, t), ref.run(Yn, Un, t))
    worst["samples"] = count
    return worst
