"""Su–Müller–Zheng non-smooth observer, numpy reference (docs/papers/seed002.md §3.3, seed 002 (35)).

e = qhat - q;  sg = sign (sgn_eps = 0) or tanh(e / sgn_eps)
literal (xian = 0):  qhat' = w,  w' = -K0 sg(e) - (K1 + 1) w - K2 e,  qd_hat = w    [S002 (35)]
Xian    (xian = 1):  qhat' = w + (K1 + 1)(q - qhat),  w' = K0 sg(q - qhat) + K2 (q - qhat),
                     qd_hat = qhat'                                                  [DERIVED]
x = [qhat (n, rad), w (n, rad/s)], y = q (n, rad), u = tau (n, unused), est = [qd_hat, qhat],
p = [K0 (n), K1 (n), K2 (n), xian, sgn_eps (rad)]; init from est0 = [qd_hat(0), qhat(0)],
w(0) = qd_hat(0) (literal) or qd_hat(0) - (K1 + 1)(q(0) - qhat(0)) (Xian).
"""
from __future__ import annotations

import numpy as np


def _sg(e, eps):
    return np.tanh(e / eps) if eps > 0 else np.sign(e)


def _parts(robot, x, y, p):
    n = robot.n
    return n, x[:n], x[n:], p[:n], p[n:2 * n], p[2 * n:3 * n], p[3 * n], p[3 * n + 1]


def output(robot, x, y, u, p):
    """est = [qd_hat; qhat]  [S002 (35)] (literal) or [DERIVED] (Xian).

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (2n,) array
        [qhat (rad); w (rad/s)].
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m (unused).
    p : (3n + 2,) array
        [K0; K1; K2 (n each); xian (0 or 1); sgn_eps (rad, 0: sign)].

    Returns
    -------
    (2n,) array
        [qd_hat (rad/s); qhat (rad)].
    """
    n, qhat, w, K0, K1, K2, xian, eps = _parts(robot, x, y, p)
    if xian == 1.0:
        qd_hat = w + (K1 + 1.0) * (y - qhat)
    elif xian == 0.0:
        qd_hat = w
    else:
        raise ValueError(f"xian must be 0 (literal form) or 1 (Xian form), got {xian}")
    return np.concatenate([qd_hat, qhat])


def rhs(robot, x, y, u, p):
    """[qhat' (rad/s); w' (rad/s^2)] (2n,) of the form ``xian`` selects  [S002 (35)], [DERIVED];
    ``robot``, ``x``, ``y``, ``u`` (unused) and ``p`` as in ``output``."""
    n, qhat, w, K0, K1, K2, xian, eps = _parts(robot, x, y, p)
    qd_hat = output(robot, x, y, u, p)[:n]
    if xian == 1.0:
        wdot = K0 * _sg(y - qhat, eps) + K2 * (y - qhat)
    else:
        wdot = -K0 * _sg(qhat - y, eps) - (K1 + 1.0) * w - K2 * (qhat - y)
    return np.concatenate([qd_hat, wdot])


def init(robot, y0, est0, p):
    """qhat(0) = est0[n:], w(0) from qd_hat(0) = est0[:n] (module docstring).

    Parameters
    ----------
    robot : reference robot (n joints)
    y0 : (n,) array
        q(0), rad.
    est0 : (2n,) array
        [qd_hat(0) (rad/s); qhat(0) (rad)].
    p : (3n + 2,) array
        As in ``output``.

    Returns
    -------
    (2n,) array
    """
    n = robot.n
    qd0, qhat0 = est0[:n], est0[n:]
    K1, xian = p[n:2 * n], p[3 * n]
    w0 = qd0 - (K1 + 1.0) * (y0 - qhat0) if xian == 1.0 else qd0
    return np.concatenate([qhat0, w0])


def sizes(robot):
    """{"nx": 2n, "ny": n, "nu": n, "nest": 2n} for ``robot`` with n joints."""
    n = robot.n
    return {"nx": 2 * n, "ny": n, "nu": n, "nest": 2 * n}
