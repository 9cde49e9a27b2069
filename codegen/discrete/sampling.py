"""Measurements and declared state slots drawn where each family declares them (``spec.inputs``,
a ``codegen.core.options.InputRanges``): the random inputs of the cross-checks (codegen.verify.inputs)
and the working points of the discrete stability check (codegen.discrete.stability). numpy only; the
robot is read through ``spec.robot`` (``sample_configurations``, ``g``)."""
from __future__ import annotations

import numpy as np


def measurements(spec, count, seed, rng):
    """Random (Y (N, ny), U (N, nu)) as ``random_inputs`` draws them (also the working points of
    codegen.discrete.stability): N = ``count`` samples for the observer ``spec``, configurations drawn
    with ``seed``, the rest (jitter, extra slots, torques) from the numpy Generator ``rng``."""
    ir, robot = spec.inputs, spec.robot
    Q = (robot.sample_configurations(count, seed) if ir.y_jitter is None else
         robot.sample_configurations(count, 0) + ir.y_jitter * rng.normal(size=(count, robot.n)))
    Y = np.column_stack([Q] + [m + s * rng.normal(size=count) for m, s in ir.y_extra])
    if Y.shape[1] != spec.ny:
        raise ValueError(f"{spec.family}: inputs give {Y.shape[1]} measurement slots, the spec has {spec.ny}")
    return Y, torques(ir, np.asarray(robot.g.map(count)(Q.T)).T, spec.nu, rng)


def torques(ir, G, nu, rng):
    """u (N, nu) of ``ir.u`` (``ir``: the InputRanges) from the gravity torques G (N, n) N m, noise
    drawn from the numpy Generator ``rng``."""
    W = ir.u_scale * rng.normal(size=(G.shape[0], nu))
    if ir.u == "gravity":
        return G[:, :nu] + W
    if ir.u == "scaled":
        return W * np.maximum(1.0, np.abs(G).max(axis=0))[:nu]
    return W


def slot_index(spec, names, name):
    """Index of slot ``name`` in ``names`` (ValueError naming the family of ``spec`` and the slot)."""
    if name not in names:
        raise ValueError(f"{spec.family}: inputs name slot {name!r}, not one of {list(names)}")
    return names.index(name)


def declared_slots(spec, Y, rng, about_y_spread=None):
    """The state slots ``spec.inputs`` declares (about a measurement, uniform, normal, integer):
    {state index: (N,) values}, from the measurements Y (N, ny) and the numpy Generator ``rng``.
    ``about_y_spread``: {state index: std (scalar or (N,))} of the about-y slots around their
    measurement, or None: exactly on it."""
    ir, count, out = spec.inputs, len(Y), {}
    for xs, ys in ir.x_about_y:
        i, j = slot_index(spec, spec.x_names, xs), slot_index(spec, spec.y_names, ys)
        out[i] = Y[:, j] + (0.0 if about_y_spread is None else about_y_spread[i] * rng.normal(size=count))
    for name, lo, hi in ir.x_uniform:
        out[slot_index(spec, spec.x_names, name)] = rng.uniform(lo, hi, size=count)
    for name, mean, std in ir.x_normal:
        out[slot_index(spec, spec.x_names, name)] = mean + std * rng.normal(size=count)
    for name, lo, hi in ir.x_integer:
        out[slot_index(spec, spec.x_names, name)] = rng.integers(lo, hi + 1, size=count)
    return out
