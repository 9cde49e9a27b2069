"""Reduced-order velocity observer with a time-switched gain: fast, then quiet [DERIVED].

The fixed-gain observer of seed 000 (docs/papers/seed000.md §1.1) with the gain k0 until t_switch, then k0_final
(the hybrid-gain idea of seed 000 §IV with time as the switching signal). A constant gain must
choose between converging fast (k0 large) and passing little encoder noise (the estimate's noise
grows like k0 sigma); the design (codegen.families.design.noise.switched_gains) converges with the floor
gain and then runs at the noise-aware optimum:

    x2hat = z + k y,   z' = FD(y, sat(x2hat), tau) - k x2hat             [S000 (6),(9)]
    k     = k0 while s < t_switch + 1/2, else k0_final
    s'    = 1 while s < t_switch + 1/2, else 0                           (the clock)

Jump, applied at each sample: when t_switch <= s < t_switch + 1/2 (the clock has passed the
switch time and the switch has not happened), z+ = z + (k0 - k0_final) y (x2hat continuous,
as at a hybrid jump, docs/papers/seed000.md §1.3) and s+ = t_switch + 1 (marks the switch done).

Phases the stability check linearises at (``phases``): the clock where init puts it (s = 0, gain
k0) and the switch done (s = t_switch + 1, z moved by the jump: gain k0_final), so both gains
are checked, jointly. The clock counts in the target's precision: a t_switch it cannot reach
(s += dt rounded) is refused (``clocks``, codegen.discrete.stability).

sat: the velocity bound of codegen.families.observers._bound (the published observer inside it).
State x = [z (n); s], measurement y = q, input u = tau, parameters
p = [k0, k0_final (1/s), t_switch (s)], estimate x2hat. The error dynamics are those of the
fixed-gain observer with k0 then with k0_final: eps is continuous at the switch.
"""
from __future__ import annotations

import math

import casadi as ca

from ..design import reduced_order_design, switched_gains
from ...core.options import InputRanges, VelocityBoundOptions
from ...core.spec import ObserverSpec, split_model
from ._design import design_discretization, stable_report
from . import _bound, reduced_order
from .reduced_order import flow, model

TUNE = {"k0_final": 1}    # the steady gain a log tunes (codegen.logs.tune); k0 only starts it
# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"}]

P_NAMES = ["k0", "k0_final", "t_switch"]


def active_gain(s, p):
    """The gain in force at clock s: k0 before the switch is done, k0_final after (``p`` as the
    family's parameters, SX)."""
    return ca.if_else(s < p[2] + 0.5, p[0], p[1])


def build(robot, k0=None, k0_final=None, t_switch=None, eta=1.0, v_max=2.0, noise=None,
          quantization=None, uncertainty=0.0, dt=None, t_conv=0.18, t_settle=2.0, torque_uncertainty=0.0,
          v_bound=None):
    """Reduced-order observer with a time-switched gain for ``robot``.

    Parameters
    ----------
    robot : RobotModel
    k0, k0_final : float, optional
        Gains before and after the switch (1/s); given (with t_switch: all three or none), they
        bypass the design (not the stability check at compile time).
    t_switch : float, optional
        Time of the switch (s) after the first sample; given with the gains.
    eta, v_max, noise, quantization, uncertainty, dt, torque_uncertainty, v_bound
        As in ``reduced_order.build`` (the design of k0: codegen.families.design.noise); the
        torque uncertainty also raises k0_final to where its bias is no larger than the noise
        (k0_bias of codegen.families.design.noise.switched_gains).
    t_conv : float
        Time (s) to fall below 1e-2 rad/s from v_max at the gain k0. [ASSUMPTION] 0.18 s: 10 %
        inside the 0.2 s asked of the default, for the Coriolis coupling the linear prediction
        ignores (MuJoCo's panda took 0.214 s at ln(200)/0.2); k0 runs only until t_switch, so
        the margin costs no steady noise.
    t_settle : float
        Time (s) the final gain still takes to bring an error of v_max below 1e-2 rad/s (the
        floor of k0_final, codegen.families.design.noise.switched_gains).
    """
    given = [v is not None for v in (k0, k0_final, t_switch)]
    if any(given) and not all(given):
        raise ValueError("k0, k0_final, t_switch: give all three (or none: designed)")
    report = None
    if not any(given):
        disc = design_discretization(dt)
        nd = reduced_order_design(robot, disc.dt, noise, quantization, uncertainty, eta, v_max, t_conv,
                                  torque_uncertainty)
        report = {**switched_gains(nd, robot.n, t_settle), "k0_design": nd.as_dict()}
        k0, k0_final, t_switch = report["k0"], report["k0_final"], report["t_switch"]
    if not (isinstance(t_switch, (int, float)) and math.isfinite(t_switch) and t_switch >= 0):
        raise ValueError(f"t_switch must be a time >= 0 (s), got {t_switch!r}")
    if report is not None:
        # after the switch the observer is the fixed-gain one at k0_final: designed (and kept
        # stable) as that family; the spec's check then covers both phases (``phases``)
        final = stable_report(reduced_order.build(robot, k0=k0_final, v_max=v_max, v_bound=v_bound), disc)
        report["stability_after_switch"] = final.design["stability"]
        k0_final = float(final.p_default[0])
    bound = _bound.velocity_bound(robot, v_max, v_bound)
    spec = _spec(robot, [float(k0), float(k0_final), float(t_switch)], report, bound,
                 _bound.report(robot, bound, v_max, v_bound is not None))
    return spec if report is None else stable_report(spec, disc)


def _spec(robot, p_default, report, bound, bound_report):
    n = robot.n
    z, s, y, tau = ca.SX.sym("z", n), ca.SX.sym("s"), ca.SX.sym("y", n), ca.SX.sym("tau", n)
    y_cfg = ca.SX.sym("y_cfg", n)
    p, p_new = ca.SX.sym("p", 3), ca.SX.sym("p_new", 3)
    x = ca.vertcat(z, s)
    k = active_gain(s, p)
    m = ca.SX.sym("m", n)
    x2hat, zdot = flow(robot, z, y_cfg, y, tau, k, bound, m)      # [S000 (6),(9)] with the gain k
    running = s < p[2] + 0.5
    rhs, rhs_split, fd, rhs_model = split_model(x, y_cfg, y, tau, p, m, model(robot, z, y_cfg, y, tau, k, bound),
                                                ca.vertcat(zdot, ca.if_else(running, 1, 0)))
    switching = ca.logic_and(s >= p[2], running)
    z_plus = z + ca.if_else(switching, p[0] - p[1], 0) * y        # x2hat continuous at the switch
    s_plus = ca.if_else(switching, p[2] + 1, s)
    # a retune keeps x2hat and whether the switch is done; the clock keeps running otherwise
    s_new = ca.if_else(running, s, p_new[2] + 1)
    z_new = z + (k - active_gain(s_new, p_new)) * y
    # the phases of the clock: as given, and the switch done (the jump's z, s = t_switch + 1)
    phases = ca.Function("phases", [x, y, p], [ca.horzcat(x, ca.vertcat(z + (p[0] - p[1]) * y, p[2] + 1))])
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    joints = robot.joint_names
    t_hi = int(2 * p_default[2]) + 2
    return ObserverSpec(
        family="reduced_order_switched", robot=robot,
        x_names=[f"z_{j}" for j in joints] + ["s"], y_names=[f"q_{j}" for j in joints],
        u_names=[f"tau_{j}" for j in joints], p_names=list(P_NAMES),
        est_names=[f"qd_hat_{j}" for j in joints], p_default=list(p_default),
        rhs=rhs, rhs_split=rhs_split, model=fd, rhs_model=rhs_model,
        output=ca.Function("output", [x, y, tau, p], [x2hat]),
        init=ca.Function("init", [y0, est0, p], [ca.vertcat(est0 - p[0] * y0, 0)]),   # [CODE-KUKA]
        jump=ca.Function("jump", [x, y, p], [ca.vertcat(z_plus, s_plus)]),
        # the flow is [FD - k^2 y] - k z on z, k constant along a step (the switch is a jump)
        rate=ca.Function("rate", [x, p], [k]), rate_states=[f"z_{j}" for j in joints],
        retune=ca.Function("retune", [x, y, p, p_new], [ca.vertcat(z_new, s_new)]),
        gains={"k0": ("k0",), "k0_final": ("k0_final",)}, phases=phases, clocks={"s": "t_switch"},
        # whole seconds of the clock, before and after the switch (a run crosses it); the
        # stability check keeps it where init puts it (0: the gain k0) and moves it by ``phases``
        inputs=InputRanges(x_integer=(("s", 0, t_hi),)),
        options=VelocityBoundOptions(v_bound=tuple(bound)),
        design={**(report or {"k0": p_default[0], "k0_final": p_default[1], "t_switch": p_default[2],
                              "given": True}), **bound_report},
    )
