"""Reduced-order velocity observer, linear gain k(y) = k0 y (SPEC §1.1, seed 000).

    x2hat = z + k0 y                                                         [S000 (6),(9)]
    z'    = M(y)^{-1} [tau - C(y, x2hat) x2hat - F x2hat - g(y)] - k0 x2hat  [S000 (6),(9)]
    z(0)  = x2hat(0) - k0 y(0)                            [CODE-KUKA controller_kuka.hpp]

x = z (n), y = q (n), u = tau (n), p = [k0], est = x2hat (n).
"""
from __future__ import annotations

import numpy as np

P_NAMES = ("k0",)


def output(robot, x, y, u, p):
    """x2hat = z + k0 y  [S000 (9)]."""
    return x + p[0] * y


def rhs(robot, x, y, u, p):
    """z' = forward_dynamics(y, x2hat, tau) - k0 x2hat  [S000 (6)]
    (M^{-1} k0 M x2hat = k0 x2hat, so the M(y) dk/dy term leaves the solve)."""
    x2hat = output(robot, x, y, u, p)
    return robot.forward_dynamics(y, x2hat, u) - p[0] * x2hat


def rate(robot, x, p):
    """The gain rate a = k0 of z' = [FD - k0^2 y] - k0 z, on every state (integrated exactly by etdrk4)."""
    return float(p[0])


def rate_states(robot):
    """0/1 per state: the linear gain term acts on all of z."""
    return np.ones(robot.n)


def retune(robot, x, y, p_old, p_new):
    """z+ = z + (k0_old - k0_new) y: x2hat = z + k0 y continuous at a change of k0."""
    return np.asarray(x, dtype=float) + (p_old[0] - p_new[0]) * np.asarray(y, dtype=float)


def init(robot, y0, est0, p):
    """z(0) = x2hat(0) - k0 y(0)."""
    return np.asarray(est0, dtype=float) - p[0] * np.asarray(y0, dtype=float)


def sizes(robot):
    """Vector sizes (nx, ny, nu, nest) for this robot."""
    n = robot.n
    return {"nx": n, "ny": n, "nu": n, "nest": n}
