"""Reference open-loop torque of seed-000 Example 1 (docs/papers/seed000.md §1.4, docs/papers/experiments.md §12.1; [S000 (18)]), numpy.

A stateless law (nx = 0): y = [q_1 .. q_n, t], no input, "estimate" = the torque

    tau = g(q) + (cos(t/2), -cos t)                                      [S000 (18)]

on the reference robot (2-joint robots only). Never imports CasADi or the symbolic code.
"""
from __future__ import annotations

import numpy as np

from ._law import constant_state

P_NAMES = ()
rhs, init = constant_state(0)


def extra_torque(t):
    """The time-dependent part of (18): (cos(t/2), -cos t), N m, at time t (s)."""
    return np.array([np.cos(0.5 * t), -np.cos(t)])


def torque(robot, y, extra):
    """tau = g(q) + extra(t)  [S000 (18), (19)].

    Parameters
    ----------
    robot : reference robot with 2 joints
    y : (3,) array
        [q (rad); t (s)].
    extra : callable
        t -> (2,) torque, N m.

    Returns
    -------
    (2,) array
        N m.
    """
    n = robot.n
    if n != 2:
        raise ValueError(f"seed-000 open-loop torques need a 2-joint robot, got n={n}")
    q, t = np.asarray(y[:n], dtype=float), float(y[n])
    return np.asarray(robot.g(q), dtype=float).reshape(n) + extra(t)


def output(robot, x, y, u, p):
    """tau of [S000 (18)] (2,), N m, on ``robot`` (2 joints); x (0,), y = [q; t] (3,), u (0,),
    p (0,)."""
    return torque(robot, y, extra_torque)


def sizes(robot):
    """{"nx": 0, "ny": n + 1, "nu": 0, "nest": n} for ``robot`` with n joints."""
    return {"nx": 0, "ny": robot.n + 1, "nu": 0, "nest": robot.n}
