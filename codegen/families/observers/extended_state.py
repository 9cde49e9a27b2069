"""Model-based extended-state observer: the robot model plus a per-joint disturbance estimate
[DERIVED; the extended-state observer of Han, IEEE TIE 56(3) 2009, with the model's acceleration
as its known part].

The reduced-order and Nicosia–Tomei observers trust the model: a model error e (masses and
inertias off, a torque offset, friction the model lacks) leaves a velocity error ~ e / k0. Here
the model error is a state, estimated from the position residual, so a slowly varying e leaves
no steady bias:

    e_y     = y - q_hat
    q_hat'  = v_hat + l1 e_y
    v_hat'  = FD(y, sat(v_hat), tau) + d_hat + l2 e_y
    d_hat'  = l3 e_y,       (l1, l2, l3) = (3 w, 3 w^2, w^3): the error poles at -w (triple)

per joint, whatever the robot's inertia (the injection is in accelerations, not torques, so no
lightly damped light-link modes as with Nicosia–Tomei's scalar kp); sat: the velocity bound of
codegen.families.observers._bound (the model's velocity argument, the published observer inside
it). The default w minimises the predicted error for the sensor noise, the model uncertainty
and the torque uncertainty, at or above the floor that converges in t_conv
(codegen.families.design.noise.extended_state_noise_gain).

The estimate of the model error is also an output, as a torque:

    tau_d_hat = M(y) d_hat       (N m per joint)

the torque the model misses (M qdd = tau + tau_d - C qd - F qd - g): an external contact, friction,
an offset or a payload; for collision detection and friction compensation.

State x = [q_hat; v_hat; d_hat] (3n), measurement y = q, input u = tau, p = [omega],
estimate [v_hat (est names qd_hat_<joint>); tau_d_hat (tau_d_hat_<joint>)] (2n);
init from est0 = [v_hat(0); tau_d_hat(0)]: d_hat(0) = M(y0)^-1 tau_d_hat(0).
"""
from __future__ import annotations

import casadi as ca

from ..design import model_statistics, sensor_sigma, torque_statistics
from ..design.noise import (check_torque_uncertainty, check_uncertainty, extended_state_floor,
                            extended_state_gains, extended_state_noise_gain, torque_error_rms)
from ...core.options import InputRanges, VelocityBoundOptions
from ...core.spec import ObserverSpec, split_flow
from . import _bound
from ._design import design_discretization, stable_report

TUNE = {"omega": 1}       # the bandwidth a log tunes (codegen.logs.tune)
# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"}]


def design_omega(robot, dt, noise=None, quantization=None, uncertainty=0.0, v_max=2.0, t_conv=0.2,
                 torque_uncertainty=0.0):
    """(omega, report): the default pole of the error dynamics for ``robot`` at sample time
    ``dt`` (s), the sensor (``noise`` std, ``quantization`` step, rad; both None: the default
    encoder), the relative model ``uncertainty``, the ``torque_uncertainty`` (N m, a number or
    one per joint), the speed bound ``v_max`` (rad/s; the initial error of the floor, and twice
    the speed at which the model error's rate is estimated) and the convergence time ``t_conv`` (s).

    A constant model error leaves no bias; what remains is its rate, as the configuration moves.
    The relative error (~ uncertainty M^-1 g) changes at uncertainty * rms_q ||M^-1 dg/dq||_F *
    v / sqrt(n), the RMS of ||M^-1 dg/dq v|| over speeds v of norm v_max / 2 in random directions
    [ASSUMPTION: half the speed bound]; a torque error dtau (M^-1 dtau) at
    sqrt(sum_j t_j^2 (v^2 / n) mean_q sum_k |M^-1 dM/dq_k M^-1 e_j|^2) over the same speeds
    (codegen.families.design.noise); the two add in quadrature."""
    stats = model_statistics(robot)
    sigma, unc = sensor_sigma(noise, quantization), check_uncertainty(uncertainty)
    tau_unc = check_torque_uncertainty(torque_uncertainty, robot.n, robot.joint_names)
    v = v_max / 2
    e_dot_rel = unc * stats["minv_dg_rms"] * v / robot.n ** 0.5
    e_dot_tau = (v / robot.n ** 0.5 * torque_error_rms(tau_unc, torque_statistics(robot)["dminv_col_ms"])
                 if tau_unc.any() else 0.0)
    e_dot = (e_dot_rel ** 2 + e_dot_tau ** 2) ** 0.5
    floor = extended_state_floor(v_max, t_conv)
    omega, predicted, w_opt = extended_state_noise_gain(robot.n, dt, sigma, e_dot, floor)
    choice = "noise-aware optimum" if omega > floor else "convergence floor"
    return float(omega), {"omega": float(omega), "choice": choice, "omega_floor": float(floor),
                          "omega_noise": float(w_opt), "predicted_error": float(predicted),
                          "sigma": sigma, "uncertainty": unc, "e_dot": float(e_dot),
                          "torque_uncertainty": tau_unc.tolist() if tau_unc.any() else None,
                          "e_dot_torque": float(e_dot_tau), "dt": float(dt),
                          "t_conv": float(t_conv), "v_max": float(v_max)}


def build(robot, omega=None, v_max=2.0, noise=None, quantization=None, uncertainty=0.0, dt=None,
          t_conv=0.2, torque_uncertainty=0.0, v_bound=None):
    """Extended-state observer for ``robot``.

    Parameters
    ----------
    robot : RobotModel
    omega : float, optional
        The error poles -omega (1/s); given, it bypasses the design (not the stability check).
    v_max, noise, quantization, uncertainty, dt, t_conv, torque_uncertainty
        Design inputs (``design_omega``), as in ``reduced_order.build``.
    v_bound : float or sequence of n floats, optional
        Speed (rad/s) at which the model's velocity argument saturates (default twice the URDF
        velocity limit, else twice v_max; codegen.families.observers._bound).
    """
    report = None
    if omega is None:
        disc = design_discretization(dt)
        omega, report = design_omega(robot, disc.dt, noise, quantization, uncertainty, v_max, t_conv,
                                     torque_uncertainty)
    n = robot.n
    qh, vh, dh = ca.SX.sym("q_hat", n), ca.SX.sym("v_hat", n), ca.SX.sym("d_hat", n)
    y, y_cfg, tau, w = ca.SX.sym("y", n), ca.SX.sym("y_cfg", n), ca.SX.sym("tau", n), ca.SX.sym("omega")
    l1, l2, l3 = extended_state_gains(w)
    x = ca.vertcat(qh, vh, dh)
    e = y - qh
    bound = _bound.velocity_bound(robot, v_max, v_bound)
    # the model at y_cfg (y itself in continuous time; the midpoint under the first-order hold)
    # and at the saturated velocity estimate
    a_model = robot.forward_dynamics(y_cfg, _bound.saturate(vh, bound), tau)
    xdot = ca.vertcat(vh + l1 * e, a_model + dh + l2 * e, l3 * e)
    rhs, rhs_split = split_flow(x, y_cfg, y, tau, w, xdot)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", 2 * n)
    tau_d_hat = ca.mtimes(robot.mass_matrix(y), dh)                       # M(y) d_hat, N m
    d_hat0 = ca.solve(robot.mass_matrix(y0), est0[n:])                   # from tau_d_hat(0)
    joints = robot.joint_names
    spec = ObserverSpec(
        family="extended_state", robot=robot,
        x_names=[f"q_hat_{j}" for j in joints] + [f"qd_hat_{j}" for j in joints] + [f"d_hat_{j}" for j in joints],
        y_names=[f"q_{j}" for j in joints], u_names=[f"tau_{j}" for j in joints], p_names=["omega"],
        est_names=[f"qd_hat_{j}" for j in joints] + [f"tau_d_hat_{j}" for j in joints], p_default=[omega],
        rhs=rhs, rhs_split=rhs_split,
        output=ca.Function("output", [x, y, tau, w], [ca.vertcat(vh, tau_d_hat)]),
        init=ca.Function("init", [y0, est0, w], [ca.vertcat(y0, est0[:n], d_hat0)]),
        # q_hat' = [v_hat + l1 y] - l1 q_hat: the rate l1 = 3 omega on q_hat, integrated exactly
        rate=ca.Function("rate", [x, w], [l1]), rate_states=[f"q_hat_{j}" for j in joints],
        gains={"omega": ("omega",)},
        options=VelocityBoundOptions(v_bound=tuple(bound)),
        design={"omega": float(omega), **(report or {"given": True}),
                **_bound.report(robot, bound, v_max, v_bound is not None)},
        # cross-check inputs: positions within a few rad, speeds ~10 rad/s, disturbances ~10 rad/s^2
        inputs=InputRanges(x_scale=(3.0,) * n + (10.0,) * n + (10.0,) * n),
    )
    return spec if report is None else stable_report(spec, disc)
