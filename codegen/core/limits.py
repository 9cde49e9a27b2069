"""The declared ranges of an observer's inputs: what a sample may hold before the generated C
refuses it (status ERR_OUT_OF_RANGE, the state unchanged) or, in its skip mode, predicts through it
(docs/guide/reliability.md), and what a log's reader refuses naming row and column
(codegen.logs.recording).

Per joint j, from the robot's declared limits (models/robot.py ``position_limited``,
``effort_limit``; a URDF's ``<limit lower upper effort>``):

    q_j in [lower_j - POSITION_MARGIN r_j, upper_j + POSITION_MARGIN r_j],  r_j = upper_j - lower_j
    |tau_j| <= TORQUE_MARGIN effort_j

POSITION_MARGIN = 0.1 [ASSUMPTION]: a real reading passes a joint's limit only by its calibration
offset and the overshoot past a soft limit, a few degrees; a tenth of the range (36 deg on a +-pi
joint, 4 mm on a 40 mm finger) keeps every such reading and refuses a wild one (1e200, a unit
mix-up of a factor 1000 on a revolute joint, degrees for radians beyond 1.1 x the range).
TORQUE_MARGIN = 10 [ASSUMPTION]: the URDF's effort is the drive's rated (continuous) torque; its
peak torque is 2 to 4 times that, a torque sensor's spikes and a model's offset add to it, so ten
times the rating still passes every torque a drive can apply and refuses 1e300 N m.
A joint without a declared limit (a continuous joint, a closed-form or DH robot) still gets an
absolute range, UNDECLARED_POSITION = 1e4 (rad or m) either side of 0, and one without an effort
limit |tau| <= UNDECLARED_TORQUE = 1e6 N m [ASSUMPTION]: 1e4 rad is 1,600 turns of a continuous
joint (hours at a wrist's top speed, more than any arm's cable allows), 1e4 m longer than any
slide, 1e6 N m above the largest industrial axis (a few 1e4 N m); a reading beyond them is no
motion but a wild sample (1e200, an overflowed counter), which would ruin every later estimate. The user may declare other ranges
(``observers.build(..., limits=...)``, a targets file's ``design = { limits = {...} }``): taken as
given, without a margin.

Slots are matched by name: a measurement ``q_<joint>`` (``q1_<joint>``: an elastic joint's link
position) gets the joint's position range, an input ``tau_<joint>`` (``u_<joint>``: its motor
torque) its torque bound; any other slot (a measured force, a clock) none.
"""
from __future__ import annotations

import numpy as np

POSITION_MARGIN = 0.1
TORQUE_MARGIN = 10.0
UNDECLARED_POSITION = 1e4
UNDECLARED_TORQUE = 1e6
POSITION_PREFIXES = ("q_", "q1_")
TORQUE_PREFIXES = ("tau_", "u_")
KEYS = ("q_lower", "q_upper", "tau_max")


def joint_ranges(robot):
    """(lower (n,), upper (n,), tau_max (n,)): the accepted range of each joint's position (rad or
    m; +-UNDECLARED_POSITION where none is declared) and the bound of its torque (N m or N;
    UNDECLARED_TORQUE where none is), with the margins of the module docstring, from the declared limits of ``robot`` (its
    ``position_limited``, ``q_lower``, ``q_upper`` and ``effort_limit``)."""
    n = robot.n
    limited = np.asarray(getattr(robot, "position_limited", np.zeros(n, bool)), dtype=bool).reshape(-1)
    lo = np.asarray(getattr(robot, "q_lower", np.full(n, -np.inf)), dtype=float).reshape(-1)
    hi = np.asarray(getattr(robot, "q_upper", np.full(n, np.inf)), dtype=float).reshape(-1)
    effort = np.asarray(getattr(robot, "effort_limit", np.full(n, np.inf)), dtype=float).reshape(-1)
    if limited.size != n:
        limited = np.zeros(n, bool)
    if effort.size != n:
        effort = np.full(n, np.inf)
    margin = POSITION_MARGIN * (hi - lo)
    lower = np.where(limited, lo - margin, -UNDECLARED_POSITION)
    upper = np.where(limited, hi + margin, UNDECLARED_POSITION)
    tau = np.where(np.isfinite(effort) & (effort > 0), TORQUE_MARGIN * effort, UNDECLARED_TORQUE)
    return lower, upper, tau


def _given(name, value, n, default):
    """The (n,) values of a given range entry ``value`` (a number or n of them; None: ``default``),
    or ValueError naming ``limits[name]``."""
    if value is None:
        return default
    a = np.asarray(value, dtype=float).reshape(-1) if not isinstance(value, (str, bytes, dict)) else None
    if a is not None and a.size == 1:
        a = np.full(n, float(a[0]))
    if a is None or a.size != n or np.any(np.isnan(a)):
        raise ValueError(f"limits[{name!r}]: expected a number or {n} numbers (one per joint), got {value!r}")
    return a


def check_given(limits, n):
    """``limits`` (None, "none" or a dict of ``KEYS``) as given to ``observers.build``, checked for n
    joints: ValueError naming the entry and what was expected."""
    if limits is None or limits == "none":
        return limits
    if not isinstance(limits, dict):
        raise ValueError(f"limits: expected 'none' or a table of {', '.join(KEYS)}, got {limits!r}")
    unknown = sorted(set(limits) - set(KEYS))
    if unknown:
        raise ValueError(f"limits: unknown key(s) {', '.join(unknown)}; valid: {', '.join(KEYS)}")
    lo = _given("q_lower", limits.get("q_lower"), n, np.full(n, -np.inf))
    hi = _given("q_upper", limits.get("q_upper"), n, np.full(n, np.inf))
    tau = _given("tau_max", limits.get("tau_max"), n, np.full(n, np.inf))
    if np.any(lo >= hi):
        j = int(np.argmax(lo >= hi))
        raise ValueError(f"limits: q_lower[{j}] = {lo[j]:g} is not below q_upper[{j}] = {hi[j]:g}")
    if np.any(tau <= 0):
        raise ValueError(f"limits['tau_max']: expected positive bounds, got {tau.tolist()}")
    return limits


def input_ranges(robot, y_names, u_names, given=None):
    """The declared ranges of the measurement and input slots (plain data, the metadata's "limits").

    Parameters
    ----------
    robot : models.RobotModel or ElasticRobot
        Its ``joint_names`` and declared limits (``joint_ranges``).
    y_names, u_names : sequence of str
        The slots (matched by name: module docstring).
    given : None, "none" or dict, optional
        None: the robot's limits with the margins; "none": no range; a dict with any of
        ``q_lower``, ``q_upper``, ``tau_max`` (a number or one per joint, as given; the others
        the robot's).

    Returns
    -------
    dict
        ``y_lower``, ``y_upper`` (ny,) and ``u_max`` (nu,): numbers, None where the slot is not
        checked; ``rule``: where they come from (one line).
    """
    n, joints = robot.n, list(robot.joint_names)
    if given == "none":
        lower, upper, tau = np.full(n, -np.inf), np.full(n, np.inf), np.full(n, np.inf)
        rule = "none declared (limits = 'none')"
    else:
        lower, upper, tau = joint_ranges(robot)
        rule = (f"the robot's declared limits: positions {POSITION_MARGIN:g} x the range beyond either end, "
                f"|torque| <= {TORQUE_MARGIN:g} x the effort limit; joints without one: |q| <= "
                f"{UNDECLARED_POSITION:g}, |torque| <= {UNDECLARED_TORQUE:g}")
        if given:
            check_given(given, n)
            lower = _given("q_lower", given.get("q_lower"), n, lower)
            upper = _given("q_upper", given.get("q_upper"), n, upper)
            tau = _given("tau_max", given.get("tau_max"), n, tau)
            rule = f"given ({', '.join(k for k in KEYS if k in given)}), else " + rule

    def of(names, prefixes, values):
        out = []
        for name in names:
            j = next((joints.index(name[len(p):]) for p in prefixes
                      if name.startswith(p) and name[len(p):] in joints), None)
            v = None if j is None else float(values[j])
            out.append(v if v is not None and np.isfinite(v) else None)
        return out
    return {"y_lower": of(y_names, POSITION_PREFIXES, lower), "y_upper": of(y_names, POSITION_PREFIXES, upper),
            "u_max": of(u_names, TORQUE_PREFIXES, tau), "rule": rule}


def out_of_range(limits, y=None, u=None):
    """The first slot of ``y`` (ny,) or ``u`` (nu,) outside the declared ``limits`` (dict of
    ``input_ranges``): (kind "y" or "u", index, value, (low, high)), or None when all are inside.
    A NaN is outside."""
    if not limits:
        return None
    for kind, v, lo, hi in (("y", y, limits.get("y_lower"), limits.get("y_upper")),
                            ("u", u, None, limits.get("u_max"))):
        if v is None:
            continue
        v = np.asarray(v, dtype=float).reshape(-1)
        for i, x in enumerate(v):
            low = -np.inf if lo is None or lo[i] is None else lo[i]
            high = np.inf if hi is None or hi[i] is None else hi[i]
            if kind == "u" and hi is not None and hi[i] is not None:
                low = -high
            if not (low <= x <= high):
                return kind, i, float(x), (low, high)
    return None
