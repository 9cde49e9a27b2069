"""Generalized-momentum observer for the external torque, with collision detection and isolation
(De Luca & Mattone, ICRA 2005; Haddadin, De Luca & Albu-Schaeffer, IEEE T-RO 33(6) 2017, §IV),
fed by the reduced-order velocity observer of seed 000 inside the same step (seed 000 §VII).

The momentum p = M(q) qd obeys p' = tau + tau_ext + C(q, qd)^T qd - g(q) - tau_f(qd)
(Mdot = C + C^T). Its observer integrates what the model explains and feeds the residual back:

    r     = K_O (M(q) v - p_hat)                                   (the residual, ~ tau_ext)
    p_hat' = tau + C(q, v)^T v - g(q) - tau_f(v) + r,    p_hat(0) = M(q0) v(0)

i.e. r = K_O (M v - int (tau + C^T v - g - tau_f + r) dt - p(0)): r' = K_O (tau_ext - r), a
first-order filter of the external torque with per-joint bandwidths K_O = diag(K_O_<j>).
The velocity v is the reduced-order observer's estimate (codegen.families.observers.reduced_order)
with the estimated external torque added to its model's torque, so that a contact biases it no
more than the model's own error does

    x2hat = z + k0 q,   z' = FD(q, sat(x2hat), tau + r) - k0 x2hat,    v = sat(x2hat)

sat the velocity bound. Together r = K_O k0 / (s^2 + k0 s + K_O k0) tau_ext per joint (a linear
picture; codegen.families.design.momentum). The residual passes x2hat's encoder noise at gain K_O k0 M(q) with no roll-off; the output is
the residual through one more lag, well above the residual's own bandwidth,

    r_f' = omega_f (r - r_f),   r_f(0) = 0             (tau_ext_<j> = r_f_j, N m)

Detection and isolation at each sample (Haddadin et al. §IV-B, §V):

    alarm_j = |r_f_j| > th0_j + th1_j |x2hat_j|      (a constant and a term for the model's
                                                      error growing with speed)
    link    = max { j : alarm_j } (1-based; 0: none) the last joint above its threshold: a
              contact on link i acts on joints 1..i only

State x = [z; p_hat; r_f] (3n), y = q, u = tau (measured), p = [k0, K_O_<j>, th0_<j>, th1_<j>,
omega_f], estimate [qd_hat_<j> (rad/s); tau_ext_<j> = r_f (N m); alarm_<j> (0/1); link].
"""
from __future__ import annotations

import casadi as ca

from ..design.momentum import FALSE_ALARMS, T_DETECT, design_momentum
from ...core.options import InputRanges, VelocityBoundOptions
from ...core.spec import ObserverSpec, split_model
from . import _bound, reduced_order
from ._design import design_discretization, stable_report

TUNE = {"k0": 1}          # the velocity observer's bandwidth a log tunes (codegen.logs.tune)
# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"}]


def p_names(joints):
    """The parameter names: k0, then K_O_<j>, th0_<j>, th1_<j> per joint of ``joints`` (names),
    then omega_f."""
    return ["k0"] + [f"{g}_{j}" for g in ("K_O", "th0", "th1") for j in joints] + ["omega_f"]


def momentum_model(robot, y_cfg, v, tau, K):
    """tau + C(q, v)^T v - g(q) - tau_f(v) + K_O M(q) v of ``robot`` at q = ``y_cfg``: the model's
    part of p_hat' (the flow is it minus K_O p_hat); v, tau (n,) SX, K (n,) SX the gains."""
    C = robot.coriolis(y_cfg, v)
    return (tau + ca.mtimes(C.T, v) - robot.gravity(y_cfg) - robot.friction_torque(v)
            + K * ca.mtimes(robot.mass_matrix(y_cfg), v))


def detection(r, x2hat, th0, th1):
    """(alarms (n,), link) of the residual r: alarm_j = |r_j| > th0_j + th1_j |x2hat_j| (SX: ``x2hat``
    the velocity estimate, ``th0``, ``th1`` the thresholds), link the last joint (1-based) in
    alarm, 0 for none."""
    n = r.shape[0]
    alarm = ca.vertcat(*[ca.if_else(ca.fabs(r[j]) > th0[j] + th1[j] * ca.fabs(x2hat[j]), 1.0, 0.0)
                         for j in range(n)])
    link = ca.SX(0.0)
    for j in range(n):                                      # the last one set wins
        link = ca.if_else(alarm[j] > 0.5, float(j + 1), link)
    return alarm, link


def build(robot, k0=None, K_O=None, th0=None, th1=None, omega_f=None, torque_noise=None, t_detect=T_DETECT,
          false_alarms=FALSE_ALARMS, noise=None, quantization=None, v_max=2.0, v_bound=None, dt=None):
    """Momentum observer for ``robot`` (module docstring).

    Parameters
    ----------
    robot : RobotModel
    k0 : float, optional
        The velocity observer's gain (1/s); default the design's omega.
    K_O : float or (n,) floats, optional
        The residual's bandwidths (1/s); default the design's omega on every joint.
    th0, th1 : float or (n,) floats, optional
        Thresholds: th0_j (N m) + th1_j (N m s/rad) |qd_hat_j|; default the design's
        (codegen.families.design.momentum; a log sets them: codegen.logs.detect).
    omega_f : float, optional
        The output lag's bandwidth (1/s); default the design's.
    torque_noise : float or (n,) floats, optional
        Std of the measured torque per sample (N m), for the default thresholds.
    t_detect : float
        Time (s) in which a contact three times the threshold is to be detected (default gains).
    false_alarms : float
        False alarms per hour the default thresholds allow.
    noise, quantization : float, optional
        The encoder's noise std and step (rad) for the default thresholds; both None: a 2^16
        counts/rev encoder.
    v_max, v_bound
        The velocity bound of the model's velocity argument (codegen.families.observers._bound).
    dt : float, optional
        Sample time of the design and its stability check (s).
    """
    n = robot.n
    disc = design_discretization(dt)
    report = design_momentum(robot, disc.dt, torque_noise, t_detect, false_alarms, noise=noise,
                             quantization=quantization)
    given = {"k0": k0 is not None, "K_O": K_O is not None, "th0": th0 is not None, "th1": th1 is not None}
    k0 = report["k0"] if k0 is None else float(k0)
    values = {}
    for name, v in (("K_O", K_O), ("th0", th0), ("th1", th1)):
        v = report[name] if v is None else v
        v = [float(v)] * n if isinstance(v, (int, float)) else [float(a) for a in v]
        if len(v) != n or any(a < 0 for a in v) or (name == "K_O" and any(a <= 0 for a in v)):
            raise ValueError(f"{name}: expected {'a positive' if name == 'K_O' else 'a non-negative'} number "
                             f"or {n} of them (one per joint), got {v}")
        values[name] = v
    omega_f = report["omega_f"] if omega_f is None else float(omega_f)
    for name, v in (("k0", k0), ("omega_f", omega_f)):
        if v <= 0:
            raise ValueError(f"{name}: expected a positive gain (1/s), got {v}")
    values["omega_f"] = omega_f
    bound = _bound.velocity_bound(robot, v_max, v_bound)
    spec = _spec(robot, k0, values, bound,
                 {**report, "given": [k for k, g in given.items() if g],
                  **_bound.report(robot, bound, v_max, v_bound is not None)})
    return stable_report(spec, disc) if not (given["k0"] and given["K_O"]) else spec


def _spec(robot, k0, values, bound, report):
    n, joints = robot.n, robot.joint_names
    z, ph, rf = ca.SX.sym("z", n), ca.SX.sym("p_hat", n), ca.SX.sym("r_f", n)
    y, y_cfg, tau = ca.SX.sym("y", n), ca.SX.sym("y_cfg", n), ca.SX.sym("tau", n)
    k, K, th0, th1 = ca.SX.sym("k0"), ca.SX.sym("K_O", n), ca.SX.sym("th0", n), ca.SX.sym("th1", n)
    wf = ca.SX.sym("omega_f")
    p = ca.vertcat(k, K, th0, th1, wf)
    x = ca.vertcat(z, ph, rf)
    m = ca.SX.sym("m", 3 * n)
    x2hat = z + k * y                                                   # [S000 (9)]
    v_cfg = _bound.saturate(x2hat, bound)
    r_cfg = K * (ca.mtimes(robot.mass_matrix(y_cfg), v_cfg) - ph)       # the residual at y_cfg
    model = ca.vertcat(reduced_order.model(robot, z, y_cfg, y, tau + r_cfg, k, bound),
                       momentum_model(robot, y_cfg, v_cfg, tau, K), wf * r_cfg)
    xdot = ca.vertcat(m[:n] - k * x2hat, m[n:2 * n] - K * ph, m[2 * n:] - wf * rf)
    rhs, rhs_split, fd, rhs_model = split_model(x, y_cfg, y, tau, p, m, model, xdot)
    alarm, link = detection(rf, x2hat, th0, th1)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", 3 * n + 1)
    z0 = est0[:n] - k * y0                                              # x2hat(0) = est0's velocity
    p0 = ca.mtimes(robot.mass_matrix(y0), _bound.saturate(est0[:n], bound))   # r(0) = 0
    k_new = ca.SX.sym("k0_new")
    p_new = ca.vertcat(k_new, ca.SX.sym("K_O_new", n), ca.SX.sym("th0_new", n), ca.SX.sym("th1_new", n),
                       ca.SX.sym("omega_f_new"))
    return ObserverSpec(
        family="momentum", robot=robot,
        x_names=[f"z_{j}" for j in joints] + [f"p_hat_{j}" for j in joints] + [f"r_f_{j}" for j in joints],
        y_names=[f"q_{j}" for j in joints], u_names=[f"tau_{j}" for j in joints], p_names=p_names(joints),
        est_names=([f"qd_hat_{j}" for j in joints] + [f"tau_ext_{j}" for j in joints]
                   + [f"alarm_{j}" for j in joints] + ["link"]),
        p_default=[k0] + values["K_O"] + values["th0"] + values["th1"] + [values["omega_f"]],
        rhs=rhs, rhs_split=rhs_split, model=fd, rhs_model=rhs_model,
        output=ca.Function("output", [x, y, tau, p], [ca.vertcat(x2hat, rf, alarm, link)]),
        init=ca.Function("init", [y0, est0, p], [ca.vertcat(z0, p0, ca.SX.zeros(n))]),
        # z' = [FD - k0^2 y] - k0 z: the velocity observer's rate k0 on z, integrated exactly
        rate=ca.Function("rate", [x, p], [k]), rate_states=[f"z_{j}" for j in joints],
        # x2hat continuous at a change of k0 (reduced_order); p_hat, r_f kept (r scales with K_O)
        retune=ca.Function("retune", [x, y, p, p_new], [ca.vertcat(z + (k - k_new) * y, ph, rf)]),
        gains={"k0": ("k0",), "K_O": tuple(f"K_O_{j}" for j in joints), "omega_f": ("omega_f",)},
        options=VelocityBoundOptions(v_bound=tuple(bound)),
        design=report,
        # cross-check inputs: z near its start, momenta ~1 N m s about M v(0), r_f ~10 N m
        inputs=InputRanges(x_scale=(0.1,) * n + (1.0,) * n + (10.0,) * n),
    )
