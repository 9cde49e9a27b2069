"""Spong's controllers for elastic-joint robots (seed 004 §4, docs/papers/seed004.md §9, §10), as specs.

Both are static laws, ObserverSpec-shaped with a 1-slot dummy state (nx = 1, never changes) so
they emit and compile through ``compile_observer``; call ``estimate(y, [])`` for u. The
measurement is y = [x (4n); q_d; q_d'; q_d''; q_d'''; q_d''''] (9n): the (true or estimated)
state and the reference derivatives. The output is u, saturated at +-u_max (200 N m, §12.4).

Feedback linearisation (docs/papers/seed004.md §9) with Spong coordinates y = Phi(x) = [q1, q1', q1'', q1''']:

    y'''' = F(x) + M^{-1} K J^{-1} u,   F = L_f^4 q1
    u  = J K^{-1} M(q1) (nu - F(x))                                       [S004 (4.5)]
    nu = q_d'''' + K_c (y - y_d)   (per joint row -[a0, a1, a2, a3])       [S004 (4.7)]

Integral manifold (docs/papers/seed004.md §10), mu = K^{-1}, z = K(q1 - q2):

    u0 = (M + J)(q_d'' + K_P (q_d - q1) + K_D (q_d' - q1')) + c + g       [CODE-CP]
    h0 = -A2^{-1}(a2 + B2 u0),  a2 = -M^{-1}(c + g), A2 = -(M^{-1} + J^{-1}), B2 = -J^{-1}  (4.18)
    u_s = u0 + mu B2^{-1} h0''                                           (4.17), (4.19)
    eta = z - h0,  eta' = K(q1' - q2') - h0',  u_f = -J(zeta - A2 eta),  zeta = K_f [eta; eta']  (4.23)
    u = sat(u_s + u_f)

h0' and h0'' by the chain rule with q1'' := y3(x), q1''' := y4(x) [CODE-CP].
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...core import symbolic as sym
from ..design import spong_fast_gains, spong_fl_gains
from ...core.spec import ObserverSpec


def _io(robot):
    n = robot.n
    y = ca.SX.sym("y", 9 * n)
    x = y[:4 * n]
    qd = [y[(4 + k) * n:(5 + k) * n] for k in range(5)]
    j = robot.joint_names
    y_names = list(robot.state_names) + [f"qd{'_' + 'd' * k if k else ''}_{a}" for k in range(5) for a in j]
    return y, x, qd, y_names


def _spong_coordinates(robot, x):
    """[y1, y2, y3, y4] (Lie derivatives of h = q1) and F = L_f^4 q1."""
    chain = sym.lie_chain(robot.link_positions(x), x, robot.drift(x), 4)
    return chain[:4], chain[4]


def _spec(robot, family, y, y_names, p, p_names, p_default, u, design):
    n = robot.n
    xs, e, y0 = ca.SX.sym("s", 1), ca.SX.sym("u_in", 0), ca.SX.sym("y0", 9 * n)
    est0 = ca.SX.sym("est0", n)
    return ObserverSpec(
        family=family, robot=robot, x_names=["dummy"], y_names=y_names, u_names=[],
        p_names=p_names, est_names=[f"u_{a}" for a in robot.joint_names], p_default=p_default,
        rhs=ca.Function("rhs", [xs, y, e, p], [ca.SX.zeros(1)]),
        output=ca.Function("output", [xs, y, e, p], [ca.cse(u)]),
        init=ca.Function("init", [y0, est0, p], [ca.SX.zeros(1)]), design=design)


def _saturate(u, umax):
    return ca.fmin(ca.fmax(u, -umax), umax)


def feedback_linearization(robot, poles=None, u_max=200.0):
    """Spong FL controller (docs/papers/seed004.md §9)  [S004 (4.5), (4.7)], as a static spec.

    Parameters
    ----------
    robot : models.ElasticRobot
        n joints.
    poles : (4n,) array_like, optional
        Closed-loop poles (1/s), four per joint in order; default -5{1..4n}.
    u_max : float
        Saturation of each motor torque, N m (default 200, docs/papers/experiments.md §12.4).

    Returns
    -------
    codegen.core.spec.ObserverSpec
        Family ``spong_fl``: 1 dummy state, y (9n,) = [x; q_d .. q_d''''], est = u (n,), N m;
        p = [Kc (4 per joint); u_max].
    """
    n = robot.n
    poles = -5.0 * np.arange(1, 4 * n + 1) if poles is None else np.asarray(poles, float)
    y, x, qd, y_names = _io(robot)
    Kc = ca.SX.sym("Kc", 4 * n)
    umax = ca.SX.sym("u_max")
    phi, F = _spong_coordinates(robot, x)
    nu = qd[4]
    for k in range(4):                                  # nu = yd'''' + Kc (y - yd)     (4.7)
        nu = nu + Kc[k::4] * (phi[k] - qd[k])
    M = robot.rigid.mass_matrix(robot.link_positions(x))
    u = ca.mtimes([ca.DM(robot.J @ np.linalg.inv(robot.K)), M, nu - F])     # (4.5)
    return _spec(robot, "spong_fl", y, y_names, ca.vertcat(Kc, umax),
                 [f"Kc{k}_{a}" for a in robot.joint_names for k in range(4)] + ["u_max"],
                 np.r_[spong_fl_gains(n, poles), u_max], _saturate(u, umax),
                 {"poles": poles.tolist()})


def integral_manifold(robot, KP=7000.0, KD=7000.0, fast_poles=None, u_max=200.0):
    """Spong integral-manifold controller (docs/papers/seed004.md §10)  [S004 (4.17)-(4.23)], as a static spec.

    Parameters
    ----------
    robot : models.ElasticRobot
        n joints.
    KP, KD : float
        Gains of the rigid (slow) law u0 on q_d - q1 (1/s^2) and q_d' - q1' (1/s); default
        7000 each (docs/papers/seed004.md §10).
    fast_poles : (2n,) array_like, optional
        Eigenvalues of the fast (boundary-layer) loop, 1/s, two per joint in order; default
        -70{1.1, 1.2, ...} (the seed's set, A4-5).
    u_max : float
        Saturation of each motor torque, N m (default 200, docs/papers/experiments.md §12.4).

    Returns
    -------
    codegen.core.spec.ObserverSpec
        Family ``spong_manifold``: 1 dummy state, y (9n,) = [x; q_d .. q_d''''], est = u (n,),
        N m; p = [K_P (n); K_D (n); K_f (eta, eta' per joint); u_max].
    """
    n = robot.n
    if fast_poles is None:
        fast_poles = -70.0 * (1.0 + 0.1 * np.arange(1, 2 * n + 1))
    fast_poles = np.asarray(fast_poles, dtype=float)
    y, x, qd, y_names = _io(robot)
    pKP, pKD, pKf = ca.SX.sym("KP", n), ca.SX.sym("KD", n), ca.SX.sym("Kf", 2 * n)
    umax = ca.SX.sym("u_max")
    rigid, J, K = robot.rigid, ca.DM(robot.J), ca.DM(robot.K)
    Jinv, Kinv = ca.DM(np.linalg.inv(robot.J)), ca.DM(np.linalg.inv(robot.K))
    x1, x2, x3, x4 = robot.split(x)
    phi, _ = _spong_coordinates(robot, x)

    # h0 as a function of the independent variables w = [q1, q1', qd, qd', qd''] (CODE-CP)
    q, v = ca.SX.sym("q", n), ca.SX.sym("v", n)
    r0, r1, r2 = ca.SX.sym("r0", n), ca.SX.sym("r1", n), ca.SX.sym("r2", n)
    d2q, d3q = ca.SX.sym("d2q", n), ca.SX.sym("d3q", n)
    r3, r4 = ca.SX.sym("r3", n), ca.SX.sym("r4", n)
    M = rigid.mass_matrix(q)
    cg = rigid.nle(q, v) + rigid.friction_torque(v)                           # c includes tau_f(q1')
    u0 = ca.mtimes(M + J, r2 + pKP * (r0 - q) + pKD * (r1 - v)) + cg          # [CODE-CP] (4.20) A4-7
    Minv_cg = ca.solve(M, cg)
    A2 = -(ca.inv(M) + Jinv)
    h0 = ca.solve(-A2, -Minv_cg - ca.mtimes(Jinv, u0))                        # (4.18)
    w = ca.vertcat(q, v, r0, r1, r2)
    dh0 = ca.jtimes(h0, w, ca.vertcat(v, d2q, r1, r2, r3))
    w2 = ca.vertcat(q, v, d2q, r0, r1, r2, r3)
    ddh0 = ca.jtimes(dh0, w2, ca.vertcat(v, d2q, d3q, r1, r2, r3, r4))
    us = u0 + ca.mtimes(Kinv, -ca.mtimes(J, ddh0))                             # (4.17), (4.19)
    z = ca.mtimes(K, q - x3)
    eta = z - h0
    etad = ca.mtimes(K, v - x4) - dh0
    zeta = pKf[0::2] * eta + pKf[1::2] * etad
    uf = -ca.mtimes(J, zeta - ca.mtimes(A2, eta))                              # (4.23)
    u = ca.substitute(us + uf, ca.vertcat(q, v, r0, r1, r2, r3, r4, d2q, d3q),
                      ca.vertcat(x1, x2, *qd, phi[2], phi[3]))
    return _spec(robot, "spong_manifold", y, y_names, ca.vertcat(pKP, pKD, pKf, umax),
                 [f"{g}_{a}" for g in ("KP", "KD") for a in robot.joint_names]
                 + [f"Kf{k}_{a}" for a in robot.joint_names for k in ("eta", "etad")] + ["u_max"],
                 np.r_[np.full(n, KP), np.full(n, KD), spong_fast_gains(n, fast_poles, np.diag(robot.K)), u_max],
                 _saturate(u, umax), {"fast_poles": fast_poles.tolist()})


def cubic_reference(t, q0, qf, T):
    """Rest-to-rest cubic q_d(t) and derivatives up to 4 (docs/papers/experiments.md §12.4, A4-9): (5, n) array at time
    ``t`` (s), from ``q0`` to ``qf`` (n,) (rad) over [0, T] (s), held outside."""
    q0, qf = np.asarray(q0, float), np.asarray(qf, float)
    s = min(max(t / T, 0.0), 1.0)
    dq = qf - q0
    moving = 0.0 < t < T
    return np.stack([q0 + dq * (3 * s ** 2 - 2 * s ** 3),
                     dq * (6 * s - 6 * s ** 2) / T if moving else 0 * dq,
                     dq * (6 - 12 * s) / T ** 2 if moving else 0 * dq,
                     -12 * dq / T ** 3 if moving else 0 * dq,
                     0 * dq])


ELASTIC = True       # both laws act on an ElasticRobot
LAWS = {"spong_fl": feedback_linearization, "spong_manifold": integral_manifold}
