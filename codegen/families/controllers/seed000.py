"""Control laws of the seed-000 experiments (docs/papers/seed000.md §1.4, docs/papers/experiments.md §12.1), as specs like any observer.

A law is an ObserverSpec with no state (nx = 0): its measurement vector carries what the law
reads (joint positions, velocity estimate, time), it has no input, and its "estimate" is the
torque. So it is emitted, compiled and loaded through ``compile_observer`` like any block.

    open_loop(robot, 1):  tau = g(q) + (cos(t/2), -cos t)                 [S000 (18)]
    open_loop(robot, 2):  tau = g(q) + (cos t, -1 + sin 2t)               [S000 (19)]
    tracking(robot, ...): tau = M(q)(qdd_d + Lambda(qd_d - x2hat))
                                + C(q, x2hat)(qd_d + Lambda(q_d - q)) + g(q)
                                + K_P (q_d - q) + K_D (qd_d - x2hat)      [S000 eq. after Fig. 5]
with q_d a quintic rest-to-rest motion q_start -> q_goal over ``[0, T_move]`` [ASSUMPTION docs/papers/experiments.md §12.1].
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...core.spec import ObserverSpec

LAMBDA = 0.5                                   # [S000] Lambda = 0.5 I
KP = (40.0, 60.0)                              # [S000] K_P = diag(40, 60)
KD = (60.0, 90.0)                              # [S000] K_D = diag(60, 90)
Q_GOAL = (np.pi / 4, -np.pi / 3)               # [S000] qbar = (pi/4, -pi/3)
T_MOVE = 8.0                                   # [S000] reached at t = 8 s


# ----------------------------------------------------------------------------- reference motion
def quintic_profile(s, T):
    """(h, h', h'') of the rest-to-rest quintic h(s) = 10 s^3 - 15 s^4 + 6 s^5, s = t/T in [0, 1],
    differentiated in t. Plain arithmetic, so it serves numpy arrays and CasADi SX alike."""
    h = s ** 3 * (10 - 15 * s + 6 * s ** 2)
    hd = 30 * s ** 2 * (1 - 2 * s + s ** 2) / T
    hdd = 60 * s * (1 - 3 * s + 2 * s ** 2) / T ** 2
    return h, hd, hdd


def quintic(t, q_start, q_goal, T=T_MOVE):
    """Numeric reference (q_d, qd_d, qdd_d), each (len(t), n), for times ``t`` (s), rest-to-rest
    from ``q_start`` to ``q_goal`` (n,) (rad) over [0, T] (s), held outside  [ASSUMPTION §12.1]."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    s = np.clip(t / T, 0.0, 1.0)[:, None]
    h, hd, hdd = quintic_profile(s, T)
    dq = np.asarray(q_goal, float) - np.asarray(q_start, float)
    return np.asarray(q_start, float) + h * dq, hd * dq, hdd * dq


# ----------------------------------------------------------------------------- laws as specs
def _law(robot, family, y_names, y, p_names, p, p_default, tau):
    joints = robot.joint_names
    x, u = ca.SX.sym("x", 0), ca.SX.sym("u", 0)
    y0, est0 = ca.SX.sym("y0", len(y_names)), ca.SX.sym("est0", robot.n)
    return ObserverSpec(
        family=family, robot=robot, x_names=[], y_names=y_names, u_names=[], p_names=p_names,
        est_names=[f"tau_{j}" for j in joints], p_default=p_default,
        rhs=ca.Function("rhs", [x, y, u, p], [ca.SX(0, 1)]),
        output=ca.Function("output", [x, y, u, p], [tau]),
        init=ca.Function("init", [y0, est0, p], [ca.SX(0, 1)]))


def open_loop(robot, example=1):
    """Gravity-compensated open-loop torque of Example 1 (18) or Example 2 (19) as a stateless spec.

    Measurement slots y = [q_1 .. q_n, t]; the output is tau (2R robots only).

    Parameters
    ----------
    robot : models.RobotModel
        A 2-joint robot (ValueError otherwise).
    example : {1, 2}
        tau = g(q) + (cos(t/2), -cos t)  [S000 (18)] or g(q) + (cos t, -1 + sin 2t)  [S000 (19)].

    Returns
    -------
    codegen.core.spec.ObserverSpec
        Family ``seed000_torque_ex<example>``, nx = 0, y (3,), no input, est = tau (2,), N m.
    """
    if robot.n != 2 or example not in (1, 2):
        raise ValueError(f"open_loop: needs a 2-joint robot and example 1 or 2, got n={robot.n}, {example!r}")
    q, t = ca.SX.sym("q", 2), ca.SX.sym("t")
    if example == 1:
        extra = ca.vertcat(ca.cos(t / 2), -ca.cos(t))                  # [S000 (18)]
    else:
        extra = ca.vertcat(ca.cos(t), -1 + ca.sin(2 * t))              # [S000 (19)]
    names = [f"q_{j}" for j in robot.joint_names] + ["t"]
    p = ca.SX.sym("p", 0)
    return _law(robot, f"seed000_torque_ex{example}", names, ca.vertcat(q, t), [], p, [],
                robot.gravity(q) + extra)


def tracking(robot, q_start, q_goal=Q_GOAL, T=T_MOVE, lam=LAMBDA, kp=KP, kd=KD):
    """Example-3 output-feedback law fed by the observer's velocity estimate x2hat
    [S000 eq. after Fig. 5], as a stateless spec.

    Measurement slots y = [q (n), x2hat (n), t]; parameters p = [q_start (n), q_goal (n),
    T_move, lambda, kp (n), kd (n)] (diagonal gains); output tau.

    Parameters
    ----------
    robot : models.RobotModel
        n joints.
    q_start : (n,) array_like or float
        Start of the quintic reference, rad (the robot's q(0) in the scenario).
    q_goal : (n,) array_like or float
        Goal qbar, rad; default (pi/4, -pi/3)  [S000].
    T : float
        Duration of the rest-to-rest motion T_move, s; default 8.
    lam : float
        Lambda = lam I, 1/s; default 0.5  [S000].
    kp, kd : (n,) array_like or float
        Diagonals of K_P (N m/rad) and K_D (N m s/rad); defaults diag(40, 60), diag(60, 90)  [S000].

    Returns
    -------
    codegen.core.spec.ObserverSpec
        Family ``seed000_tracking``, nx = 0, y (2n + 1,), no input, est = tau (n,), N m; the
        arguments are the defaults of its runtime parameters p.
    """
    n, joints = robot.n, robot.joint_names
    q, x2hat, t = ca.SX.sym("q", n), ca.SX.sym("x2hat", n), ca.SX.sym("t")
    q0, q1 = ca.SX.sym("q_start", n), ca.SX.sym("q_goal", n)
    T_s, lam_s = ca.SX.sym("T_move"), ca.SX.sym("lambda")
    kp_s, kd_s = ca.SX.sym("kp", n), ca.SX.sym("kd", n)
    s = ca.fmin(ca.fmax(t / T_s, 0), 1)
    h, hd, hdd = quintic_profile(s, T_s)
    q_d, qd_d, qdd_d = q0 + h * (q1 - q0), hd * (q1 - q0), hdd * (q1 - q0)
    M, C = robot.mass_matrix(q), robot.coriolis(q, x2hat)
    tau = (ca.mtimes(M, qdd_d + lam_s * (qd_d - x2hat))                # [S000 eq. after Fig. 5]
           + ca.mtimes(C, qd_d + lam_s * (q_d - q)) + robot.gravity(q)
           + kp_s * (q_d - q) + kd_s * (qd_d - x2hat))
    names = ([f"q_{j}" for j in joints] + [f"qd_hat_{j}" for j in joints] + ["t"])
    p_names = ([f"q_start_{j}" for j in joints] + [f"q_goal_{j}" for j in joints] + ["T_move", "lambda"]
               + [f"kp_{j}" for j in joints] + [f"kd_{j}" for j in joints])
    p_default = np.concatenate([np.broadcast_to(np.asarray(v, float), (n,)) for v in (q_start, q_goal)]
                               + [[T, lam]]
                               + [np.broadcast_to(np.asarray(v, float), (n,)) for v in (kp, kd)])
    return _law(robot, "seed000_tracking", names, ca.vertcat(q, x2hat, t), p_names,
                ca.vertcat(q0, q1, T_s, lam_s, kp_s, kd_s), p_default, tau)


LAWS = {"seed000_torque_ex1": lambda robot, **kw: open_loop(robot, example=1, **kw),
        "seed000_torque_ex2": lambda robot, **kw: open_loop(robot, example=2, **kw),
        "seed000_tracking": tracking}
