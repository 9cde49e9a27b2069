"""Random cross-check inputs, drawn where each family declares them (``spec.inputs``, an
``codegen.options.InputRanges``: data, never a hook into the family's module)."""
from __future__ import annotations

import numpy as np

from ..sampling import declared_slots, measurements, slot_index
from ..trajectory import demo_trajectory


def random_inputs(spec, count, seed=0):
    """Random (X, Y, U) for a cross-check, at the physical scales the family declares.

    y: configurations in the joint ranges (rad; fixed plus jitter when ``y_jitter``), then the
    ``y_extra`` slots; u: around g(y), scaled by |g(y)| or plain (N m); x: init(y, est, p) plus a
    perturbation, with the declared about-y, uniform, normal and integer slots.

    Parameters
    ----------
    spec : codegen.spec.ObserverSpec
        Its ``inputs`` (codegen.options.InputRanges), robot (``sample_configurations``,
        ``g``), ``init`` and slot names are read.
    count : int
        Number of draws N.
    seed : int
        Seed of the draws (the configurations of a ``y_jitter`` family are fixed).

    Returns
    -------
    X : (N, nx) array
    Y : (N, ny) array
    U : (N, nu) array
    """
    rng = np.random.default_rng(seed)
    Y, U = measurements(spec, count, seed, rng)
    return _states(spec, spec.inputs, Y, rng), Y, U


def _states(spec, ir, Y, rng):
    """x (N, nx): init(y, est, p) + N(0, x_scale^2), then the declared slots."""
    count = Y.shape[0]
    p = spec.p_default.copy()
    for name, value in ir.init_p:
        p[slot_index(spec, spec.p_names, name)] = value
    EST = ir.est_scale * rng.normal(size=(count, spec.nest))
    X0 = np.asarray(spec.init.map(count)(Y.T, EST.T, np.tile(p[:, None], count))).T.reshape(count, spec.nx)
    scale = np.asarray(ir.x_scale, dtype=float)
    if scale.ndim and scale.shape != (spec.nx,):
        raise ValueError(f"{spec.family}: inputs x_scale has {scale.size} entries, the spec has nx = {spec.nx}")
    scale = np.broadcast_to(scale, (spec.nx,))
    X = X0 + rng.normal(size=(count, spec.nx)) * scale
    fine = None if not ir.x_about_y or ir.x_fine is None else rng.uniform(size=count) < 0.5
    spread = {i: (s if fine is None else np.where(fine, ir.x_fine, s)) for i, s in enumerate(scale)}
    for i, values in declared_slots(spec, Y, rng, spread).items():
        X[:, i] = values
    return X


def run_inputs(spec, count, dt, seed=0):
    """Inputs of a run of ``count`` samples, ``dt`` apart.

    When y = q and u = tau: the built-in smooth motion (codegen.trajectory) with sensor noise
    (1e-3 rad, 1e-2 N m); otherwise the family's random inputs (``random_inputs``).

    Parameters
    ----------
    spec : codegen.spec.ObserverSpec
    count : int
        Number of samples N.
    dt : float
        Sample time (s).
    seed : int

    Returns
    -------
    Y : (N, ny) array
    U : (N, nu) array
    """
    rng = np.random.default_rng(seed + 1)
    if spec.ny == spec.nu == spec.robot.n:
        _, Q, _, TAU = demo_trajectory(spec.robot, T=(count - 1) * dt, dt=dt, seed=seed)
        return Q + 1e-3 * rng.normal(size=Q.shape), TAU + 1e-2 * rng.normal(size=TAU.shape)
    _, Y, U = random_inputs(spec, count, seed + 2)
    return Y, U
