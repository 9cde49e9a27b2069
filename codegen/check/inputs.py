"""Random cross-check inputs, drawn where each family declares them (``spec.inputs``, an
``codegen.options.InputRanges``: data, never a hook into the family's module)."""
from __future__ import annotations

import numpy as np


def measurements(spec, count, seed, rng):
    """Random (Y, U): configurations in the joint ranges (plus the declared extra y slots), u
    around or scaled by gravity, as ``spec.inputs`` declares."""
    robot, ir = spec.robot, spec.inputs
    n = robot.n
    if ir.y_jitter is None:
        Q = robot.sample_configurations(count, seed)
    else:
        Q = robot.sample_configurations(count, 0) + ir.y_jitter * rng.normal(size=(count, n))
    extra = [m + s * rng.normal(size=count) for m, s in ir.y_extra]
    Y = np.column_stack([Q] + extra) if extra else Q
    if Y.shape[1] != spec.ny:
        raise ValueError(f"{spec.family}: inputs give {Y.shape[1]} measurement slots, the spec has {spec.ny}")
    G = np.asarray(robot.g.map(count)(Q.T)).T
    if ir.u_gravity:
        U = (G + ir.u_scale * rng.normal(size=(count, n)))[:, :spec.nu]
    else:
        gscale = np.maximum(1.0, np.abs(G).max(axis=0))
        U = ir.u_scale * rng.normal(size=(count, spec.nu)) * gscale[:spec.nu]
    return Y, U


def declared_slots(spec, Y, rng, about_y_scale=None):
    """State slots drawn as ``spec.inputs`` declares (about a measurement slot, uniform,
    integer): {state index: (count,) values}. ``about_y_scale`` (count,) or None: the spread of
    the about-y slots around their measurement (None: exactly on it)."""
    ir, count, out = spec.inputs, len(Y), {}
    for xs, ys in ir.x_about_y:
        i, j = spec.x_names.index(xs), spec.y_names.index(ys)
        out[i] = Y[:, j] + (0.0 if about_y_scale is None else about_y_scale[i] * rng.normal(size=count))
    for name, lo, hi in ir.x_uniform:
        out[spec.x_names.index(name)] = rng.uniform(lo, hi, size=count)
    for name, lo, hi in ir.x_integer:
        out[spec.x_names.index(name)] = rng.integers(int(lo), int(hi) + 1, size=count)
    return out


def random_inputs(spec, count, seed=0):
    """Random (X, Y, U) for cross-checks at the physical scales the family declares in
    ``spec.inputs`` (codegen.options.InputRanges): y in the joint ranges (plus the declared
    extra slots), u around or scaled by gravity, x = init(y, est, p) + a perturbation, with
    the declared uniform, integer and about-y slots."""
    rng = np.random.default_rng(seed)
    ir = spec.inputs
    Y, U = measurements(spec, count, seed, rng)
    EST = ir.est_scale * rng.normal(size=(count, spec.nest))
    X0 = np.asarray(spec.init.map(count)(Y.T, EST.T, np.tile(spec.p_default[:, None], count))).T
    X = X0.reshape(count, spec.nx) + rng.normal(size=(count, spec.nx)) * np.asarray(ir.x_scale, dtype=float)
    fine = rng.uniform(size=count) < 0.5
    scale = np.broadcast_to(np.asarray(ir.x_scale, dtype=float), (spec.nx,))
    spread = {i: (np.where(fine, ir.x_fine, s) if ir.x_fine is not None else np.full(count, s))
              for i, s in enumerate(scale)}
    for i, values in declared_slots(spec, Y, rng, spread).items():
        X[:, i] = values
    return X, Y, U
