"""Reference Example-3 output-feedback law of seed 000 (docs/papers/seed000.md §1.4, docs/papers/experiments.md §12.1), numpy.

Stateless (nx = 0). y = [q (n), x2hat (n), t]; p = [q_start (n), q_goal (n), T_move, lambda,
kp (n), kd (n)] (diagonal gains); "estimate" = the torque

    tau = M(q)(qdd_d + Lambda(qd_d - x2hat)) + C(q, x2hat)(qd_d + Lambda(q_d - q)) + g(q)
          + K_P (q_d - q) + K_D (qd_d - x2hat)                           [S000 eq. after Fig. 5]

with q_d the rest-to-rest quintic q_start -> q_goal over [0, T_move], held outside
[ASSUMPTION docs/papers/experiments.md §12.1]:  q_d = q_start + (q_goal - q_start) h(s), s = clip(t / T_move, 0, 1),
h = 10 s^3 - 15 s^4 + 6 s^5 (h' and h'' by t, written out below). Never imports CasADi.
"""
from __future__ import annotations

import numpy as np

from ._law import constant_state, parameters


def _quintic(t, q0, q1, T):
    """(q_d, qd_d, qdd_d) of the rest-to-rest quintic at time t."""
    s = min(max(t / T, 0.0), 1.0)
    h = 10.0 * s ** 3 - 15.0 * s ** 4 + 6.0 * s ** 5
    dh = (30.0 * s ** 2 - 60.0 * s ** 3 + 30.0 * s ** 4) / T
    ddh = (60.0 * s - 180.0 * s ** 2 + 120.0 * s ** 3) / T ** 2
    dq = q1 - q0
    return q0 + h * dq, dh * dq, ddh * dq


rhs, init = constant_state(0)


def sizes(robot):
    """{"nx": 0, "ny": 2n + 1, "nu": 0, "nest": n} for ``robot`` with n joints."""
    n = robot.n
    return {"nx": 0, "ny": 2 * n + 1, "nu": 0, "nest": n}


def output(robot, x, y, u, p):
    """The Example-3 torque [S000 eq. after Fig. 5] (module docstring).

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (0,) array
    y : (2n + 1,) array
        [q (rad); x2hat (rad/s); t (s)].
    u : (0,) array
    p : (4n + 2,) array
        [q_start; q_goal (rad); T_move (s); lambda (1/s); kp (n); kd (n)].

    Returns
    -------
    (n,) array
        N m.
    """
    n = robot.n
    p = parameters("seed000_tracking", p, 4 * n + 2)
    q, qh, t = y[:n], y[n:2 * n], float(y[2 * n])
    q0, q1 = p[:n], p[n:2 * n]
    T, lam = float(p[2 * n]), float(p[2 * n + 1])
    kp, kd = p[2 * n + 2:3 * n + 2], p[3 * n + 2:4 * n + 2]
    q_d, qd_d, qdd_d = _quintic(t, q0, q1, T)
    M = np.asarray(robot.M(q), dtype=float)
    C = np.asarray(robot.C(q, qh), dtype=float)                      # Christoffel C(q, x2hat)
    g = np.asarray(robot.g(q), dtype=float).reshape(n)
    return (M @ (qdd_d + lam * (qd_d - qh)) + C @ (qd_d + lam * (q_d - q)) + g
            + kp * (q_d - q) + kd * (qd_d - qh))
