"""Reduced-order velocity observer with hybrid (scheduled) gain, seed 000 (docs/papers/seed000.md §1.2–§1.3).

Flow (logic state r constant), as the fixed-gain family with k0 -> k_r   [S000 (6),(16)]:

    x2hat = z + k_r y,      z' = FD(y, sat(x2hat), tau) - k_r x2hat,      r' = 0

(sat: the velocity bound of codegen.families.observers._bound, the published flow inside it)

Jump map, applied before every step (the logic state lives in the observer state, so the
generated C does the switching)                                           [DERIVED, docs/papers/seed000.md §1.3, A0-3]:

    up   while ||x2hat|| >= r vbar - eta                     and r < r_max   (repeatable)
    down while ||x2hat|| <= (r-1) vbar - eta - delta         and r >= 2      (repeatable)
    z+   = z + (k_r - k_{r+}) y      i.e. x2hat continuous across the jump

State x = [z; r], measurement y = q, input u = tau, estimate x2hat,
parameters p = [k_1 .. k_{r_max}, eta, vbar, delta] (k_r designed by (16)). The stability check
linearises at every logic state (``phases``: the estimate in r's band), so every k_r is checked.
The literal sets (15)-(17) loop (Zeno) right after an up-jump; the rule above keeps the
safety property ||x2|| <= ||x2hat|| + eta <= r vbar while k_r is active (docs/papers/seed000.md §1.3).
"""
from __future__ import annotations

import casadi as ca

from ..design import reduced_order_design, scheduled_gains
from ...core.options import HybridOptions, InputRanges
from ...core.spec import ObserverSpec, split_flow
from . import _bound
from ._design import check_design, design_discretization, stable_report
from .reduced_order import flow

TUNE = lambda names: {k: 1 for k in names if k.startswith("k_")}  # the ladder of gains ~ s (codegen.logs.tune)  # noqa: E731
# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"}]


def gain_names(r_max):
    """Parameter names of the scheduled gains: k_1 .. k_{r_max}."""
    return [f"k_{r}" for r in range(1, r_max + 1)]


def logic_index(r, r_max):
    """r as an exact integer 1..r_max: 1 + #{i in 2..r_max : r >= i - 1/2} (clamps bad values);
    ``r`` SX, ``r_max`` the number of gains."""
    return 1 + sum(ca.if_else(r >= i - 0.5, 1, 0) for i in range(2, r_max + 1))


def scheduled_gain(r, k):
    """k_r selected exactly from the list k = [k_1 .. k_{r_max}] by the integer-valued r."""
    sel = k[0]
    for i in range(2, len(k) + 1):
        sel = ca.if_else(r >= i - 0.5, k[i - 1], sel)
    return sel


def switch(r, speed, eta, vbar, delta, r_max):
    """Logic state after the jumps of docs/papers/seed000.md §1.3 at estimated speed ||x2hat|| = ``speed``, from ``r``
    (1..r_max), with ``eta``, ``vbar`` and the down-jump tolerance ``delta`` (rad/s).

    Each test is unrolled r_max - 1 times ("repeat the test"); after the up-jumps the
    down-test cannot fire (speed >= (r-1) vbar - eta there), so the order is immaterial."""
    for _ in range(r_max - 1):                                        # up: r+ = r + 1 on D_r^+
        r = r + ca.if_else(ca.logic_and(speed >= r * vbar - eta, r < r_max), 1, 0)
    for _ in range(r_max - 1):                                        # down, tolerance delta
        r = r - ca.if_else(ca.logic_and(speed <= (r - 1) * vbar - eta - delta, r >= 2), 1, 0)
    return r


def _phases(x2hat, y, k, eta, vbar, delta, x):
    """The state x as given, then at each logic state r = 1..r_max with the estimate moved to the
    middle of r's band, where no jump leaves r: speed (r - 1/2) vbar - eta - delta/2 (>= 0),
    between the down-test's (r-1) vbar - eta - delta and the up-test's r vbar - eta, along
    x2hat (or (1, .., 1) at rest); z = x2hat_r - k_r y. The stability check linearises at each,
    so every scheduled gain k_r is checked (columns: nx = n + 1 rows, r_max + 1 of them)."""
    n = x2hat.numel()
    norm = ca.norm_2(x2hat)
    direction = ca.if_else(norm > 0, x2hat / ca.fmax(norm, 1e-300), ca.DM.ones(n) / n ** 0.5)
    cols = [x]
    for r in range(1, k.numel() + 1):
        speed = ca.fmax(0, (r - 0.5) * vbar - eta - 0.5 * delta)
        cols.append(ca.vertcat(speed * direction - k[r - 1] * y, r))
    return ca.horzcat(*cols)


def build(robot, eta=1.0, vbar=2.0, r_max=6, delta=0.1, gains=None, noise=None, quantization=None,
          uncertainty=0.0, design="noise", dt=None, t_conv=0.2, torque_uncertainty=0.0, v_bound=None):
    """Hybrid reduced-order observer for ``robot``.

    Parameters
    ----------
    eta, vbar : float
        (16) design constants (rad/s): k_r covers speeds up to r vbar with error margin eta.
    r_max : int
        Number of scheduled gains (the logic state is kept in [1, r_max]).
    delta : float
        Down-jump tolerance layer (rad/s) [ASSUMPTION docs/papers/seed000.md §1.3: 0.1].
    gains : sequence of r_max floats, optional
        k_1 .. k_{r_max}; given, they bypass the design (not the stability check).
    noise, quantization, uncertainty, dt, t_conv, torque_uncertainty
        As in ``reduced_order.build``.
    v_bound : float or sequence of n floats, optional
        Speed (rad/s) at which the model's velocity argument saturates; default twice the URDF
        velocity limit, else twice r_max vbar, the top of the schedule
        (codegen.families.observers._bound).
    design : {"noise", "guarantee"}
        "guarantee": the (16) table; "noise" (default): k_1 is the noise-aware reduced-order gain
        (with v_max = vbar) and the increments k_r - k_1 of (16) are kept.
    """
    if int(r_max) != r_max or r_max < 1:
        raise ValueError(f"r_max must be a positive integer, got {r_max!r}")
    r_max = int(r_max)
    report = {}
    if gains is None:
        disc = design_discretization(dt)
        table = scheduled_gains(robot, eta=eta, vbar=vbar, r_max=r_max)
        gains = table
        report = {"k_r (16)": table.tolist(), "design": check_design(design)}
        if design == "noise":
            nd = reduced_order_design(robot, disc.dt, noise, quantization, uncertainty, eta, vbar, t_conv,
                                      torque_uncertainty)
            gains = nd.k0 + (table - table[0])         # the (16) increments on the noise-aware k_1
            report["k_1"] = nd.as_dict()
    gains = [float(g) for g in gains]
    if len(gains) != r_max:
        raise ValueError(f"gains: expected {r_max} values k_1..k_{r_max}, got {len(gains)}")
    n = robot.n
    z, r = ca.SX.sym("z", n), ca.SX.sym("r")
    y, y_cfg, tau = ca.SX.sym("y", n), ca.SX.sym("y_cfg", n), ca.SX.sym("tau", n)
    k = ca.SX.sym("k", r_max)
    eta_s, vbar_s, delta_s = ca.SX.sym("eta"), ca.SX.sym("vbar"), ca.SX.sym("delta")
    p = ca.vertcat(k, eta_s, vbar_s, delta_s)
    x = ca.vertcat(z, r)

    k_r = scheduled_gain(r, ca.vertsplit(k))
    bound = _bound.velocity_bound(robot, r_max * vbar, v_bound)
    x2hat, zdot = flow(robot, z, y_cfg, y, tau, k_r, bound)           # [S000 (6)] with k_r of (16)
    rhs, rhs_split = split_flow(x, y_cfg, y, tau, p, ca.vertcat(zdot, 0))
    r_plus = switch(logic_index(r, r_max), ca.norm_2(x2hat), eta_s, vbar_s, delta_s, r_max)
    z_plus = z + (k_r - scheduled_gain(r_plus, ca.vertsplit(k))) * y  # [DERIVED] x2hat continuous
    p_new = ca.SX.sym("p_new", p.numel())
    z_retuned = z + (k_r - scheduled_gain(r, ca.vertsplit(p_new[:r_max]))) * y   # likewise at a retune

    phases = ca.Function("phases", [x, y, p], [_phases(x2hat, y, k, eta_s, vbar_s, delta_s, x)])

    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    joints = robot.joint_names
    spec = ObserverSpec(
        family="reduced_order_hybrid", robot=robot,
        x_names=[f"z_{j}" for j in joints] + ["r"], y_names=[f"q_{j}" for j in joints],
        u_names=[f"tau_{j}" for j in joints], p_names=gain_names(r_max) + ["eta", "vbar", "delta"],
        est_names=[f"qd_hat_{j}" for j in joints], p_default=gains + [eta, vbar, delta],
        rhs=rhs, rhs_split=rhs_split,
        output=ca.Function("output", [x, y, tau, p], [x2hat]),
        # [S000 §V] r(0) = 1; [CODE-KUKA] z(0) = x2hat(0) - k_1 y(0); the first jump raises r if needed
        init=ca.Function("init", [y0, est0, p], [ca.vertcat(est0 - k[0] * y0, 1)]),
        jump=ca.Function("jump", [x, y, p], [ca.vertcat(z_plus, r_plus)]),
        # the flow is [FD - k_r^2 y] - k_r z on z (r' = 0: k_r constant along it)
        rate=ca.Function("rate", [x, p], [k_r]), rate_states=[f"z_{j}" for j in joints],
        retune=ca.Function("retune", [x, y, p, p_new], [ca.vertcat(z_retuned, r)]),
        gains={"k_r": tuple(gain_names(r_max))}, phases=phases,
        options=HybridOptions(r_max=r_max, v_bound=tuple(bound)),
        inputs=InputRanges(x_integer=(("r", 1, r_max),)),
        design={"eta": float(eta), "vbar": float(vbar), "r_max": r_max, "delta": float(delta),
                "k_r": gains, **report, **_bound.report(robot, bound, r_max * vbar, v_bound is not None)},
    )
    return stable_report(spec, disc) if report else spec
