"""Random cross-check inputs, drawn where each family declares them (``spec.inputs``, an
``codegen.options.InputRanges``: data, never a hook into the family's module)."""
from __future__ import annotations

import numpy as np

from ..trajectory import demo_trajectory


def random_inputs(spec, count, seed=0):
    """Random (X, Y, U) for cross-checks at the physical scales the family declares in
    ``spec.inputs`` (codegen.options.InputRanges): y in the joint ranges (plus the declared
    extra slots), u around or scaled by gravity, x = init(y, est, p) + a perturbation, with
    the declared uniform, integer and about-y slots."""
    rng = np.random.default_rng(seed)
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
    EST = ir.est_scale * rng.normal(size=(count, spec.nest))
    X0 = np.asarray(spec.init.map(count)(Y.T, EST.T, np.tile(spec.p_default[:, None], count))).T
    X = X0.reshape(count, spec.nx) + rng.normal(size=(count, spec.nx)) * np.asarray(ir.x_scale, dtype=float)
    fine = rng.uniform(size=count) < 0.5
    for xs, ys in ir.x_about_y:
        i, j = spec.x_names.index(xs), spec.y_names.index(ys)
        scale = np.asarray(ir.x_scale, dtype=float)
        s = scale[i] if scale.ndim else float(scale)
        if ir.x_fine is not None:
            s = np.where(fine, ir.x_fine, s)
        X[:, i] = Y[:, j] + s * rng.normal(size=count)
    for name, lo, hi in ir.x_uniform:
        X[:, spec.x_names.index(name)] = rng.uniform(lo, hi, size=count)
    for name, lo, hi in ir.x_integer:
        X[:, spec.x_names.index(name)] = rng.integers(int(lo), int(hi) + 1, size=count)
    return X, Y, U


def run_inputs(spec, count, dt, seed=0):
    """Inputs (Y, U) of a run of ``count`` samples, ``dt`` apart: when y = q and u = tau, the
    built-in smooth motion (codegen.trajectory) with sensor noise (1e-3 rad, 1e-2 N m);
    otherwise the family's random inputs (``random_inputs``)."""
    rng = np.random.default_rng(seed + 1)
    if spec.ny == spec.nu == spec.robot.n:
        _, Q, _, TAU = demo_trajectory(spec.robot, T=(count - 1) * dt, dt=dt, seed=seed)
        return Q + 1e-3 * rng.normal(size=Q.shape), TAU + 1e-2 * rng.normal(size=TAU.shape)
    _, Y, U = random_inputs(spec, count, seed + 2)
    return Y, U
