"""A short built-in trajectory for any robot, exact by inverse dynamics.

    q(t)  = q_c + a sin(w t + phi)                 (per joint, inside the joint range)
    tau(t) = M(q) qdd + C(q, qd) qd + F qd + g(q)   [S000 (1)]

so (q, qd, tau) satisfy the model exactly at every sample; an observer fed
y = q(t_k), u = tau(t_k) (held over a step) must reconstruct qd(t_k).
"""
from __future__ import annotations

import casadi as ca
import numpy as np


def inverse_dynamics_function(robot):
    """Function (q, v, a) -> tau = M a + C v + F v + g (the model of [S000 (1)])."""
    q, v, a = ca.SX.sym("q", robot.n), ca.SX.sym("v", robot.n), ca.SX.sym("a", robot.n)
    tau = ca.mtimes(robot.mass_matrix(q), a) + robot.nle(q, v) + ca.mtimes(ca.DM(robot.F), v)
    return ca.Function("id", [q, v, a], [tau])


def demo_trajectory(robot, T=2.0, dt=1e-3, amplitude=0.3, omega=2.0, seed=0):
    """Samples t, Q, QD, TAU (each (N, n), N = round(T/dt) + 1) of a smooth motion.

    Speeds stay below amplitude*omega (0.6 rad/s by default), inside the observers'
    design bound v_max = 2 rad/s."""
    rng = np.random.default_rng(seed)
    n = robot.n
    lo, hi = robot.q_lower, robot.q_upper
    centre = np.clip(0.5 * (lo + hi), lo + amplitude, hi - amplitude)
    a = amplitude * np.minimum(1.0, 0.5 * (hi - lo) / max(amplitude, 1e-12))
    phi = rng.uniform(0, 2 * np.pi, n)
    w = omega * (1.0 + 0.25 * np.arange(n) / max(n - 1, 1))
    t = np.arange(int(round(T / dt)) + 1) * dt
    arg = np.outer(t, w) + phi
    Q = centre + a * np.sin(arg)
    QD = a * w * np.cos(arg)
    QDD = -a * w ** 2 * np.sin(arg)
    f = inverse_dynamics_function(robot).map(len(t))
    TAU = np.asarray(f(Q.T, QD.T, QDD.T)).T
    return t, Q, QD, TAU
