"""Reduced-order velocity observer with the nonlinear gain k(y) = k0 C phi(y) (seed 000 §VI).

    x2hat = z + k0 C phi(y)                                                       [S000 §VI]
    z'    = M(y)^{-1} [tau - C(y, x2hat) x2hat - F x2hat - g(y)] - k0 C dphi/dy x2hat  [S000 (6)]
    z(0)  = x2hat(0) - k0 C phi(y(0))
    phi(y) = [y_l; sin y_l; cos y_l; sin 2y_l; cos 2y_l (l = 1..n); y_l cos y_m; y_l sin y_m (l != m)]

The model at the estimate saturated to the declared velocity bound (as reduced_order).
x = z (n, rad/s), y = q (n, rad), u = tau (n, N m), p = [k0 (1/s), C row-major (n x nb)],
est = x2hat (n, rad/s). phi and its Jacobian are written out here (no symbolic code).
"""
from __future__ import annotations

import numpy as np

from ._family import bound
from ._saturation import saturate, velocity_bound


def configure(robot, options):
    """This family with the declared velocity bound bound (``robot`` the reference robot,
    ``options`` its VelocityBoundOptions or plain Options: no saturation)."""
    return bound(__name__, v_bound=velocity_bound(robot, options))


def _pairs(n):
    return [(l, m) for l in range(n) for m in range(n) if l != m]


def phi(y):
    """phi(y) (nb,), nb = 5n + 2n(n-1)."""
    y = np.asarray(y, dtype=float)
    pr = _pairs(len(y))
    return np.concatenate([y, np.sin(y), np.cos(y), np.sin(2 * y), np.cos(2 * y),
                           [y[l] * np.cos(y[m]) for l, m in pr], [y[l] * np.sin(y[m]) for l, m in pr]])


def dphi(y):
    """dphi/dy (nb, n) at y = q (n,) rad, written out entry by entry."""
    y = np.asarray(y, dtype=float)
    n = len(y)
    pr = _pairs(n)
    rows = [np.diag(np.ones(n)), np.diag(np.cos(y)), np.diag(-np.sin(y)),
            np.diag(2 * np.cos(2 * y)), np.diag(-2 * np.sin(2 * y))]
    for trig, dtrig in ((np.cos, lambda a: -np.sin(a)), (np.sin, np.cos)):
        block = np.zeros((len(pr), n))
        for r, (l, m) in enumerate(pr):
            block[r, l] = trig(y[m])                  # d/dy_l of y_l trig(y_m)
            block[r, m] = y[l] * dtrig(y[m])          # d/dy_m
        rows.append(block)
    return np.vstack(rows)


def _gain(robot, p):
    n = robot.n
    return p[0], np.asarray(p[1:], dtype=float).reshape(n, -1)


def output(robot, x, y, u, p):
    """x2hat = z + k0 C phi(y) (n,), rad/s  [S000 §VI]; robot, x = z (n,) rad/s, y = q (n,) rad,
    u = tau (n,) N m (unused), p = [k0, C row-major]."""
    k0, C = _gain(robot, p)
    return np.asarray(x, dtype=float) + k0 * C @ phi(y)


def rhs_split(robot, x, y_cfg, y, u, p, v_bound=None):
    """z' = forward_dynamics(y_cfg, sat(x2hat), tau) - k0 C dphi/dy(y) x2hat  [S000 (6)] (n,),
    rad/s^2: the model at the configuration y_cfg (n,) rad and at x2hat saturated to ``v_bound``
    ((n,) rad/s or None), the gain terms at the measurement y; robot, x, y, u, p as in ``output``."""
    k0, C = _gain(robot, p)
    x2hat = output(robot, x, y, u, p)
    return robot.forward_dynamics(y_cfg, saturate(x2hat, v_bound), u) - k0 * (C @ dphi(y)) @ x2hat


def rhs(robot, x, y, u, p, v_bound=None):
    """The flow z' of the observer: ``rhs_split`` with the model at y itself;
    robot, x, y, u, p, v_bound as in ``rhs_split``."""
    return rhs_split(robot, x, y, y, u, p, v_bound)


def init(robot, y0, est0, p):
    """z(0) = x2hat(0) - k0 C phi(y(0)) (n,), rad/s; y0 = q(0) (n,) rad, est0 = x2hat(0) (n,) rad/s,
    robot, p as in ``output``."""
    k0, C = _gain(robot, p)
    return np.asarray(est0, dtype=float) - k0 * C @ phi(y0)


def sizes(robot):
    """{"nx", "ny", "nu", "nest"}: n each, n the joints of ``robot``."""
    n = robot.n
    return {"nx": n, "ny": n, "nu": n, "nest": n}
