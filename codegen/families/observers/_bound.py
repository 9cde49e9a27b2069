"""The velocity bound of the model-based velocity observers: the model is evaluated at the
estimate saturated per joint, never at the estimate itself.

    FD(y, sat(v), tau),   sat(v)_j = min(max(v_j, -b_j), b_j)

The Coriolis term C(y, v) v is quadratic in v: with a large model error (masses off, a torque
offset, Coriolis friction the model lacks) the estimate can run away and the quadratic term
drives it to a finite escape (kinova with Coulomb friction: reduced_order NaN after 2.5 s). With
the saturation the model's acceleration is bounded for bounded (y, tau), so the right-hand side
grows at most linearly in the state (the gain terms) and the observer stays finite
[DERIVED]. Inside the bound sat(v) = v exactly (a clamp, not a smooth saturation): where the
estimate stays inside, the observer is the published one, bit for bit.

The bound per joint (rad/s):

    b_j = MARGIN * v_limit_j   when the URDF velocity limit v_limit_j is finite and > 0,
    b_j = MARGIN * v_max       otherwise (the design's speed bound),

or given (``v_bound=``, a number or one per joint). MARGIN = 2 [ASSUMPTION]: the estimate's
start-up transient and noise above the rated speed still see the true model, and at the bound
the Coriolis term is at most 4 times its value at the rated speed.

The bound is recorded as the spec's options (codegen.core.options.VelocityBoundOptions, or
HybridOptions), so the metadata JSON has it and the reference applies the same clamp.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

MARGIN = 2.0


def velocity_bound(robot, v_max, v_bound=None):
    """The bound b (n,) in rad/s (module docstring).

    Parameters
    ----------
    robot : RobotModel
        Its ``v_limit`` (n,) (URDF velocity limits; inf when unknown) and ``n``.
    v_max : float
        The design's speed bound (rad/s), for joints without a finite positive limit.
    v_bound : float or sequence of n floats, optional
        Given bound (rad/s); positive and finite.

    Returns
    -------
    (n,) float array
    """
    n = robot.n
    if v_bound is not None:
        b = np.asarray(v_bound, dtype=float).reshape(-1)
        if b.size == 1:
            b = np.full(n, float(b[0]))
        if b.size != n or not np.all(np.isfinite(b) & (b > 0)):
            raise ValueError(f"v_bound must be a positive finite speed (rad/s) or {n} of them (one per "
                             f"joint), got {v_bound!r}")
        return b
    if not (np.isfinite(v_max) and v_max > 0):
        raise ValueError(f"v_max must be a positive finite speed (rad/s), got {v_max!r}")
    limit = np.asarray(getattr(robot, "v_limit", np.full(n, np.inf)), dtype=float).reshape(-1)
    if limit.size != n:
        limit = np.full(n, np.inf)
    ok = np.isfinite(limit) & (limit > 0)
    return MARGIN * np.where(ok, limit, float(v_max))


def saturate(v, bound):
    """sat(v) = min(max(v, -b), b) per entry: ``v`` an (n,) SX, ``bound`` (n,) floats (rad/s)."""
    b = ca.DM(np.asarray(bound, dtype=float))
    return ca.fmin(ca.fmax(v, -b), b)


def report(robot, bound, v_max, given):
    """The design report's entry on the bound: the values, and where they come from.

    Parameters
    ----------
    robot : RobotModel
    bound : (n,) array
        The bound used (rad/s).
    v_max : float
        The design's speed bound (rad/s).
    given : bool
        Whether the user gave ``v_bound``.

    Returns
    -------
    dict
    """
    if given:
        rule = "given (v_bound)"
    else:
        limit = np.asarray(getattr(robot, "v_limit", np.full(robot.n, np.inf)), dtype=float)
        from_limit = [bool(np.isfinite(v) and v > 0) for v in limit]
        rule = (f"{MARGIN:g} x the URDF velocity limit" if all(from_limit) else
                f"{MARGIN:g} x v_max = {MARGIN * v_max:g} rad/s" if not any(from_limit) else
                f"{MARGIN:g} x the URDF velocity limit where finite, else {MARGIN:g} x v_max")
    return {"v_bound": [float(b) for b in bound], "v_bound_rule": rule}
