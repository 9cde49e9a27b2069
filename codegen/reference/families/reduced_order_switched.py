"""Reduced-order observer with a time-switched gain (codegen.families.observers.reduced_order_switched), numpy.

    x2hat = z + k y,   z' = M(y)^{-1}[tau - C(y,x2hat) x2hat - F x2hat - g(y)] - k x2hat
                                                                        [S000 (6),(9)]
    k = k0 while the switch is not done (s < t_switch + 1/2), else k0_final;  s' = 1 before, 0 after
    jump at a sample with t_switch <= s < t_switch + 1/2: z+ = z + (k0 - k0_final) y,
    s+ = t_switch + 1 (x2hat continuous)                                [DERIVED, as docs/papers/seed000.md §1.3]

The model at the estimate saturated to the declared velocity bound (as reduced_order).
x = [z (n, rad/s); s (s)], y = q (n, rad), u = tau (n, N m), p = [k0, k0_final (1/s),
t_switch (s)], est = x2hat (n, rad/s).
"""
from __future__ import annotations

import numpy as np

from . import reduced_order
from ._family import bound
from ._saturation import velocity_bound

P_NAMES = ("k0", "k0_final", "t_switch")


def configure(robot, options):
    """This family with the declared velocity bound bound (as ``reduced_order.configure``;
    ``robot`` the reference robot, ``options`` its VelocityBoundOptions or plain Options)."""
    return bound(__name__, v_bound=velocity_bound(robot, options))


def running(x, p):
    """True while the switch is not done: the clock x[-1] (s) below t_switch + 1/2, p as in
    ``output``."""
    return x[-1] < p[2] + 0.5


def gain(x, p):
    """The gain in force (1/s) at state x (n + 1,) and parameters p (3,) as in ``output``."""
    return float(p[0] if running(x, p) else p[1])


def output(robot, x, y, u, p):
    """x2hat = z + k y  [S000 (9)].

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (n + 1,) array
        [z (rad/s); s (s)].
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m (unused).
    p : (3,) array
        [k0, k0_final (1/s); t_switch (s)].

    Returns
    -------
    (n,) array
        x2hat, rad/s.
    """
    return reduced_order.output(robot, x[:-1], y, u, [gain(x, p)])


def rhs_split(robot, x, y_cfg, y, u, p, v_bound=None):
    """[z'; s'] = [FD(y_cfg, sat(x2hat), tau) - k x2hat; 1 before the switch, else 0]  [S000 (6)]
    (n + 1,), the model at the configuration y_cfg (n,) rad and at x2hat saturated to ``v_bound``
    ((n,) rad/s or None); robot, x, y, u, p as in ``output``."""
    return rhs_model(robot, x, y, u, p, model(robot, x, y_cfg, y, u, p, v_bound))


def model(robot, x, y_cfg, y, u, p, v_bound=None):
    """The model's part of ``rhs_split``: FD(y_cfg, sat(x2hat), tau) (n,), rad/s^2 (as
    ``reduced_order.model`` with the gain in force); robot, x, y_cfg, y, u, p, v_bound as in
    ``rhs_split``."""
    return reduced_order.model(robot, x[:-1], y_cfg, y, u, [gain(x, p)], v_bound)


def rhs_model(robot, x, y, u, p, m):
    """[z'; s'] = [m - k x2hat; 1 before the switch, else 0] (n + 1,) with the model's
    acceleration given as m (n,) rad/s^2; robot, x, y, u, p as in ``output``."""
    zdot = reduced_order.rhs_model(robot, x[:-1], y, u, [gain(x, p)], m)
    return np.append(zdot, 1.0 if running(x, p) else 0.0)


def rhs(robot, x, y, u, p, v_bound=None):
    """The flow [z'; s'] of the observer: ``rhs_split`` with the model at y itself; robot, x, y,
    u, p, v_bound as in ``rhs_split``."""
    return rhs_split(robot, x, y, y, u, p, v_bound)


def jump(robot, x, y, p):
    """[z+; s+] (n + 1,): the switch when the clock has passed t_switch (z reset keeps x2hat
    continuous, s marks it done); robot, x, y, p as in ``output``."""
    x = np.asarray(x, dtype=float)
    if not (x[-1] >= p[2] and running(x, p)):
        return x.copy()
    return np.append(x[:-1] + (p[0] - p[1]) * np.asarray(y, float), p[2] + 1.0)


def phases(robot, x, y, p):
    """The states the parameter check linearises at: x itself, and x with the switch done (z
    moved as by ``jump``, s = t_switch + 1: the gain k0_final); robot, x, y, p as in ``output``."""
    x = np.asarray(x, dtype=float)
    if not running(x, p):
        return [x]
    return [x, np.append(x[:-1] + (p[0] - p[1]) * np.asarray(y, float), p[2] + 1.0)]


def rate(robot, x, p):
    """The gain rate k of the flow on z (constant along a step: the switch is a jump); robot, x,
    p as in ``output``."""
    return gain(x, p)


def rate_states(robot):
    """0/1 per state (n + 1,) of ``robot``: the linear gain term acts on z, not on the clock."""
    return np.append(np.ones(robot.n), 0.0)


def retune(robot, x, y, p_old, p_new):
    """At a change of parameters p_old -> p_new: the clock kept (or, after the switch, the new
    switch marked done) and z+ = z + (k(p_old) - k(p_new)) y, x2hat continuous; robot, x, y as
    in ``output``."""
    x = np.asarray(x, dtype=float)
    s = x[-1] if running(x, p_old) else p_new[2] + 1.0
    x_new = np.append(x[:-1], s)
    return np.append(x[:-1] + (gain(x, p_old) - gain(x_new, p_new)) * np.asarray(y, float), s)


def init(robot, y0, est0, p):
    """x(0) = [x2hat(0) - k0 y(0); 0] (n + 1,)  [CODE-KUKA]; y0 = q(0) (n,) rad, est0 = x2hat(0)
    (n,) rad/s, robot, p as in ``output``."""
    return np.append(np.asarray(est0, float) - p[0] * np.asarray(y0, float), 0.0)


def sizes(robot):
    """{"nx": n + 1, "ny": n, "nu": n, "nest": n}, n the joints of ``robot``."""
    n = robot.n
    return {"nx": n + 1, "ny": n, "nu": n, "nest": n}
