"""Reduced-order velocity observer of Cristofaro & De Luca (seed 000, SPEC §1.1).

    M(y) z' = -C(y, x2hat) x2hat - F x2hat - g(y) - M(y) (dk/dy) x2hat + tau     [S000 (6)]
    x2hat   = z + k(y),   k(y) = k0 y                                            [S000 (9)]

so z' = FD(y, x2hat, tau) - k0 x2hat with FD the robot's forward dynamics.
State x = z, measurement y = q, input u = tau, parameter p = [k0], estimate x2hat.
"""
from __future__ import annotations

import casadi as ca

from ..design import reduced_order_gain
from ..spec import ObserverSpec


def flow(robot, z, y, tau, k):
    """(x2hat, z') of the observer with gain k(y) = k y, k a scalar SX  [S000 (6),(9)].

    Shared by the hybrid family (reduced_order_hybrid), where k is the scheduled k_r."""
    x2hat = z + k * y                                                # [S000 (9)]
    zdot = robot.forward_dynamics(y, x2hat, tau) - k * x2hat         # [S000 (6)] with dk/dy = k I
    return x2hat, zdot


def build(robot, k0=None, eta=1.0, v_max=2.0):
    """Reduced-order observer for ``robot``; k0 designed by (12) unless given."""
    design = None
    if k0 is None:
        design = reduced_order_gain(robot, eta=eta, v_max=v_max)
        k0 = design.k0
    n = robot.n
    z, y, tau = ca.SX.sym("z", n), ca.SX.sym("y", n), ca.SX.sym("tau", n)
    k = ca.SX.sym("k0")
    x2hat, zdot = flow(robot, z, y, tau, k)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    q = [f"q_{j}" for j in robot.joint_names]
    return ObserverSpec(
        family="reduced_order", robot=robot,
        x_names=[f"z_{j}" for j in robot.joint_names], y_names=q,
        u_names=[f"tau_{j}" for j in robot.joint_names], p_names=["k0"],
        est_names=[f"qd_hat_{j}" for j in robot.joint_names], p_default=[k0],
        rhs=ca.Function("rhs", [z, y, tau, k], [zdot]),
        output=ca.Function("output", [z, y, tau, k], [x2hat]),
        init=ca.Function("init", [y0, est0, k], [est0 - k * y0]),  # [CODE-KUKA] z(0) = x2hat(0) - k0 y(0)
        design=design.as_dict() if design else {"k0": float(k0), "given": True},
    )
