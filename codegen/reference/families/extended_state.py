"""Model-based extended-state observer (codegen.families.observers.extended_state), numpy.

    e_y = y - q_hat,  q_hat' = v_hat + 3 w e_y,
    v_hat' = M(y)^{-1}[tau - C(y, v) v - F v - g(y)] + d_hat + 3 w^2 e_y,   v = sat(v_hat)
    d_hat' = w^3 e_y                                                     [DERIVED]
    est    = [v_hat; tau_d_hat = M(y) d_hat]

sat: the declared velocity bound (as reduced_order).
x = [q_hat (n, rad); v_hat (n, rad/s); d_hat (n, rad/s^2)], y = q (n, rad), u = tau (n, N m),
p = [omega (1/s)], est = [v_hat (n, rad/s); tau_d_hat (n, N m)].
"""
from __future__ import annotations

import numpy as np

from ._family import bound
from ._saturation import saturate, velocity_bound

P_NAMES = ("omega",)


def configure(robot, options):
    """This family with the declared velocity bound bound (``robot`` the reference robot,
    ``options`` its VelocityBoundOptions or plain Options: no saturation)."""
    return bound(__name__, v_bound=velocity_bound(robot, options))


def _split(x, n):
    x = np.asarray(x, dtype=float)
    return x[:n], x[n:2 * n], x[2 * n:]


def output(robot, x, y, u, p):
    """[v_hat; M(y) d_hat]: the velocity and the torque-error estimates.

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (3n,) array
        [q_hat (rad); v_hat (rad/s); d_hat (rad/s^2)].
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m (unused).
    p : (1,) array
        [omega], 1/s.

    Returns
    -------
    (2n,) array
        [v_hat (rad/s); tau_d_hat (N m)].
    """
    _, vh, dh = _split(x, robot.n)
    return np.concatenate([vh, robot.M(y) @ dh])


def rhs_split(robot, x, y_cfg, y, u, p, v_bound=None):
    """[q_hat'; v_hat'; d_hat'] (3n,) of the module docstring with the model at the configuration
    y_cfg (n,) rad and at v_hat saturated to ``v_bound`` ((n,) rad/s or None); robot, x, y, u, p
    as in ``output``."""
    qh, vh, dh = _split(x, robot.n)
    w = float(p[0])
    e = np.asarray(y, float) - qh
    a_model = robot.forward_dynamics(y_cfg, saturate(vh, v_bound), u)
    return np.concatenate([vh + 3 * w * e, a_model + dh + 3 * w ** 2 * e, w ** 3 * e])


def rhs(robot, x, y, u, p, v_bound=None):
    """The flow of the observer: ``rhs_split`` with the model at y itself; robot, x, y, u, p,
    v_bound as in ``rhs_split``."""
    return rhs_split(robot, x, y, y, u, p, v_bound)


def rate(robot, x, p):
    """The gain rate 3 omega of q_hat' = [v_hat + 3 omega y] - 3 omega q_hat (integrated exactly
    by etdrk4); robot, x, p as in ``output``."""
    return 3.0 * float(p[0])


def rate_states(robot):
    """0/1 per state (3n,) of ``robot``: the linear gain term acts on q_hat."""
    n = robot.n
    return np.concatenate([np.ones(n), np.zeros(2 * n)])


def init(robot, y0, est0, p):
    """x(0) = [y(0); v_hat(0); M(y(0))^-1 tau_d_hat(0)] (3n,); y0 = q(0) (n,) rad, est0 =
    [v_hat(0) (n,) rad/s; tau_d_hat(0) (n,) N m], robot, p as in ``output``."""
    n = robot.n
    y0, est0 = np.asarray(y0, float), np.asarray(est0, float)
    return np.concatenate([y0, est0[:n], np.linalg.solve(robot.M(y0), est0[n:])])


def sizes(robot):
    """{"nx": 3n, "ny": n, "nu": n, "nest": 2n}, n the joints of ``robot``."""
    n = robot.n
    return {"nx": 3 * n, "ny": n, "nu": n, "nest": 2 * n}
