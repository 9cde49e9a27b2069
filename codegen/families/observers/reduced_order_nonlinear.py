"""Reduced-order velocity observer with a nonlinear gain k(y) = k0 K1(y) (seed 000 §VI,
deformation reduction; beyond the paper, docs/papers/seed000.md §1.1 with a general k):

    M(y) z' = -C(y, x2hat) x2hat - F x2hat - g(y) - M(y) (dk/dy) x2hat + tau     [S000 (6)]
    x2hat   = z + k(y),   k(y) = k0 K1(y),   K1(y) = C phi(y)                    [S000 §VI]

so z' = FD(y, sat(x2hat), tau) - k0 (C dphi/dy) x2hat with FD the robot's forward dynamics at the
estimate saturated to the velocity bound (codegen.families.observers._bound); phi is
the basis of ``codegen.families.design.reduced_order_nonlinear`` (K1 and k0 designed there, (12')).
State x = z, measurement y = q, input u = tau, parameters p = [k0, C (row-major, n x nb)],
estimate x2hat; z(0) = x2hat(0) - k0 K1(y(0)).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..design.reduced_order_nonlinear import feature_count, features, nonlinear_gain
from ...core.options import VelocityBoundOptions
from ...core.spec import ObserverSpec, split_flow
from . import _bound

# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"}]


def build(robot, k0=None, C=None, eta=1.0, v_max=2.0, v_bound=None):
    """Reduced-order observer with k(y) = k0 C phi(y) for ``robot``; K1 and k0 designed by
    deformation reduction and (12') unless both are given (C: (n, nb) array); ``eta``, ``v_max``
    (rad/s): the error radius and speed bound of (12'); ``v_bound`` (rad/s, a number or one per
    joint): where the model's velocity argument saturates (default twice the URDF velocity
    limit, else twice v_max; codegen.families.observers._bound)."""
    n, nb = robot.n, feature_count(robot.n)
    if (k0 is None) != (C is None):
        raise ValueError("give both k0 and C, or neither (then both are designed)")
    if k0 is None:
        design = nonlinear_gain(robot, eta=eta, v_max=v_max)
        k0, C, report = design.k0, design.C, design.as_dict()
    else:
        report = {"k0": float(k0), "given": True}
    C = np.asarray(C, dtype=float)
    if C.shape != (n, nb):
        raise ValueError(f"C must have shape ({n}, {nb}), got {C.shape}")
    z, y, y_cfg, tau = ca.SX.sym("z", n), ca.SX.sym("y", n), ca.SX.sym("y_cfg", n), ca.SX.sym("tau", n)
    pk, pC = ca.SX.sym("k0"), ca.SX.sym("C", n * nb)
    Cm = ca.reshape(pC, nb, n).T                                           # row-major p -> (n, nb)
    phi = features(y)
    x2hat = z + pk * ca.mtimes(Cm, phi)                                    # [S000 §VI]
    # (6), the model at y_cfg (ObserverSpec.rhs_split), the gain's dk/dy at y
    dk_dy = pk * ca.mtimes(Cm, ca.jacobian(phi, y))
    bound = _bound.velocity_bound(robot, v_max, v_bound)
    zdot = robot.forward_dynamics(y_cfg, _bound.saturate(x2hat, bound), tau) - ca.mtimes(dk_dy, x2hat)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    p = ca.vertcat(pk, pC)
    rhs, rhs_split = split_flow(z, y_cfg, y, tau, p, zdot)
    names = robot.joint_names
    return ObserverSpec(
        family="reduced_order_nonlinear", robot=robot,
        x_names=[f"z_{j}" for j in names], y_names=[f"q_{j}" for j in names],
        u_names=[f"tau_{j}" for j in names], est_names=[f"qd_hat_{j}" for j in names],
        p_names=["k0"] + [f"C_{i}_{b}" for i in range(n) for b in range(nb)],
        p_default=np.r_[k0, C.ravel()],
        rhs=rhs, rhs_split=rhs_split,
        output=ca.Function("output", [z, y, tau, p], [x2hat]),
        init=ca.Function("init", [y0, est0, p], [est0 - pk * ca.mtimes(Cm, ca.substitute(phi, y, y0))]),
        options=VelocityBoundOptions(v_bound=tuple(bound)),
        design={**report, **_bound.report(robot, bound, v_max, v_bound is not None)},
    )
