"""Nicosia–Tomei full-order observer (SPEC §2), numpy.

    x1tilde = y - x1hat,   x1hat' = x2hat + kd x1tilde
    x2hat'  = M(y)^{-1}[tau - C(y, x1hat') x1hat' - F x1hat' - g(y) + kp x1tilde]

C evaluated at x1hat' (A0-6). x = [x1hat; x2hat], y = q, u = tau, p = [kd, kp], est = x2hat.
"""
from __future__ import annotations

import numpy as np

P_NAMES = ("kd", "kp")


def output(robot, x, y, u, p):
    """The velocity estimate x2hat."""
    return np.asarray(x[robot.n:], dtype=float)


def rhs(robot, x, y, u, p):
    """[x1hat'; x2hat'] of SPEC §2 (the K_P x1tilde term enters as a torque)."""
    n = robot.n
    x1hat, x2hat = x[:n], x[n:]
    kd, kp = p
    x1tilde = y - x1hat
    v = x2hat + kd * x1tilde
    return np.concatenate([v, robot.forward_dynamics(y, v, u + kp * x1tilde)])


def rate(robot, x, p):
    """The gain rate kd of x1hat' = [x2hat + kd y] - kd x1hat (integrated exactly by etdrk4)."""
    return float(p[0])


def rate_states(robot):
    """0/1 per state: the linear term -kd x1hat acts on x1hat."""
    return np.concatenate([np.ones(robot.n), np.zeros(robot.n)])


def init(robot, y0, est0, p):
    """x1hat(0) = y(0), x2hat(0) = est0  [CODE-KUKA]."""
    return np.concatenate([np.asarray(y0, float), np.asarray(est0, float)])


def sizes(robot):
    """Vector sizes for this robot."""
    n = robot.n
    return {"nx": 2 * n, "ny": n, "nu": n, "nest": n}
