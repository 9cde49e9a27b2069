"""Full-order velocity observer of Nicosia & Tomei (1990), the comparison in seed 000 (SPEC §2).

    x1tilde = y - x1hat
    x1hat'  = x2hat + K_D x1tilde                                    [CODE-KUKA SimObserver]
    x2hat'  = M(y)^{-1}[tau - C(y, x1hat') x1hat' - F x1hat' - g(y) + K_P x1tilde]
            = FD(y, x1hat', tau + K_P x1tilde)                        [DERIVED, SPEC §2]

C is evaluated at x1hat', not at x2hat (A0-6: the proof needs x1hat'). K_D = k_D I with
k_D = k0 of (12) (the same gain condition [S000 Rem. 4]); K_P = k_P I, k_P = 500 [ASSUMPTION].
State x = [x1hat; x2hat], measurement y = q, input u = tau, p = [kd, kp], estimate x2hat.
"""
from __future__ import annotations

import casadi as ca

from ..design import reduced_order_gain
from ..options import InputRanges
from ..spec import ObserverSpec

KP_DEFAULT = 500.0   # [ASSUMPTION SPEC §2, A0-4]


def build(robot, kd=None, kp=KP_DEFAULT, eta=1.0, v_max=2.0):
    """Nicosia–Tomei observer for ``robot``; kd = k0 of (12) unless given."""
    design = None
    if kd is None:
        design = reduced_order_gain(robot, eta=eta, v_max=v_max)
        kd = design.k0                          # [CODE-KUKA controller.hpp] k0 plays the role of kd
    n = robot.n
    x1hat, x2hat = ca.SX.sym("x1hat", n), ca.SX.sym("x2hat", n)
    y, tau = ca.SX.sym("y", n), ca.SX.sym("tau", n)
    kd_s, kp_s = ca.SX.sym("kd"), ca.SX.sym("kp")
    x, p = ca.vertcat(x1hat, x2hat), ca.vertcat(kd_s, kp_s)
    x1tilde = y - x1hat
    x1hat_dot = x2hat + kd_s * x1tilde
    x2hat_dot = robot.forward_dynamics(y, x1hat_dot, tau + kp_s * x1tilde)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    joints = robot.joint_names
    report = {"kd": float(kd), "kp": float(kp), **({"reduced_order": design.as_dict()} if design else {})}
    return ObserverSpec(
        family="nicosia_tomei", robot=robot,
        x_names=[f"q_hat_{j}" for j in joints] + [f"qd_hat_{j}" for j in joints],
        y_names=[f"q_{j}" for j in joints], u_names=[f"tau_{j}" for j in joints],
        p_names=["kd", "kp"], est_names=[f"qd_hat_{j}" for j in joints], p_default=[kd, kp],
        rhs=ca.Function("rhs", [x, y, tau, p], [ca.vertcat(x1hat_dot, x2hat_dot)]),
        output=ca.Function("output", [x, y, tau, p], [x2hat]),
        init=ca.Function("init", [y0, est0, p], [ca.vertcat(y0, est0)]),   # [CODE-KUKA] x1hat(0) = y(0)
        design=report,
        # cross-check inputs: positions within a few rad, speeds ~10 rad/s
        inputs=InputRanges(x_scale=(3.0,) * n + (10.0,) * n),
    )
