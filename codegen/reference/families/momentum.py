"""Generalized-momentum observer with detection and isolation (codegen.families.observers.momentum),
numpy, written from the equations (De Luca & Mattone, ICRA 2005; Haddadin et al., T-RO 2017 §IV).

    x2hat  = z + k0 q,   v = sat(x2hat)                               [S000 (9)]
    z'     = M(q)^{-1} [tau + r - C(q, v) v - tau_f(v) - g(q)] - k0 x2hat  [S000 (6)] with tau + r
    p_hat' = tau + C(q, v)^T v - g(q) - tau_f(v) + r
    r      = K_O (M(q) v - p_hat),   p_hat(0) = M(q0) v(0)
    r_f'   = omega_f (r - r_f),      r_f(0) = 0
    alarm_j = |r_f_j| > th0_j + th1_j |x2hat_j|,  link = the last j in alarm (1-based, 0: none)

x = [z (n, rad/s); p_hat (n, N m s); r_f (n, N m)], y = q (n, rad), u = tau (n, N m),
p = [k0 (1/s); K_O (n, 1/s); th0 (n, N m); th1 (n, N m s/rad); omega_f (1/s)],
est = [x2hat (n, rad/s); r_f (n, N m); alarm (n, 0/1); link].
"""
from __future__ import annotations

import numpy as np

from . import reduced_order
from ._family import bound
from ._saturation import saturate, velocity_bound


def configure(robot, options):
    """This family with the declared velocity bound bound (``robot`` the reference robot,
    ``options`` its VelocityBoundOptions or plain Options: no saturation)."""
    return bound(__name__, v_bound=velocity_bound(robot, options))


def _parts(robot, x, p):
    n = robot.n
    x, p = np.asarray(x, float), np.asarray(p, float)
    return x[:n], x[n:2 * n], float(p[0]), p[1:1 + n], p[1 + n:1 + 2 * n], p[1 + 2 * n:1 + 3 * n]


def output(robot, x, y, u, p, v_bound=None):
    """[x2hat; r; alarm; link] (3n + 1,) of the module docstring for ``robot`` (reference robot);
    x (2n,), y = q (n,), u = tau (n,), p (1 + 3n,) as there, the velocity saturated to ``v_bound`` ((n,) rad/s or None)."""
    z, ph, k0, K, th0, th1 = _parts(robot, x, p)
    x2hat = z + k0 * np.asarray(y, float)
    r = np.asarray(x, float)[2 * robot.n:]                 # r_f
    alarm = (np.abs(r) > th0 + th1 * np.abs(x2hat)).astype(float)
    on = np.flatnonzero(alarm)
    link = float(on[-1] + 1) if len(on) else 0.0
    return np.concatenate([x2hat, r, alarm, [link]])


def model(robot, x, y_cfg, y, u, p, v_bound=None):
    """[FD(y_cfg, v, tau + r); tau + C(y_cfg, v)^T v - g(y_cfg) - tau_f(v) + K_O M(y_cfg) v;
    omega_f r] (3n,),
    v = sat(z + k0 y), r = K_O (M(y_cfg) v - p_hat): the model's part of the flow at the
    configuration y_cfg; robot, x, y, u = tau, p as in ``output``, v_bound the velocity bound."""
    z, ph, k0, K, _, _ = _parts(robot, x, p)
    v = saturate(z + k0 * np.asarray(y, float), v_bound)
    u = np.asarray(u, float)
    M = robot.M(y_cfg)
    mom = u + robot.C(y_cfg, v).T @ v - robot.g(y_cfg) - robot.friction_torque(v) + K * (M @ v)
    r = K * (M @ v - ph)                                   # the residual at y_cfg
    return np.concatenate([robot.forward_dynamics(y_cfg, v, u + r), mom, float(p[-1]) * r])


def rhs_model(robot, x, y, u, p, m):
    """[m_1 - k0 x2hat; m_2 - K_O p_hat; m_3 - omega_f r_f] (3n,) with the model's part m (3n,)
    given; robot, x, y, u, p as in ``output``."""
    z, ph, k0, K, _, _ = _parts(robot, x, p)
    m = np.asarray(m, float)
    n = robot.n
    rf = np.asarray(x, float)[2 * n:]
    return np.concatenate([m[:n] - k0 * (z + k0 * np.asarray(y, float)), m[n:2 * n] - K * ph,
                           m[2 * n:] - float(p[-1]) * rf])


def rhs_split(robot, x, y_cfg, y, u, p, v_bound=None):
    """The flow with the model at y_cfg (``model``) and the injection at y; robot, x, u, p,
    v_bound as in ``model``."""
    return rhs_model(robot, x, y, u, p, model(robot, x, y_cfg, y, u, p, v_bound))


def rhs(robot, x, y, u, p, v_bound=None):
    """The flow: ``rhs_split`` with the model at y itself; robot, x, u, p, v_bound as there."""
    return rhs_split(robot, x, y, y, u, p, v_bound)


def rate(robot, x, p):
    """The velocity observer's gain rate k0 = p[0] on z (integrated exactly by etdrk4); robot, x
    unused."""
    return float(p[0])


def rate_states(robot):
    """0/1 per state (3n,) of ``robot``: the rate acts on z only."""
    return np.concatenate([np.ones(robot.n), np.zeros(2 * robot.n)])


def retune(robot, x, y, p_old, p_new):
    """z+ = z + (k0_old - k0_new) y (x2hat continuous), p_hat and r_f kept: x (2n,) at y, the parameters
    p_old to p_new; robot as in ``output``."""
    n = robot.n
    x = np.asarray(x, float).copy()
    x[:n] = reduced_order.retune(robot, x[:n], y, p_old[:1], p_new[:1])
    return x


def init(robot, y0, est0, p, v_bound=None):
    """x(0) = [x2hat(0) - k0 q0; M(q0) sat(x2hat(0)); 0] (r(0) = r_f(0) = 0) for ``robot`` at y0 = q0, est0's
    first n slots x2hat(0), p the parameters, v_bound the velocity bound."""
    n = robot.n
    est0 = np.asarray(est0, float)
    z0 = reduced_order.init(robot, y0, est0[:n], p[:1])
    return np.concatenate([z0, robot.M(y0) @ saturate(est0[:n], v_bound), np.zeros(n)])


def sizes(robot):
    """{"nx": 3n, "ny": n, "nu": n, "nest": 3n + 1}, n the joints of ``robot``."""
    n = robot.n
    return {"nx": 3 * n, "ny": n, "nu": n, "nest": 3 * n + 1}
