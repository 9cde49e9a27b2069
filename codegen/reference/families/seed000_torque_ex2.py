"""Reference open-loop torque of seed-000 Example 2 (docs/papers/experiments.md §12.1; [S000 (19)]), numpy.

Stateless (nx = 0): y = [q_1 .. q_n, t], no input, "estimate" = the torque

    tau = g(q) + (cos t, -1 + sin 2t)                                    [S000 (19)]

(2-joint robots only). Never imports CasADi or the symbolic code.
"""
from __future__ import annotations

import numpy as np

from .seed000_torque_ex1 import init, rhs, sizes, torque  # noqa: F401  (same stateless shape)

P_NAMES = ()


def extra_torque(t):
    """The time-dependent part of (19): (cos t, -1 + sin 2t), N m, at time t (s)."""
    return np.array([np.cos(t), -1.0 + np.sin(2.0 * t)])


def output(robot, x, y, u, p):
    """tau of [S000 (19)] (2,), N m, on ``robot`` (2 joints); x (0,), y = [q; t] (3,), u (0,),
    p (0,)."""
    return torque(robot, y, extra_torque)
