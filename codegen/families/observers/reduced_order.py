"""Reduced-order velocity observer of Cristofaro & De Luca (seed 000, docs/papers/seed000.md §1.1).

    M(y) z' = -C(y, x2hat) x2hat - F x2hat - g(y) - M(y) (dk/dy) x2hat + tau     [S000 (6)]
    x2hat   = z + k(y),   k(y) = k0 y                                            [S000 (9)]

so z' = FD(y, x2hat, tau) - k0 x2hat with FD the robot's forward dynamics, evaluated at the
estimate saturated to the velocity bound b (codegen.families.observers._bound):
z' = FD(y, sat_b(x2hat), tau) - k0 x2hat, the published observer wherever |x2hat_j| <= b_j.
State x = z, measurement y = q, input u = tau, parameter p = [k0], estimate x2hat.
"""
from __future__ import annotations

import casadi as ca

from ..design import reduced_order_design, reduced_order_gain
from ...core.options import VelocityBoundOptions
from ...core.spec import ObserverSpec, split_model
from . import _bound
from ._design import check_design, design_discretization, stable_report

TUNE = {"k0": 1}          # the bandwidth a log tunes (codegen.logs.tune): k0 ~ s
# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"}]


def flow(robot, z, y_cfg, y, tau, k, bound, m=None):
    """(x2hat, z') of the observer with gain k(y) = k y, k a scalar SX  [S000 (6),(9)], for ``robot``
    at state z, measurement y = q and torque ``tau`` (SX vectors (n,)), the model (M, C, g, F)
    at the configuration ``y_cfg`` (y itself in the continuous-time observer; ObserverSpec.rhs_split)
    and at the estimate saturated to ``bound`` ((n,) rad/s, codegen.families.observers._bound).
    ``m`` (SX (n,), optional): a symbol standing for the model's acceleration, z' = m - k x2hat
    (ObserverSpec.rhs_model; ``model`` gives the acceleration itself).

    Shared by the hybrid and switched families, where k is the scheduled or switched gain."""
    x2hat = z + k * y                                                # [S000 (9)]
    a = model(robot, z, y_cfg, y, tau, k, bound) if m is None else m
    return x2hat, a - k * x2hat                                      # [S000 (6)] with dk/dy = k I


def model(robot, z, y_cfg, y, tau, k, bound):
    """FD(y_cfg, sat(x2hat), tau), x2hat = z + k y, saturated to ``bound``: the model's part of
    ``flow`` for ``robot`` (z, y_cfg, y, tau, k, bound as there)."""
    return robot.forward_dynamics(y_cfg, _bound.saturate(z + k * y, bound), tau)


def build(robot, k0=None, eta=1.0, v_max=2.0, noise=None, quantization=None, uncertainty=0.0,
          design="noise", dt=None, t_conv=0.2, torque_uncertainty=0.0, v_bound=None):
    """Reduced-order observer for ``robot``.

    Parameters
    ----------
    robot : RobotModel
    k0 : float, optional
        The gain (1/s); given, it bypasses the design (not the stability check at compile time).
    eta, v_max : float
        (12)'s error radius and speed bound (rad/s); v_max is also the initial error of the
        convergence floor (the estimate starts at 0, the robot at up to v_max).
    noise, quantization : float or None
        Gaussian std and quantisation step of the measured q (rad); both None: a 2^16 counts/rev
        encoder (codegen.families.design.noise).
    uncertainty : float
        Relative error of the model's masses and inertias (0.1 = 10 %).
    torque_uncertainty : float, sequence of n floats or dict joint -> float
        Torque error per joint (N m: an offset, unmodelled friction or payload; e.g. the torque
        residual of an identification, ``report["residual_rms"]["after"]`` of
        codegen.logs.identify), a number for every joint or one per joint; its bias
        rms_q ||M^-1 diag(t)||_F / k0 enters the predicted error (codegen.families.design.noise).
    v_bound : float or sequence of n floats, optional
        Speed (rad/s) at which the model's velocity argument saturates; default twice the URDF
        velocity limit, else twice v_max (codegen.families.observers._bound).
    design : {"noise", "guarantee"}
        The default k0: the predicted-error minimiser (report: codegen.families.design.NoiseAwareDesign)
        or (12).
    dt : float, optional
        Sample time the default is designed for (default: codegen.core.target.DEFAULT_DISCRETIZATION).
    t_conv : float
        Time (s) to fall below 1e-2 rad/s from v_max (the floor of the noise-aware gain).
    """
    report = None
    bound = _bound.velocity_bound(robot, v_max, v_bound)
    if k0 is None:
        disc = design_discretization(dt)
        if check_design(design) == "guarantee":
            report = reduced_order_gain(robot, eta=eta, v_max=v_max).as_dict()
            k0 = report["k0"]
        else:
            nd = reduced_order_design(robot, disc.dt, noise, quantization, uncertainty, eta, v_max, t_conv,
                                      torque_uncertainty)
            report, k0 = nd.as_dict(), nd.k0
    spec = _spec(robot, k0, report, bound, _bound.report(robot, bound, v_max, v_bound is not None))
    return spec if report is None else stable_report(spec, disc)


def _spec(robot, k0, report, bound, bound_report):
    n = robot.n
    z, y, y_cfg, tau = ca.SX.sym("z", n), ca.SX.sym("y", n), ca.SX.sym("y_cfg", n), ca.SX.sym("tau", n)
    k, k_new = ca.SX.sym("k0"), ca.SX.sym("k0_new")
    m = ca.SX.sym("m", n)
    x2hat, zdot = flow(robot, z, y_cfg, y, tau, k, bound, m)
    rhs, rhs_split, fd, rhs_model = split_model(z, y_cfg, y, tau, k, m, model(robot, z, y_cfg, y, tau, k, bound),
                                                zdot)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    q = [f"q_{j}" for j in robot.joint_names]
    return ObserverSpec(
        family="reduced_order", robot=robot,
        x_names=[f"z_{j}" for j in robot.joint_names], y_names=q,
        u_names=[f"tau_{j}" for j in robot.joint_names], p_names=["k0"],
        est_names=[f"qd_hat_{j}" for j in robot.joint_names], p_default=[k0],
        rhs=rhs, rhs_split=rhs_split, model=fd, rhs_model=rhs_model,
        output=ca.Function("output", [z, y, tau, k], [x2hat]),
        init=ca.Function("init", [y0, est0, k], [est0 - k * y0]),  # [CODE-KUKA] z(0) = x2hat(0) - k0 y(0)
        # z' = [FD(y, x2hat) - k0^2 y] - k0 z: the gain rate k0 on every z, integrated exactly
        rate=ca.Function("rate", [z, k], [k]), rate_states=[f"z_{j}" for j in robot.joint_names],
        # bumpless retuning: z+ = z + (k0_old - k0_new) y keeps x2hat continuous [DERIVED, docs/papers/seed000.md §1.3]
        retune=ca.Function("retune", [z, y, k, k_new], [z + (k - k_new) * y]), gains={"k0": ("k0",)},
        options=VelocityBoundOptions(v_bound=tuple(bound)),
        design={**(report or {"k0": float(k0), "given": True}), **bound_report},
    )
