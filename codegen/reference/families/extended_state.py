"""Model-based extended-state observer (codegen.families.observers.extended_state), numpy.

    e_y = y - q_hat,  q_hat' = v_hat + 3 w e_y,
    v_hat' = M(y)^{-1}[tau - C(y, v_hat) v_hat - F v_hat - g(y)] + d_hat + 3 w^2 e_y,
    d_hat' = w^3 e_y                                                     [DERIVED]

x = [q_hat (n, rad); v_hat (n, rad/s); d_hat (n, rad/s^2)], y = q (n, rad), u = tau (n, N m),
p = [omega (1/s)], est = v_hat (n, rad/s).
"""
from __future__ import annotations

import numpy as np

P_NAMES = ("omega",)


def _split(x, n):
    x = np.asarray(x, dtype=float)
    return x[:n], x[n:2 * n], x[2 * n:]


def output(robot, x, y, u, p):
    """v_hat.

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
    (n,) array
        v_hat, rad/s.
    """
    return _split(x, robot.n)[1].copy()


def rhs_split(robot, x, y_cfg, y, u, p):
    """[q_hat'; v_hat'; d_hat'] (3n,) of the module docstring with the model at the configuration
    y_cfg (n,) rad; robot, x, y, u, p as in ``output``."""
    qh, vh, dh = _split(x, robot.n)
    w = float(p[0])
    e = np.asarray(y, float) - qh
    return np.concatenate([vh + 3 * w * e, robot.forward_dynamics(y_cfg, vh, u) + dh + 3 * w ** 2 * e,
                           w ** 3 * e])


def rhs(robot, x, y, u, p):
    """The flow of the observer: ``rhs_split`` with the model at y itself; robot, x, y, u, p as
    in ``rhs_split``."""
    return rhs_split(robot, x, y, y, u, p)


def rate(robot, x, p):
    """The gain rate 3 omega of q_hat' = [v_hat + 3 omega y] - 3 omega q_hat (integrated exactly
    by etdrk4); robot, x, p as in ``output``."""
    return 3.0 * float(p[0])


def rate_states(robot):
    """0/1 per state (3n,) of ``robot``: the linear gain term acts on q_hat."""
    n = robot.n
    return np.concatenate([np.ones(n), np.zeros(2 * n)])


def init(robot, y0, est0, p):
    """x(0) = [y(0); x2hat(0); 0] (3n,); y0 = q(0) (n,) rad, est0 (n,) rad/s, robot, p as in
    ``output``."""
    return np.concatenate([np.asarray(y0, float), np.asarray(est0, float), np.zeros(robot.n)])


def sizes(robot):
    """{"nx": 3n, "ny": n, "nu": n, "nest": n}, n the joints of ``robot``."""
    n = robot.n
    return {"nx": 3 * n, "ny": n, "nu": n, "nest": n}
