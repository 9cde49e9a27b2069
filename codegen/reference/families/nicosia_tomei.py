"""Nicosia–Tomei full-order observer (docs/papers/seed000.md §2), numpy.

    x1tilde = y - x1hat,   x1hat' = x2hat + kd x1tilde
    x2hat'  = M(y)^{-1}[tau - C(y, x1hat') x1hat' - F x1hat' - g(y) + kp x1tilde]

C evaluated at x1hat' (A0-6), saturated to the declared velocity bound (as reduced_order).
x = [x1hat (n, rad); x2hat (n, rad/s)], y = q (n, rad),
u = tau (n, N m), p = [kd (1/s), kp (N m/rad)], est = x2hat (n, rad/s).
"""
from __future__ import annotations

import numpy as np

from ._family import bound
from ._saturation import saturate, velocity_bound

P_NAMES = ("kd", "kp")


def configure(robot, options):
    """This family with the declared velocity bound bound (``robot`` the reference robot,
    ``options`` its VelocityBoundOptions or plain Options: no saturation)."""
    return bound(__name__, v_bound=velocity_bound(robot, options))


def output(robot, x, y, u, p):
    """The velocity estimate x2hat (docs/papers/seed000.md §2).

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (2n,) array
        [x1hat (rad); x2hat (rad/s)].
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m.
    p : (2,) array
        [kd (1/s), kp (N m/rad)].

    Returns
    -------
    (n,) array
        x2hat, rad/s.
    """
    return np.asarray(x[robot.n:], dtype=float)


def rhs_split(robot, x, y_cfg, y, u, p, v_bound=None):
    """[x1hat' (rad/s); x2hat' (rad/s^2)] (2n,) of docs/papers/seed000.md §2, the K_P x1tilde term entering as a
    torque, the model M, C, g, F at the configuration y_cfg (n,) rad and at x1hat' saturated to
    ``v_bound`` ((n,) rad/s or None), x1tilde = y - x1hat at the measurement; robot, x, y, u, p
    as in ``output``."""
    n = robot.n
    x1hat, x2hat = x[:n], x[n:]
    kd, kp = p
    x1tilde = y - x1hat
    v = x2hat + kd * x1tilde
    return np.concatenate([v, robot.forward_dynamics(y_cfg, saturate(v, v_bound), u + kp * x1tilde)])


def rhs(robot, x, y, u, p, v_bound=None):
    """The flow of the observer: ``rhs_split`` with the model at y itself;
    robot, x, y, u, p, v_bound as in ``rhs_split``."""
    return rhs_split(robot, x, y, y, u, p, v_bound)


def rate(robot, x, p):
    """The gain rate kd = p[0] of x1hat' = [x2hat + kd y] - kd x1hat (integrated exactly by etdrk4);
    robot, x as in ``output`` (unused)."""
    return float(p[0])


def rate_states(robot):
    """0/1 per state (2n,) of ``robot``: the linear term -kd x1hat acts on x1hat."""
    return np.concatenate([np.ones(robot.n), np.zeros(robot.n)])


def init(robot, y0, est0, p):
    """x(0) = [x1hat(0) = y0; x2hat(0) = est0] (2n,)  [CODE-KUKA]; y0 (n,) rad, est0 (n,) rad/s;
    robot, p as in ``output`` (unused)."""
    return np.concatenate([np.asarray(y0, float), np.asarray(est0, float)])


def sizes(robot):
    """{"nx": 2n, "ny": n, "nu": n, "nest": n} for ``robot`` (n joints)."""
    n = robot.n
    return {"nx": 2 * n, "ny": n, "nu": n, "nest": n}
