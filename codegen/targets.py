"""The default targets of `make generate` and the helpers the CLI and tests share."""
from __future__ import annotations

import numpy as np

DEFAULT_ROBOTS = ["seed000_2r", "seed002_2r", "seed003_2r_abs", "ur5", "panda"]
DEFAULT_FAMILY = "reduced_order"


def default_spec(robot_name, family=DEFAULT_FAMILY):
    from models import load_robot

    from . import observers
    return observers.build(family, load_robot(robot_name))


def random_inputs(spec, count, seed=0):
    """Random (X, Y, U) for cross-checks, at physical scales: y in the joint ranges, u around
    the gravity torques, x = init(y, est, p) + a perturbation, est ~ N(0, 2^2) per slot (a
    velocity-sized estimate; the perturbation is N(0, s^2) with
    s = ``spec.info["random_state_scale"]``, default 0.1, scalar or per state); state slots listed in
    ``spec.info["integer_states"] = {name: (lo, hi)}`` get random integers in [lo, hi].
    A family module may give its own ``random_inputs(spec, count, seed)`` (e.g. when y is not q)."""
    from . import observers
    if spec.family in observers.FAMILIES:
        import importlib
        hook = getattr(importlib.import_module(f"{observers.__name__}.{spec.family}"), "random_inputs", None)
        if hook is not None:
            return hook(spec, count, seed)
    rng = np.random.default_rng(seed)
    robot = spec.robot
    Y = robot.sample_configurations(count, seed)
    gscale = np.maximum(1.0, np.abs(np.asarray(robot.g.map(count)(Y.T))).max(axis=1))
    U = rng.normal(size=(count, spec.nu)) * gscale[: spec.nu]
    EST = 2.0 * rng.normal(size=(count, spec.nest))
    X0 = np.asarray(spec.init.map(count)(Y.T, EST.T, np.tile(spec.p_default[:, None], count))).T
    scale = spec.info.get("random_state_scale", 0.1)
    X = X0.reshape(count, spec.nx) + rng.normal(size=(count, spec.nx)) * np.asarray(scale, dtype=float)
    for name, (lo, hi) in spec.info.get("integer_states", {}).items():  # e.g. a hybrid logic state
        X[:, spec.x_names.index(name)] = rng.integers(lo, hi + 1, size=count)
    return X, Y, U


def relative_error(a, b):
    """max over rows of ||a - b|| / ||b|| (rows with ||b|| = 0 compare absolutely).
    NaN if anything is not finite, so that a comparison `<= tol` fails."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return float("nan")
    nb = np.linalg.norm(b, axis=1)
    return float(np.max(np.linalg.norm(a - b, axis=1) / np.where(nb > 0, nb, 1.0)))
