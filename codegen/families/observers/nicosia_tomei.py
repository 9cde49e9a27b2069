"""Full-order velocity observer of Nicosia & Tomei (1990), the comparison in seed 000 (docs/papers/seed000.md §2).

    x1tilde = y - x1hat
    x1hat'  = x2hat + K_D x1tilde                                    [CODE-KUKA SimObserver]
    x2hat'  = M(y)^{-1}[tau - C(y, x1hat') x1hat' - F x1hat' - g(y) + K_P x1tilde]
            = FD(y, x1hat', tau + K_P x1tilde)                        [DERIVED, docs/papers/seed000.md §2]

C is evaluated at x1hat', not at x2hat (A0-6: the proof needs x1hat'), saturated to the velocity
bound (FD(y, sat(x1hat'), ...), codegen.families.observers._bound; the published observer inside
it). K_D = k_D I, K_P = k_P I.
Default gains (``design``): "noise" -- (kd, kp) minimising the predicted error for the sensor
noise and model uncertainty with the slowest error mode decaying below 1e-2 rad/s within t_conv
(codegen.families.design.noise); "guarantee" -- k_D = k0 of (12) (the same gain condition [S000 Rem. 4])
and k_P = 500 [ASSUMPTION].
State x = [x1hat; x2hat], measurement y = q, input u = tau, p = [kd, kp], estimate x2hat.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..design import model_statistics, nicosia_tomei_noise_gains, reduced_order_gain, sensor_sigma
from ..design.noise import check_torque_uncertainty, check_uncertainty, convergence_floor
from ...core.options import InputRanges, VelocityBoundOptions
from ...core.spec import ObserverSpec, split_flow
from . import _bound
from ._design import check_design, design_discretization, stable_report

TUNE = {"kd": 1, "kp": 2}  # the bandwidth a log tunes (codegen.logs.tune): kd ~ s, kp ~ s^2
# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"}]

KP_DEFAULT = 500.0   # [ASSUMPTION docs/papers/seed000.md §2, A0-4], the "guarantee" design's k_P


def design_gains(robot, design, eta, v_max, noise, quantization, uncertainty, dt, t_conv,
                 torque_uncertainty=0.0):
    """(kd, kp, report) of the default design (module docstring) for ``robot``: ``design`` "noise"
    or "guarantee"; ``eta``, ``v_max`` (rad/s) of (12); sensor ``noise`` std and encoder
    ``quantization`` step (rad, or None); relative model ``uncertainty``; sample time ``dt`` (s);
    ``t_conv`` (s) to fall below 1e-2 rad/s from v_max; ``torque_uncertainty`` (N m, a number or
    one per joint): its bias kd / kp |dtau| enters the predicted error."""
    guarantee = reduced_order_gain(robot, eta=eta, v_max=v_max)
    if check_design(design) == "guarantee":
        return guarantee.k0, KP_DEFAULT, {"design": design, "reduced_order": guarantee.as_dict()}
    stats = model_statistics(robot)
    sigma, unc = sensor_sigma(noise, quantization), check_uncertainty(uncertainty)
    tau_unc = check_torque_uncertainty(torque_uncertainty, robot.n, robot.joint_names)
    tau_rms = float((tau_unc ** 2).sum() ** 0.5)
    rate = convergence_floor(v_max, t_conv)
    kd, kp, predicted = nicosia_tomei_noise_gains(dt, sigma, stats["g_rms"], unc, stats["trace_minv2"],
                                                  stats["mu_min"], rate, torque_rms=tau_rms)
    return kd, kp, {"design": design, "why": "minimises the predicted error (noise ~ kp^2/kd, model-error "
                    "bias ~ kd/kp) with the slowest error mode decaying at the convergence floor",
                    "predicted_error": predicted, "rate_floor": rate, "sigma": sigma, "uncertainty": unc,
                    "torque_uncertainty": tau_unc.tolist() if tau_unc.any() else None,
                    "predicted_bias": kd / kp * float(np.hypot(unc * stats["g_rms"], tau_rms)),
                    "t_conv": t_conv, "eta": eta, "dt": dt, "statistics": stats,
                    "guarantee": {"kd": guarantee.k0, "kp": KP_DEFAULT, "reduced_order": guarantee.as_dict()}}


def build(robot, kd=None, kp=None, eta=1.0, v_max=2.0, noise=None, quantization=None, uncertainty=0.0,
          design="noise", dt=None, t_conv=1.5, torque_uncertainty=0.0, v_bound=None):
    """Nicosia–Tomei observer for ``robot``; (kd, kp) designed unless both are given (a given
    one overrides its designed value). eta, v_max, noise, quantization, uncertainty, design, dt,
    torque_uncertainty, v_bound: as in ``reduced_order.build``; t_conv: the time (s) the slowest
    error mode takes to fall below 1e-2 rad/s from v_max. [ASSUMPTION] 1.5 s: kp grows like 1/t_conv^2, and the scalar
    gains leave the light links' modes (kp mu_max >> kd^2) lightly damped, so the encoder noise
    they pass grows fast; on MuJoCo's panda with a 1e-4 rad encoder t_conv = 1 s gives a noise
    peak of 1.6e-2 rad/s (never below 1e-2), 1.5 s stays below 1e-2 from 1.6 s on."""
    report = None
    if kd is None or kp is None:
        disc = design_discretization(dt)
        kd_d, kp_d, report = design_gains(robot, design, eta, v_max, noise, quantization, uncertainty,
                                          disc.dt, t_conv, torque_uncertainty)
        kd, kp = kd_d if kd is None else kd, kp_d if kp is None else kp
    n = robot.n
    x1hat, x2hat = ca.SX.sym("x1hat", n), ca.SX.sym("x2hat", n)
    y, y_cfg, tau = ca.SX.sym("y", n), ca.SX.sym("y_cfg", n), ca.SX.sym("tau", n)
    kd_s, kp_s = ca.SX.sym("kd"), ca.SX.sym("kp")
    x, p = ca.vertcat(x1hat, x2hat), ca.vertcat(kd_s, kp_s)
    x1tilde = y - x1hat
    x1hat_dot = x2hat + kd_s * x1tilde
    bound = _bound.velocity_bound(robot, v_max, v_bound)
    x2hat_dot = robot.forward_dynamics(y_cfg, _bound.saturate(x1hat_dot, bound), tau + kp_s * x1tilde)  # at y_cfg
    rhs, rhs_split = split_flow(x, y_cfg, y, tau, p, ca.vertcat(x1hat_dot, x2hat_dot))
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    joints = robot.joint_names
    spec = ObserverSpec(
        family="nicosia_tomei", robot=robot,
        x_names=[f"q_hat_{j}" for j in joints] + [f"qd_hat_{j}" for j in joints],
        y_names=[f"q_{j}" for j in joints], u_names=[f"tau_{j}" for j in joints],
        p_names=["kd", "kp"], est_names=[f"qd_hat_{j}" for j in joints], p_default=[kd, kp],
        rhs=rhs, rhs_split=rhs_split,
        output=ca.Function("output", [x, y, tau, p], [x2hat]),
        init=ca.Function("init", [y0, est0, p], [ca.vertcat(y0, est0)]),   # [CODE-KUKA] x1hat(0) = y(0)
        # x1hat' = [x2hat + kd y] - kd x1hat: the rate kd on x1hat, integrated exactly
        rate=ca.Function("rate", [x, p], [kd_s]), rate_states=[f"q_hat_{j}" for j in joints],
        gains={"kd": ("kd",), "kp": ("kp",)},
        options=VelocityBoundOptions(v_bound=tuple(bound)),
        design={"kd": float(kd), "kp": float(kp), **(report or {"given": True}),
                **_bound.report(robot, bound, v_max, v_bound is not None)},
        # cross-check inputs: positions within a few rad, speeds ~10 rad/s
        inputs=InputRanges(x_scale=(3.0,) * n + (10.0,) * n),
    )
    return spec if report is None else stable_report(spec, disc)
