"""Random cross-check inputs, drawn where each family declares them (``spec.inputs``, an
``codegen.core.options.InputRanges``: data, never a hook into the family's module), and the inputs
of a run along a motion of the robot. Observers of an elastic-joint robot (one with
``sample_states``) measure true states through their slot names (``elastic_measurement``).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from ..discrete.sampling import declared_slots, measurements, slot_index, torques
from .trajectory import demo_trajectory, elastic_measurement, elastic_trajectory

Run = namedtuple("Run", "Y U truth truth_names")
Run.__doc__ = """Inputs of a run: Y (N, ny), U (N, nu), and the true values (N, k) of the estimate
slots ``truth_names`` (None when the inputs are random draws)."""


def _elastic(robot):
    return hasattr(robot, "sample_states")


def random_inputs(spec, count, seed=0):
    """Random (X, Y, U) for a cross-check, at the physical scales the family declares.

    y: configurations in the joint ranges (rad; fixed plus jitter when ``y_jitter``), then the
    ``y_extra`` slots; u: around g(y), scaled by |g(y)| or plain (N m); x: init(y, est, p) plus a
    perturbation, with the declared about-y, uniform, normal and integer slots.

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec
        Its ``inputs`` (codegen.core.options.InputRanges), robot (``sample_configurations``,
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
    ir, robot = spec.inputs, spec.robot
    if _elastic(robot):       # y measured off true states, the estimate started near them
        S = robot.sample_states(count, seed)
        Y, G = elastic_measurement(spec, S), np.asarray(robot.rigid.g.map(count)(S[:, :robot.n].T)).T
        return _states(spec, ir, Y, rng, est=S), Y, torques(ir, G, spec.nu, rng)
    Y, U = measurements(spec, count, seed, rng)
    return _states(spec, ir, Y, rng), Y, U


def _states(spec, ir, Y, rng, est=None):
    """x (N, nx): init(y, est, p) + N(0, x_scale^2), then the declared slots; est (N, nest)
    default N(0, est_scale^2)."""
    count = Y.shape[0]
    p = spec.p_default.copy()
    for name, value in ir.init_p:
        p[slot_index(spec, spec.p_names, name)] = value
    EST = ir.est_scale * rng.normal(size=(count, spec.nest)) if est is None else est
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


def trajectory_inputs(spec, count, dt, seed=0):
    """Noise-free inputs of a run of ``count`` samples, ``dt`` apart, with the truth.

    An elastic robot's observer: the robot's motion (``codegen.verify.trajectory.elastic_trajectory``)
    measured through the slot names, truth the state (estimate slots ``<state>_hat``). When
    y = q and u = tau: the built-in smooth motion (``demo_trajectory``), truth qd (estimate
    slots ``qd_hat_<joint>``). Otherwise the family's random inputs (``random_inputs``), no truth.

    Parameters
    ----------
    spec : ObserverSpec
        The observer (its robot, slots and input recipe).
    count : int
        Number of samples N.
    dt : float
        Sample time, s.
    seed : int
        Seed of the motion (phases) or of the random inputs.

    Returns
    -------
    Run
    """
    robot = spec.robot
    if _elastic(robot):
        _, X, U = elastic_trajectory(robot, T=(count - 1) * dt, dt=dt, seed=seed)
        return Run(elastic_measurement(spec, X), U, X, [f"{s}_hat" for s in robot.state_names])
    if spec.ny == spec.nu == robot.n:
        _, Q, QD, TAU = demo_trajectory(robot, T=(count - 1) * dt, dt=dt, seed=seed)
        return Run(Q, TAU, QD, [f"qd_hat_{j}" for j in robot.joint_names])
    _, Y, U = random_inputs(spec, count, seed + 2)
    return Run(Y, U, None, None)


def run_inputs(spec, count, dt, seed=0):
    """Inputs of a run of ``count`` samples, ``dt`` apart: ``trajectory_inputs`` with sensor
    noise on a motion (1e-3 on y, 1e-2 on u), the random draws as they are.

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec
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
    run = trajectory_inputs(spec, count, dt, seed)
    if run.truth is None:
        return run.Y, run.U
    return run.Y + 1e-3 * rng.normal(size=run.Y.shape), run.U + 1e-2 * rng.normal(size=run.U.shape)


def jittered_stamps(count, dt, seed=0, jitter=(0.7, 1.6), gap_every=100, gap=10.0):
    """Time stamps (s) of a jittered log of ``count`` samples around the sample time ``dt`` (s):
    intervals drawn uniformly in ``jitter`` x dt (a 1 kHz loop's 0.7-1.6 ms), and every
    ``gap_every``-th one ``gap`` x dt long (a dropped sample, a late packet: split by the step);
    t[0] = 0, drawn with ``seed``."""
    rng = np.random.default_rng(seed)
    h = dt * rng.uniform(jitter[0], jitter[1], size=max(count - 1, 0))
    h[gap_every - 1::gap_every] = gap * dt
    return np.concatenate([[0.0], np.cumsum(h)])[:count]
