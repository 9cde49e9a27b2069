"""Reduced-order velocity observer, linear gain k(y) = k0 y (docs/papers/seed000.md §1.1, seed 000).

    x2hat = z + k0 y                                                         [S000 (6),(9)]
    z'    = M(y)^{-1} [tau - C(y, v) v - F v - g(y)] - k0 x2hat,  v = sat(x2hat)   [S000 (6),(9)]
    z(0)  = x2hat(0) - k0 y(0)                            [CODE-KUKA controller_kuka.hpp]

sat: the declared velocity bound (``_saturation``; none in a description without it).
x = z (n, rad/s), y = q (n, rad), u = tau (n, N m), p = [k0 (1/s)], est = x2hat (n, rad/s).
"""
from __future__ import annotations

import numpy as np

from ._family import bound
from ._saturation import saturate, velocity_bound

P_NAMES = ("k0",)


def configure(robot, options):
    """This family with the declared velocity bound (``options.v_bound``, rad/s) bound.

    Parameters
    ----------
    robot : reference robot (n joints)
    options : codegen.core.options.Options
        VelocityBoundOptions (or plain Options: no saturation).

    Returns
    -------
    family bound to ``v_bound`` ((n,) array or None)
    """
    return bound(__name__, v_bound=velocity_bound(robot, options))


def output(robot, x, y, u, p):
    """x2hat = z + k0 y  [S000 (9)].

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (n,) array
        z, rad/s.
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m (unused).
    p : (1,) array
        [k0], 1/s.

    Returns
    -------
    (n,) array
        x2hat, rad/s.
    """
    return x + p[0] * y


def rhs_split(robot, x, y_cfg, y, u, p, v_bound=None):
    """z' = forward_dynamics(y_cfg, sat(x2hat), tau) - k0 x2hat  [S000 (6)] (n,), rad/s^2, the model
    at the configuration y_cfg (n,) rad and at x2hat = z + k0 y saturated to ``v_bound`` ((n,)
    rad/s or None), x2hat at the measurement (M^{-1} k0 M x2hat = k0 x2hat, so the M dk/dy term
    leaves the solve); robot, x, y, u, p as in ``output``."""
    return rhs_model(robot, x, y, u, p, model(robot, x, y_cfg, y, u, p, v_bound))


def model(robot, x, y_cfg, y, u, p, v_bound=None):
    """The model's part of ``rhs_split``: forward_dynamics(y_cfg, sat(x2hat), tau) (n,), rad/s^2,
    x2hat = z + k0 y saturated to ``v_bound``; robot, x, y_cfg, y, u = tau, p as in ``rhs_split``."""
    return robot.forward_dynamics(y_cfg, saturate(output(robot, x, y, u, p), v_bound), u)


def rhs_model(robot, x, y, u, p, m):
    """z' = m - k0 x2hat  [S000 (6)] (n,) with the model's acceleration given as m (n,) rad/s^2;
    robot, x, y, u, p as in ``output``."""
    return np.asarray(m, dtype=float) - p[0] * output(robot, x, y, u, p)


def rhs(robot, x, y, u, p, v_bound=None):
    """The flow z' of the observer: ``rhs_split`` with the model at y itself;
    robot, x, y, u, p, v_bound as in ``rhs_split``."""
    return rhs_split(robot, x, y, y, u, p, v_bound)


def rate(robot, x, p):
    """The gain rate a = k0 = p[0] of z' = [FD - k0^2 y] - k0 z, on every state (integrated exactly
    by etdrk4); robot, x as in ``output`` (unused)."""
    return float(p[0])


def rate_states(robot):
    """0/1 per state (n,) of ``robot``: the linear gain term acts on all of z."""
    return np.ones(robot.n)


def retune(robot, x, y, p_old, p_new):
    """z+ = z + (k0_old - k0_new) y: x2hat = z + k0 y continuous at a change of k0 from p_old to
    p_new; robot, x = z, y as in ``output``."""
    return np.asarray(x, dtype=float) + (p_old[0] - p_new[0]) * np.asarray(y, dtype=float)


def init(robot, y0, est0, p):
    """z(0) = x2hat(0) - k0 y(0)  [CODE-KUKA] (n,), rad/s; y0 = q(0) (n,) rad, est0 = x2hat(0)
    (n,) rad/s, robot, p as in ``output``."""
    return np.asarray(est0, dtype=float) - p[0] * np.asarray(y0, dtype=float)


def sizes(robot):
    """{"nx", "ny", "nu", "nest"}: n each, n the joints of ``robot``."""
    n = robot.n
    return {"nx": n, "ny": n, "nu": n, "nest": n}
