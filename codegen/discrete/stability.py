"""Discrete-time stability and accuracy of a discretised observer (docs/architecture.md §4).

The step x_k+1 = Phi(x_k; y, u, p) of ``codegen.discrete.discretize`` is linearised in x (CasADi
Jacobian of the step with dt as an input; the robot's F, M, C enter through the flow) at working
points: sampled configurations y (``spec.inputs``), each at rest (estimate 0) and moving
(velocity-sized estimate), x = init(y, est, p) (elastic robots: sampled plant states as estimates). At each point i

    rho_i   = spectral radius of dPhi/dx                      (the discrete observer)
    rho_c,i = rho(expm(dt (J(x_i) + J(x_i+)) / 2)),  J = d rhs/dx   (the exact linearised flow
              over the step, to O(dt^3): J at both ends, so a moving point compares like with like)

The working points are taken at every phase a spec declares (``spec.phases``: a switched gain
after its switch, each logic state of a hybrid), so every gain the observer can switch to is
linearised, all of them jointly at the parameters p.

The discretisation is *stable* when rho_i <= max(1, rho_c,i) (1 + 1e-6) at every point (it adds
no growth the continuous-time observer does not have; a step that is not finite there, an
overflow or a NaN, is unstable), every declared gain (``spec.gains``) is >= 0 (a negative
output-injection gain makes the continuous observer itself unstable), the precision carries the
gains, and every clock reaches its time (below).

Precision (``precision`` "double" or "float", unit roundoff u = 2^-53 or 2^-24): the C stores the
state to within u |x_k|; the estimate's error from it is u e, e = max_i max_j sum_k
|d est_j/d x_k| |x_k| at the working points (reduced_order: z = x2hat - k0 y, so e ~ k0 |y|).
It must keep at least half the estimate's significand: u e <= sqrt(u) m, m the estimate's size
there (max |est|). k0 = 1e17 on seed000_2r: u e = 35 rad/s, refused; the bound is k0 <= 4.2e7
in double, 1.8e3 in float. Clocks (``spec.clocks``: a state s' = 1 counting up to a time
parameter): each step adds the elapsed time h >= dt_min rounded, so the time t is reached within
one sample when (t / dt_min) ulp(t) / 2 <= dt (``clock_limit``: 2.1 s in float at dt = 1 ms).

The step takes the elapsed time as an input, so this must hold at every sample time of the
declared range [dt_min, dt_max] (``Discretization.dt_range``): it is checked on ``sample_times``,
dt_min, dt, dt_max and the geometric midpoints dt_min-dt and dt-dt_max. A range where it fails is
refused naming the fix (more substeps, or a smaller dt_max: a longer interval is integrated in
sub-intervals of at most dt_max by the C, so any dt_max >= dt that is stable is a fix). Where is
the worst point: an explicit step's amplification R(lambda h) leaves the stability region as h
grows, so dt_max decides for the gain terms (RK4 on z' = -k0 z: k0 dt_max <= 2.785); the grid
also covers a non-monotone case, and the accuracy figure below is taken at dt.
Reported with it: the largest value of each gain stable over the whole range and within the
precision (bisection, the other parameters fixed), the largest stable sample time and the substeps that would make the
range stable, and the accuracy of the step at dt, max_i ||dPhi/dx - expm(dt (J(x_i) + J(x_i+)) / 2)||_2.

The search for a gain's largest stable value (``_max_stable``): stable at 0 (every point and sample
time), then x4 from its value until unstable, then ``BISECTIONS`` halvings of the bracket. The growth
and the halvings test a probe: the sample times and working points that have failed in this search
(at first the sample time that failed last, at every point); the value found is confirmed at every
point and sample time, and when that fails, its halving is taken the other way and the probe has
learnt the point (``_bisect``: the same bracket as the full check at every halving when their
verdicts agree). A verdict tries the point and sample time that failed last first, and stops at the
first that fails (an unstable value usually costs one point's linearisation); the radii at p
themselves are not computed twice. The linearisation (the step's SX Jacobian, ``linearisation``)
is kept for the last few specs in the process (``tune`` and ``compare`` check many parameter
vectors of one spec), and ``require_stable(..., bounds=False)`` (``obs.params = p``) gives the
verdict without the search. kalman_model on ur5 (the targets file's): 304 point-evaluations of the
Jacobian (16 points at 1-5 sample times), 992 before the probe (the same report).

    report = check(spec, disc)               # StabilityReport; cached on disk
    require_stable(spec, disc)               # the report, or UnstableDiscretization (a ValueError)
    auto_substeps(spec, disc)                # the smallest stable substeps (and, by default, dt_max)

When unstable, the report also names the stiff mode (the flow Jacobian's eigenvalue of largest
modulus at the worst working point), the joint it lives on and its cause (joint damping on a small
inertia, or the small inertia alone: an unlocked gripper, a light wrist), and the refusal gives the
fix in the words of where the user is: Python arguments (``substeps="auto"``, ``dt=``,
``locked_joints=``) or command-line flags (``--substeps auto``, ``--dt``, ``--lock``).
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, field

import casadi as ca
import numpy as np
from scipy.linalg import expm

from ..core.cache import cached_json
from ..core.target import AUTO, DT_MAX_FACTOR, SUBSTEPS_MAX
from .sampling import declared_slots, measurements
from .discretize import step_jacobians

VERSION = 7            # of this check (part of the cache key)
POINTS = 8             # sampled configurations; each at rest and moving
TOL = 1e-6             # relative slack on the spectral radius
GROWTH = 4.0 ** 10     # a gain is searched up to this multiple of its value (x4 at a time)
BISECTIONS = 16        # relative precision 2^-16 of the bracket
SHRINK = 600           # an unstable gain or sample time is searched down to 4^-600 of its value
UNIT_ROUNDOFF = {"double": 2.0 ** -53, "float": 2.0 ** -24}    # u of each precision
SIGNIFICAND = {"double": 53, "float": 24}                       # its significand bits
REAL_MAX = {"double": float(np.finfo(np.float64).max), "float": float(np.finfo(np.float32).max)}


# joints a user would rather lock than integrate: grippers, fingers, hands
GRIPPER = re.compile(r"finger|gripper|grip|hand|jaw|claw", re.IGNORECASE)


class UnstableDiscretization(ValueError):
    """The discretised observer is unstable for its gains, dt and method; the message names
    the gain, dt, the cause and the fix as Python arguments; ``cli_message`` (or None) the same
    with the command line's flags (what ``python -m codegen`` prints).

    Parameters
    ----------
    message : str
        The refusal, with the fixes as Python arguments.
    cli_message : str, optional
        The refusal, with the fixes as command-line flags.
    """

    def __init__(self, message, cli_message=None):
        super().__init__(message)
        self.cli_message = cli_message


@dataclass
class StabilityReport:
    """What ``check`` found (JSON-able through ``as_dict``).

    Attributes
    ----------
    stable : bool
    spectral_radius : float
        max_i rho(dPhi/dx) over the working points, at dt (stable) or at ``worst_dt`` (unstable).
    flow_radius : float
        max(1, rho_c) at the worst point: what the exact flow allows there.
    step_error : float
        max_i ||dPhi/dx - expm(dt (J_i + J_i+)/2)||_2 (accuracy of the step over one sample dt).
    gains : dict
        gain -> {"value": current (largest slot), "slots": parameter names, "max_stable": the
        largest stable value (None: unstable even at 0, or not computed), "limit_found": False
        when no instability was found up to ``max_stable`` = 4^10 times the value}.
    negative : list
        Gains below 0.
    dt, method, hold, substeps : the discretisation checked
    dt_min, dt_max : float or None
        The declared range of the elapsed time (s), checked at ``sample_times`` (``dts``).
    worst_dt : float or None
        The sample time of the range where rho / max(1, rho_c) is largest (for a stable observer
        usually dt_min, where both radii are closest to 1).
    dt_limit : float or None
        Largest stable sample time with these parameters (computed when unstable).
    substeps_needed : int or None
        ceil(dt_max / dt_limit) (computed when unstable): the factor on substeps that makes the range stable.
    points : int
    precision, rounding, rounding_limit : the precision checked; the estimate's rounding error
        from the stored state and its bound (module docstring: precision)
    clocks : dict
        time parameter -> {"value", "max"}: the largest time its clock reaches (``clock_limit``).
    """

    stable: bool
    spectral_radius: float
    flow_radius: float
    step_error: float
    dt: float
    method: str
    hold: str
    substeps: int
    gains: dict = field(default_factory=dict)
    negative: list = field(default_factory=list)
    dt_min: float | None = None
    dt_max: float | None = None
    worst_dt: float | None = None
    dts: list = field(default_factory=list)
    dt_limit: float | None = None
    substeps_needed: int | None = None
    points: int = 0
    checked: bool = True
    evaluable: bool = True     # False: the step is not finite at the working points (unstable)
    stiff_mode: dict | None = None   # when unstable: rate (1/s), state, joint, cause, lock
    precision: str = "double"
    rounding: float | None = None        # u max_i sum_k |d est / d x_k| |x_k|: the estimate's rounding
    rounding_limit: float | None = None  # sqrt(u) max_i ||est_i||: half the significand kept
    clocks: dict = field(default_factory=dict)   # time parameter -> {"value", "max"} (s)

    def as_dict(self):
        """The report as a JSON-ready dict (``dataclasses.asdict``; ``stiff_mode`` only when
        there is one, so a stable target's metadata is what it was before the field existed)."""
        d = asdict(self)
        if d["stiff_mode"] is None:
            del d["stiff_mode"]
        return d

    @property
    def imprecise(self):
        """True when the estimate's rounding error is above its bound (module docstring: precision)."""
        return self.rounding is not None and not self.rounding <= self.rounding_limit

    @property
    def late(self):
        """{time parameter: {"value", "max"}} of the clocks that do not reach their time."""
        return {t: c for t, c in self.clocks.items() if not c["value"] <= c["max"]}

    def message(self, family, form="python", auto=False):
        """One line: the gain(s) (or the name ``family`` when none), dt, method, spectral radius,
        the cause (the stiff mode's joint and why it is stiff) and the fixes, as Python arguments
        (``form`` "python": ``substeps="auto"``, ``dt=``, ``locked_joints=``) or command-line flags
        ("cli": ``--substeps auto``, ``--dt``, ``--lock``); ``auto``: the substeps were chosen
        automatically already (choosing them is then no fix)."""
        if form not in ("python", "cli"):
            raise ValueError(f"form must be 'python' or 'cli', got {form!r}")
        cli = form == "cli"
        where = f"at dt = {self.dt:g} with {self.method} ({self.hold} hold, {self.substeps} substep(s))"
        if self.dt_min is not None and self.dt_max is not None and self.dt_min < self.dt_max:
            where += f", elapsed time in [{self.dt_min:g}, {self.dt_max:g}]"
        gains = ", ".join(f"{g} = {v['value']:.6g}" for g, v in self.gains.items()) or family
        at = (f" at elapsed time {self.worst_dt:g}" if self.worst_dt is not None and self.worst_dt != self.dt
              and not self.stable else "")
        grows = not self.evaluable or not self.spectral_radius <= self.flow_radius * (1 + TOL)
        imprecise, late = self.imprecise, self.late
        reasons = [f"{', '.join(self.negative)} must be >= 0"] if self.negative else []
        if not self.evaluable:
            reasons.append(f"the step is not finite (an overflow, a NaN) at the working points{at}")
        elif grows or not (imprecise or late or self.negative):
            reasons.append(f"spectral radius {self.spectral_radius:.4g} > 1{at} (the continuous-time observer: "
                           f"{self.flow_radius:.4g})")
        stiff = self.stiff_mode or {}
        if stiff.get("cause") and grows and not self.negative:
            reasons.append(stiff["cause"])
        half = SIGNIFICAND[self.precision] // 2
        if imprecise:
            reasons.append(f"in {self.precision} the estimate's rounding error from the stored state is "
                           f"{self.rounding:.3g} (u sum_k |d est/d x_k| |x_k|), above {self.rounding_limit:.3g} "
                           f"(2^-{half} of the estimate's size: fewer than half its {SIGNIFICAND[self.precision]} "
                           f"bits left; the gain cancels in the state)")
        for t, c in late.items():
            reasons.append(f"{t} = {c['value']:g} s is beyond what the {self.precision} clock reaches within one "
                           f"sample (each step adds the elapsed time, rounded: {t} <= {c['max']:.6g} s at "
                           f"elapsed times >= {self.dt_min:g} s)")
        why = "; ".join(reasons)
        fixes = [f"stable for 0 <= {g} <= {v['max_stable']:.6g}" if v["limit_found"] else
                 f"stable for every {g} >= 0 tested (up to {v['max_stable']:.3g})"
                 for g, v in self.gains.items() if v["max_stable"]]
        m = (self.substeps_needed or 0) * self.substeps
        if grows and 0 < m <= SUBSTEPS_MAX:   # more than a target may have: not a fix
            fixes.append(f"or use --substeps {m} (or more)" if cli else f"or use substeps >= {m}")
        if grows and self.dt_limit:
            limit = f"{self.dt_limit:.3g}"
            if self.dt_limit >= self.dt:
                fixes.append(f"or --dt-max {limit} (or less; longer intervals are split)" if cli else
                             f"or dt_max <= {limit} (longer intervals are split)")
            else:
                fixes.append(f"or --dt {limit} (or less)" if cli else f"or dt <= {limit}")
        if grows and not self.negative and not auto:   # sub-steps cannot make a negative gain stable
            fixes.append("or --substeps auto to choose them" if cli else 'or substeps="auto" to choose them')
        if stiff.get("lock") and grows and not self.negative:
            j = stiff["lock"]
            fixes.append(f"or lock {j}: --lock {j}=0" if cli else
                         f"or lock {j}: load_robot(urdf=..., locked_joints={{{j!r}: 0.0}})")
        if (imprecise or late) and self.precision != "double":
            fixes.append("or --precision double" if cli else 'or precision="double"')
        if fixes:                             # the first fix is not an alternative to another
            fixes[0] = fixes[0].removeprefix("or ")
        return f"{gains} {where}: {why}" + (f"; {', '.join(fixes)}" if fixes else "")


def _gain_value(p, idx):
    return float(np.max(p[idx])) if len(idx) else 0.0


def _working_points(spec, points, seed, rng):
    """(Y, U, EST), 2 ``points`` rows: each measurement with the estimate at rest, then moving.

    A rigid robot: y where ``spec.inputs`` declares it (codegen.verify.inputs), u = g(y) when u
    is the joint torque (else as declared), estimates 0 and velocity-sized. An elastic one (no joint-space sampling of its own): sampled plant
    states as the estimates (at rest: velocities 0), y and u at unit scale."""
    robot = spec.robot
    if hasattr(robot, "sample_configurations"):
        Y, U = measurements(spec, points, seed, rng)
        if spec.nu == robot.n:                # u = tau: the static torque g(y), at rest an equilibrium
            U = np.asarray(robot.g.map(points)(Y[:, :robot.n].T)).T
        moving = 0.5 * spec.inputs.est_scale * rng.normal(size=(points, spec.nest))
        rest = np.zeros_like(moving)
    else:
        Y, U = rng.normal(size=(points, spec.ny)), rng.normal(size=(points, spec.nu))
        if spec.nest == robot.nx:
            moving = robot.sample_states(points, seed)
            rest = robot.sample_states(points, seed, speed=0.0)
        else:
            moving = 0.5 * spec.inputs.est_scale * rng.normal(size=(points, spec.nest))
            rest = np.zeros_like(moving)
    EST = np.vstack([rest, moving])
    if spec.measurement is not None:          # y of a plant in the estimated state: converged
        Y = np.asarray(spec.measurement.map(2 * points)(EST.T)).reshape(spec.ny, 2 * points).T
        return Y, np.vstack([U, U]), EST
    return np.vstack([Y, Y]), np.vstack([U, U]), EST


def sample_times(disc):
    """The sample times the check covers (s, ascending): dt_min, dt, dt_max of ``disc`` (a
    Discretization) and the geometric midpoints of [dt_min, dt] and [dt, dt_max], without repeats."""
    lo, hi = disc.dt_range
    dts = {lo, disc.dt, hi, math.sqrt(lo * disc.dt), math.sqrt(disc.dt * hi)}
    return sorted(d for d in dts if lo <= d <= hi)


class _Linearisation:
    """The step's Jacobian and the exact flow's growth at the working points, for any p and
    sample times (one mapped call for all of them)."""

    def __init__(self, spec, disc, points=POINTS, seed=0):
        self.spec, self.disc = spec, disc
        rng = np.random.default_rng(seed)
        Y, U, EST = _working_points(spec, points, seed, rng)
        # the declared continuous slots (about y, uniform); a discrete one (a hybrid logic state)
        # stays as init sets it, consistent with the rest of the state, and the step's jump moves it
        slots = declared_slots(spec, Y, rng)
        integer = {spec.x_names.index(name) for name, _, _ in spec.inputs.x_integer}
        self.slots = {i: v for i, v in slots.items() if i not in integer}
        # each point at each phase of the logic or clock slots (``spec.phases``): K copies in a row
        self.K = 1 if spec.phases is None else spec.phases.size2_out(0)
        self._base = (Y, EST)
        self.Y, self.U, self.EST = (np.repeat(a, self.K, axis=0) for a in (Y, U, EST))
        self.S = len(self.Y)
        # SX (a step that calls its model is expanded there before its Jacobian is taken)
        self._jac, self._maps, self._output = step_jacobians(spec, disc), {}, None
        self.failed = (None, None)      # (sample time, point) that failed last (``stable``)
        self.known = (None, {})         # (p, {sample time: excess (S,)}) of the last ``radii``
        self.init = spec.init.map(len(Y))
        self.phases = None if spec.phases is None else spec.phases.map(len(Y))

    def _map(self, count):
        if count not in self._maps:
            self._maps[count] = self._jac.map(count)
        return self._maps[count]

    def states(self, p):
        """The states x (nx, S) at the working points for parameters p: init(y, est, p), the
        declared slots, then each phase (``spec.phases``)."""
        (Y, EST), nx, B = self._base, self.spec.nx, len(self._base[0])
        P = np.tile(np.asarray(p, float)[:, None], B)
        X = np.asarray(self.init(Y.T, EST.T, P)).reshape(nx, B)
        for i, values in self.slots.items():
            X[i] = values
        if self.phases is not None:           # point i at phase k: column i K + k, as Y repeated
            X = np.asarray(self.phases(X, Y.T, P)).reshape(nx, self.S)
        return X

    def at(self, p, dts, points=None):
        """(Phi, J) (G, S, nx, nx) at parameters p and the G sample times ``dts``: the step's
        Jacobian and (J(x) + J(x_next)) / 2, whose exponential expm(dt J) is the exact linearised
        flow over the step to O(dt^3); None for J when anything is not finite. ``points``: the
        indices of the working points to take (default all S; then S is their number)."""
        X, Y, U = self.states(p), self.Y.T, self.U.T
        if points is not None:
            X, Y, U = X[:, points], Y[:, points], U[:, points]
        S, G = X.shape[1], len(dts)
        P = np.tile(np.asarray(p, float)[:, None], S)
        # a mapped matrix output is [A_1 A_2 ...] side by side; the points repeat per sample time
        # (Phi is larger than J by the step's memory, "expmid1")
        T = np.repeat(np.asarray(dts, float), S)[None, :]
        with np.errstate(all="ignore"):
            Phi, J0, J1 = (np.asarray(m).reshape(m.size1(), G, S, m.size1()).transpose(1, 2, 0, 3)
                           for m in self._map(G * S)(np.tile(X, G), np.tile(Y, G), np.tile(U, G),
                                                    np.tile(P, G), T))
            J = 0.5 * (J0 + J1)
        return Phi, (J if np.all(np.isfinite(Phi)) and np.all(np.isfinite(J)) else None)

    def rounding(self, p):
        """(e, m): e = max_i max_j sum_k |d est_j / d x_k| |x_k| at the working points, the error
        of the estimate per unit roundoff of the stored state (x_k to within u |x_k|), and
        m = max_i max(||est_i||_inf, ||output_i||_inf), the estimate's size there (the one the
        point is built from, and the output's); e inf when not finite."""
        spec = self.spec
        if self._output is None:
            f = spec.output
            x, y, u, q = f.sx_in() if f.is_a("SXFunction") else f.mx_in()
            est = f(x, y, u, q)
            self._output = ca.Function("rounding", [x, y, u, q], [ca.jacobian(est, x), est]).map(self.S)
        X = self.states(p)
        with np.errstate(all="ignore"):
            D, E = (np.asarray(m) for m in self._output(X, self.Y.T, self.U.T,
                                                       np.tile(np.asarray(p, float)[:, None], self.S)))
            D = D.reshape(spec.nest, self.S, spec.nx).transpose(1, 0, 2)
            e = float(np.max(np.abs(D) @ np.abs(X.T)[:, :, None])) if spec.nest and spec.nx else 0.0
            m = float(max(np.max(np.abs(E)), np.max(np.abs(self.EST)))) if E.size else 0.0
        return (e if math.isfinite(e) and math.isfinite(m) else math.inf), m

    def _radii(self, p, dts, points=None):
        """(Phi, J, rho, rho_c): ``at`` and, at each sample time and point (G, S), rho(Phi) and
        max(1, rho_c), rho_c = exp(dt max Re eig J) (= rho(expm(dt J))); both infinite (J None)
        when anything is not finite."""
        Phi, J = self.at(p, dts, points)
        if J is None:
            inf = np.full(Phi.shape[:2], math.inf)
            return Phi, J, inf, inf
        d = np.asarray(dts, float)[:, None]
        rho = np.max(np.abs(np.linalg.eigvals(Phi)), axis=2)
        rho_c = np.maximum(1.0, np.exp(np.minimum(d * np.max(np.linalg.eigvals(J).real, axis=2), 700.0)))
        return Phi, J, rho, rho_c

    def radii(self, p, dts, accuracy=None):
        """At each sample time of ``dts``: (max rho(Phi), max(1, rho_c) at the worst point,
        max_i rho(Phi_i) / max(1, rho_c,i)) as three (G,) arrays, rho_c = exp(dt max Re eig J)
        (= rho(expm(dt J))); and max_i ||Phi_i - expm(dt J_i)||_2 at the sample time
        ``accuracy`` (one of dts) if given, else None. Infinite when anything is not finite."""
        Phi, J, rho, rho_c = self._radii(p, dts)
        if J is None:
            self.known = (np.asarray(p, float).tobytes(), {d: None for d in dts})
            inf = np.full(len(dts), math.inf)
            return inf, inf, inf, math.inf if accuracy is not None else None
        excess = rho / rho_c
        self.known = (np.asarray(p, float).tobytes(), dict(zip(dts, excess)))
        worst = np.argmax(excess, axis=1)
        rows = np.arange(len(dts))
        error = None
        if accuracy is not None:
            g = list(dts).index(accuracy)
            # the state's block (a step's memory has no flow to compare with)
            n = J.shape[-1]
            error = float(max(_distance(a[:n, :n], expm(accuracy * b)) for a, b in zip(Phi[g], J[g])))
        return rho.max(axis=1), rho_c[rows, worst], excess[rows, worst], error

    def stable(self, p, dts, points=None):
        """True when the step is stable (module docstring) at every sample time of ``dts`` and
        working point of ``points`` (indices; default all). The verdict is that of all of them,
        its cost not: the point and sample time that failed last (``failed``; else the largest
        of ``dts``, where an explicit step leaves its region first) are tried first, then that
        sample time's other points, then the other sample times, stopping at the first that
        fails, whose (sample time, point) becomes ``failed`` (point None when the step is not
        finite there). An unstable value usually costs one point's linearisation."""
        dts, h, k = list(dts), *self.failed
        rows = list(range(self.S)) if points is None else list(points)
        key, known = self.known
        if key == np.asarray(p, float).tobytes() and all(d in known for d in dts):
            return self._known_stable(dts, rows)
        if h not in dts:
            h = dts[-1]
        first = [k] if k in rows and len(rows) > 1 else []
        rest = [d for d in dts if d != h]
        for group, at in (([h], first), ([h], [i for i in rows if i not in first]), (rest, rows)):
            if not group or not at:
                continue
            _, J, rho, rho_c = self._radii(p, group, at)
            if J is None:
                self.failed = (group[-1], None)
                return False
            excess = rho / rho_c
            if not np.all(excess <= 1 + TOL):
                g, i = np.unravel_index(np.argmax(excess), excess.shape)
                self.failed = (group[g], at[i])
                return False
        return True

    def _known_stable(self, dts, rows):
        """``stable`` from the excess ``radii`` found at the same p (``known``), ``failed`` set
        as there."""
        known = self.known[1]
        for d in dts:
            excess = known[d]
            if excess is None:
                self.failed = (d, None)
                return False
            bad = [i for i in rows if not excess[i] <= 1 + TOL]
            if bad:
                self.failed = (d, max(bad, key=lambda i: excess[i]))
                return False
        return True

    def precision(self, p, precision="double"):
        """(u e, sqrt(u) m) of ``rounding`` in ``precision`` (unit roundoff u): the estimate's
        rounding error from the stored state, and the most it may be (half the significand kept)."""
        e, m = self.rounding(p)
        u = UNIT_ROUNDOFF[precision]
        return u * e, math.sqrt(u) * m

    def precise(self, p, precision="double"):
        """True when the estimate keeps at least half its significand (``precision``)."""
        error, limit = self.precision(p, precision)
        return error <= limit


LINEARISATIONS = 4     # the last linearisations kept in the process (``linearisation``)
_linearisations = {}


def linearisation(spec, disc, digest=None):
    """The ``_Linearisation`` of ``spec`` under ``disc``, kept for the last ``LINEARISATIONS``
    (spec, method, hold, substeps): it does not depend on p nor on the sample times, and building
    it (the step's SX Jacobian, 0.9 s for kalman_model on ur5) costs as much as a whole search,
    every time ``tune`` or ``compare`` checks a parameter vector of the same spec. ``digest``:
    ``_digest(spec)`` if known."""
    key = (digest or _digest(spec), disc.method, disc.hold, disc.substeps, POINTS)
    lin = _linearisations.pop(key, None) or _Linearisation(spec, disc)
    _linearisations[key] = lin                       # the most recent last
    while len(_linearisations) > LINEARISATIONS:
        del _linearisations[next(iter(_linearisations))]
    return lin


def _joint_of(spec, state):
    """The robot joint a state slot belongs to (its name ends with ``_<joint>``), or None."""
    name = spec.x_names[state]
    joints = sorted(getattr(spec.robot, "joint_names", []), key=len, reverse=True)
    return next((j for j in joints if name.endswith("_" + j)), None)


def stiff_mode(spec, lin, p, dt):
    """The stiffest mode of the flow at the working points: the eigenvalue of (J(x) + J(x+))/2 of
    largest modulus, the state slot its eigenvector lives on most, that slot's joint, and why it
    is stiff, from the robot at that point's configuration y: for joint j with M^-1 (kg m^2)^-1 and
    the friction's slope at rest d_j = viscous_j + coulomb_j / width (N m s/rad; the smooth
    Coulomb sign tanh(v / width) is steepest there), the rate d_j (M^-1)_jj when it explains the
    mode (>= half of it: "friction on a small inertia"), else the gain when the slot is a rate
    state whose gain rate a (``spec.rate``) is >= half of it, else the small inertia 1 / (M^-1)_jj
    alone.

    Parameters
    ----------
    spec : ObserverSpec
    lin : _Linearisation
        The working points.
    p : (np,) array
        Parameters.
    dt : float
        Sample time (s).

    Returns
    -------
    dict or None
        rate (|eigenvalue|, 1/s), rate_dt (rate dt), state (slot name), joint (or None), cause
        (text), lock (the joint, when it looks like a gripper or finger: locking it is the fix;
        else None); None when the flow is not finite there.
    """
    _, J = lin.at(p, [dt])
    if J is None:
        return None
    J = J[0]
    w, V = np.linalg.eig(J)                                  # (S, nx), (S, nx, nx)
    i, k = np.unravel_index(np.argmax(np.abs(w)), w.shape)
    rate = float(abs(w[i, k]))
    state = int(np.argmax(np.abs(V[i, :, k])))
    joint = _joint_of(spec, state)
    out = {"rate": rate, "rate_dt": rate * dt, "state": spec.x_names[state], "joint": joint,
           "cause": None, "lock": None}
    robot = spec.robot
    gain = 0.0
    if spec.rate is not None and spec.x_names[state] in spec.rate_states:
        # the output injection's own rate a (rhs = N - a x on the rate states)
        gain = float(np.max(np.abs(np.asarray(spec.rate(lin.states(p)[:, i], p), dtype=float))))
    head = f"the stiff mode (rate {rate:.3g} 1/s = {rate * dt:.3g} / dt) is "
    by_gain = f"{head}the gain's own rate {gain:.3g} 1/s on {spec.x_names[state]}"
    if joint is None or not hasattr(robot, "M"):
        out["cause"] = by_gain if gain >= 0.5 * rate else None
        return out
    j = robot.joint_names.index(joint)
    y = lin.Y[i][:robot.n]
    minv = np.linalg.inv(np.asarray(robot.M(y), dtype=float))
    inertia, viscous = 1.0 / minv[j, j], float(np.asarray(robot.F)[j, j])
    # the friction's slope at rest: viscous + Coulomb / width (its tanh's steepest point)
    coulomb = float(np.asarray(getattr(robot, "coulomb", np.zeros(robot.n)), dtype=float)[j])
    width = float(getattr(robot, "coulomb_width", 1.0))
    damping = viscous + coulomb / width
    friction = (f"viscous friction {viscous:.3g} N m s/rad" if coulomb == 0 else
                f"friction of slope {damping:.3g} N m s/rad at rest (viscous {viscous:.3g} + Coulomb "
                f"{coulomb:.3g} N m / width {width:.3g} rad/s)")
    if damping * minv[j, j] < 0.5 * rate <= gain:
        out["cause"] = by_gain
        return out
    what = (f"{friction} on the small inertia of {joint} ({inertia:.2g} kg m^2 seen from it: rate "
            f"{damping * minv[j, j]:.3g} 1/s)" if damping * minv[j, j] >= 0.5 * rate
            else f"the small inertia of {joint} ({inertia:.2g} kg m^2 seen from it)")
    gripper = bool(GRIPPER.search(joint))
    out["cause"] = f"{head}{what}" + (", a gripper joint" if gripper else "")
    out["lock"] = joint if gripper else None
    return out


def _distance(a, b):
    """||a - b||_2, inf when not finite."""
    d = a - b
    return float(np.linalg.norm(d, 2)) if np.all(np.isfinite(d)) else math.inf


def _largest(ok, lo, hi, grow, probe=None):
    """(largest v >= lo with ok(v), True) -- ok(lo) assumed: while ok(hi), hi x4 (at most
    ``grow`` times; (the last hi, False) if never unstable), then bisect. From lo = 0, when the
    bisection finds nothing above 0 (hi far beyond the limit: a gain of 1e300), hi / 4 at a
    time (at most ``SHRINK`` times) until ok, then bisect again.

    ``probe`` (default ok): what the growth and the bisection test, a cheaper part of ok (not
    probe(v) implies not ok(v)); the value returned then passes ok itself (``_bisect``), or the
    search is redone with ok alone."""
    test = probe or ok
    passed = set()

    def good(v):
        if ok(v):
            passed.add(v)
            return True
        return False
    start, first = lo, hi
    if test(hi):
        for _ in range(grow):
            lo, hi = hi, 4 * hi
            if not test(hi):
                break
        else:
            if probe is None or good(hi):
                return hi, False
            return _largest(ok, start, first, grow)
    lo, hi = _bisect(good, lo, hi, probe)
    if lo == 0 == start:
        for _ in range(SHRINK):
            if good(hi / 4):
                lo, hi = _bisect(good, hi / 4, hi, probe)
                break
            hi /= 4
    if probe is not None and lo != start and lo not in passed and not good(lo):
        return _largest(ok, start, first, grow)
    return lo, True


def _bisect(ok, lo, hi, probe=None):
    """(lo, hi) after ``BISECTIONS`` halvings of [lo, hi] keeping ok(lo) and not ok(hi).

    ``probe`` (a cheaper part of ok: not probe(v) implies not ok(v)) decides each halving instead,
    and the lo it leaves is confirmed by ok; where ok refuses it, the halving that raised lo
    there is taken the other way, and so each earlier one whose mid the probe refuses now, and
    the halvings go on from there (after ``BISECTIONS`` refusals, on ok alone). The same bracket as ok alone when their verdicts agree; the lo given is
    returned unconfirmed when no halving raises it."""
    test, raised, n = probe or ok, [], 0
    for refusals in range(BISECTIONS + 1):
        if refusals == BISECTIONS:
            test = ok
        while n < BISECTIONS:
            mid = 0.5 * (lo + hi)
            if test(mid):
                raised.append((lo, hi, n))
                lo = mid
            else:
                hi = mid
            n += 1
        if test is ok or not raised or ok(lo):
            break
        while True:       # ok refuses the last mid the probe passed: its halving the other way,
            lo, hi, n = raised.pop()         # and so the earlier ones the probe (which has
            hi, n = 0.5 * (lo + hi), n + 1   # learnt from ok's refusal) refuses now
            if not raised or test(lo):
                break
    return lo, hi


def _max_stable(lin, p, idx, dts, precision="double"):
    """(largest value of the gain at slots ``idx`` (all scaled together, others fixed) stable at
    every sample time of ``dts`` and within ``precision`` (``_Linearisation.precise``), whether an
    unstable value was found); (None, True) when unstable even at 0.

    The growth and the bisection test a probe: the sample times and working points that have
    failed in this search (at first the one that failed last, all points); ``_largest`` confirms
    the value it returns on all of them, and a failure there adds its sample time and point to
    the probe."""
    v0 = _gain_value(p, idx)
    base = p[idx] / v0 if v0 > 0 else np.ones(len(idx))
    h = lin.failed[0]
    times, points = [h if h in dts else dts[-1]], set()     # the probe's

    def ok(v, every=True):
        q = p.copy()
        q[idx] = base * v if v != v0 else p[idx]
        if not lin.stable(q, dts if every else times, None if every or not points else sorted(points)):
            h, k = lin.failed
            times.extend([h] if h not in times else [])
            points.update([k] if k is not None else [])
            return False
        return lin.precise(q, precision)
    if not ok(0.0):
        return None, True
    return _largest(ok, 0.0, v0 if v0 > 0 else 1.0, round(math.log(GROWTH, 4)), probe=lambda v: ok(v, False))


def clock_limit(dt, dt_min, precision="double"):
    """The largest time t (s) a clock s' = 1 reaches within one sample in ``precision``: each step
    adds an elapsed time h >= ``dt_min`` rounded to the precision (at most half an ulp of s), so
    after t / dt_min steps s is off by up to (t / dt_min) ulp(t) / 2; t is reached when that is
    at most the sample time ``dt``: t ulp(t) <= 2 dt dt_min, ulp(t) = 2^(e - m) on [2^e, 2^(e+1))
    (m = significand bits - 1). A float clock at dt = 1 ms, dt_min = dt / 4: 2.1 s (it stalls
    for good at 2^15 s, where h < ulp / 2); a double one: 65536 s."""
    m, budget = SIGNIFICAND[precision] - 1, 2.0 * dt * dt_min
    e = math.floor((math.log2(budget) + m) / 2)       # the last binade [2^e, 2^(e+1)) reached in
    return min(math.ldexp(budget, m - e), float(np.nextafter(math.ldexp(1.0, e + 1), 0)))


def _compute(spec, disc, p, gains, bounds=True, precision="double", digest=None):
    lin = linearisation(spec, disc, digest)
    dts = sample_times(disc)
    rho, flow, excess, step_error = lin.radii(p, dts, accuracy=disc.dt)
    worst = int(np.argmax(excess))                 # the sample time of the range closest to growing
    idx = {g: [spec.p_names.index(s) for s in slots] for g, slots in gains.items()}
    negative = [g for g, i in idx.items() if np.any(p[i] < 0)]
    # a step that is not finite at p (a gain that overflows it, a guard parameter that rejects
    # every pivot) is no observer: unstable, like one that grows
    evaluable = bool(np.all(np.isfinite(rho)))
    grows = not excess[worst] <= 1 + TOL
    rounding, rounding_limit = lin.precision(p, precision)
    lo, hi = disc.dt_range
    clocks = {t: {"value": float(p[spec.p_names.index(t)]), "max": clock_limit(disc.dt, lo, precision)}
              for t in spec.clocks.values()}
    late = [t for t, c in clocks.items() if not c["value"] <= c["max"]]
    stable = not (grows or negative or late or not rounding <= rounding_limit)
    w = dts.index(disc.dt) if not grows else worst   # the radii reported: at dt, or failing
    report = {"gains": {}}
    for g, i in idx.items():
        top, found = _max_stable(lin, p, i, dts, precision) if bounds else (None, False)
        report["gains"][g] = {"value": _gain_value(p, i), "slots": list(gains[g]), "max_stable": top,
                              "limit_found": found}
    report.update({
        "stable": stable, "spectral_radius": float(rho[w]), "flow_radius": float(flow[w]),
        "step_error": step_error, "negative": negative, "points": lin.S, "evaluable": evaluable,
        "dt_min": lo, "dt_max": hi, "worst_dt": dts[worst], "dts": dts, "precision": precision,
        "rounding": rounding, "rounding_limit": rounding_limit, "clocks": clocks})
    if bounds and grows and not negative:
        # the largest h stable from 0 (below the smallest failing sample time)
        failing = min(d for d, e in zip(dts, excess) if not e <= 1 + TOL)
        limit = _largest(lambda h: lin.stable(p, [h]), 0.0, failing, 0)[0]
        report["dt_limit"] = limit if limit > 0 else None
        report["substeps_needed"] = math.ceil(hi / limit) if limit > 0 else None
    if grows and evaluable:
        report["stiff_mode"] = stiff_mode(spec, lin, p, disc.dt)
    return report


def _digest(spec):
    """Digests of the spec's functions: the check depends on nothing else of the spec."""
    from ..core.cache import key_digest
    fns = [spec.rhs, spec.rhs_split, spec.output, spec.init, spec.jump, spec.rate, spec.measurement,
           spec.phases]
    return key_digest([f.serialize() if f is not None else None for f in fns]
                      + [list(spec.rate_states), spec.inputs.to_dict()])


def check(spec, disc, p=None, cache=True, bounds=True, precision="double"):
    """The discrete stability and accuracy of ``spec`` under ``disc`` (module docstring).

    Parameters
    ----------
    spec : ObserverSpec
    disc : codegen.core.target.Discretization
    p : (np,) array, optional
        Parameters (default ``spec.p_default``).
    cache : bool
        Keep the result on disk (codegen.core.cache), keyed by the spec's functions, p and disc.
    bounds : bool
        Also bisect for the largest stable gains (and, when unstable, dt and substeps); False:
        only the verdict and radii at p (``max_stable`` None).
    precision : {"double", "float"}
        The C's real type: the estimate's rounding and the clocks' reach are judged in it.

    Returns
    -------
    StabilityReport
        Raises ValueError for a non-finite parameter or one beyond the precision's range, and
        UnstableDiscretization for an elapsed-time range that is not finite in the precision.
    """
    p = np.asarray(spec.p_default if p is None else p, dtype=float).reshape(spec.np)
    if precision not in UNIT_ROUNDOFF:
        raise ValueError(f"precision must be one of {sorted(UNIT_ROUNDOFF)}, got {precision!r}")
    if disc.substeps == AUTO:
        raise ValueError(f'{spec.family}: substeps="auto" is a request, resolved into a number by '
                         "auto_substeps (codegen.pipeline.stages.make and compile_observer do); "
                         "check a number of substeps")
    lo, hi = disc.dt_range
    top = REAL_MAX[precision]
    if not (0 < lo and hi <= top):
        where = f"dt = {disc.dt:g} s (elapsed times in [{lo:g}, {hi:g}] s)"
        raise UnstableDiscretization(
            f"{spec.family}: {where} is beyond the {precision} range: dt and dt_max must be at most "
            f"{top:.3g} s, and a stable one is far smaller (substeps=\"auto\" finds the sub-steps it needs)",
            f"{spec.family}: {where} is beyond the {precision} range: --dt and --dt-max must be at most "
            f"{top:.3g} s, and a stable one is far smaller (--substeps auto finds the sub-steps it needs)")
    if spec.nx == 0 or spec.ny == 0:
        # a stateless law has nothing to diverge; a plant (no measurement) is no observer: its
        # step is the simulation's business (codegen.evaluate.sim), not checked here
        return StabilityReport(stable=True, spectral_radius=0.0, flow_radius=1.0, step_error=0.0, dt=disc.dt,
                               method=disc.method, hold=disc.hold, substeps=disc.substeps,
                               checked=spec.nx == 0, dt_min=lo, dt_max=hi, precision=precision)
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{spec.family}: non-finite parameter(s) "
                         f"{[n for n, v in zip(spec.p_names, p) if not np.isfinite(v)]}")
    beyond = [f"{n} = {v:g}" for n, v in zip(spec.p_names, p) if abs(v) > top]
    if beyond:
        raise ValueError(f"{spec.family}: parameter(s) {', '.join(beyond)} beyond the {precision} range "
                         f"(|p| <= {top:.3g})")
    key = {"version": VERSION, "spec": _digest(spec), "disc": disc.to_dict(), "range": list(disc.dt_range),
           "p": p.tolist(), "precision": precision, "clocks": spec.clocks,
           "gains": {g: list(s) for g, s in spec.gains.items()}, "points": POINTS, "bounds": bounds}

    def compute():
        return _compute(spec, disc, p, spec.gains, bounds, precision, key["spec"])
    value = cached_json("stability", key, compute) if cache else compute()
    return StabilityReport(dt=disc.dt, method=disc.method, hold=disc.hold, substeps=disc.substeps,
                           **value)


def require_stable(spec, disc, p=None, precision="double", bounds=True, explain=True):
    """``check(spec, disc, p, precision=precision, bounds=bounds)`` (p: parameters (np,) or None
    for the spec's defaults), raising UnstableDiscretization (its message) when unstable.
    ``bounds`` False: the verdict alone (no search for the largest stable gains, a third of the
    cost for kalman_model); when unstable, the refusal is that of the report with them (its fixes),
    unless ``explain`` is False (a search that only needs the verdict: the refusal without them)."""
    report = check(spec, disc, p, precision=precision, bounds=bounds)
    if not report.stable:
        raise _refusal(spec, report if bounds or not explain else check(spec, disc, p, precision=precision))
    return report


def _refusal(spec, report, prefix="", auto=False):
    """UnstableDiscretization of ``report`` for ``spec``, in Python's words and the CLI's
    (``auto``: refused by ``auto_substeps``, which does not suggest itself)."""
    return UnstableDiscretization(f"{spec.family}: {prefix}" + report.message(spec.family, auto=auto),
                                  f"{spec.family}: {prefix}" + report.message(spec.family, form="cli", auto=auto))


def auto_substeps(spec, disc, p=None, limit=SUBSTEPS_MAX):
    """The discretisation with the smallest substeps (>= disc.substeps, <= limit) that is stable.

    When the range of the elapsed time is the default one (``disc.dt_max`` not declared), the
    substeps are the fewest stable over [dt_min, dt], and dt_max is declared as the largest sample
    time up to the default 2 dt they are stable at (``widest_range``): the step at dt costs no
    sub-step more for the jitter, and a longer elapsed time is split into sub-intervals (every
    default target: 1 sub-step and dt_max = 2 dt; xarm7's stiff wrist: 19 sub-steps and a dt_max
    near dt, where the whole default range would take 38). A declared dt_max is kept.

    Parameters
    ----------
    spec : ObserverSpec
    disc : codegen.core.target.Discretization
        The requested one (dt, method, hold, substeps, range; substeps "auto" starts from 1).
    p : (np,) array or None
        Parameters; None: the spec's defaults.
    limit : int
        Largest substeps tried (default ``codegen.core.target.SUBSTEPS_MAX``, what a target may have).

    Returns
    -------
    codegen.core.target.Discretization
        Raises UnstableDiscretization when none is, or when a gain is negative.
    """
    from dataclasses import replace
    if disc.substeps == AUTO:
        disc = replace(disc, substeps=1)
    if disc.dt_max is not None or check(spec, disc, p).stable:
        return _fewest(spec, disc, p, limit)
    at_dt = _fewest(spec, replace(disc, dt_max=disc.dt), p, limit)
    whole = replace(at_dt, dt_max=None)
    if check(spec, whole, p).stable:
        return whole
    return widest_range(spec, at_dt, p)


def _fewest(spec, disc, p, limit):
    """``disc`` with the fewest substeps (>= its own, <= ``limit``) stable over its range."""
    from dataclasses import replace
    report = check(spec, disc, p)
    if report.stable:
        return disc
    if report.negative or not report.substeps_needed or report.imprecise or report.late:
        raise _refusal(spec, report, auto=True)      # sub-steps cannot fix these
    m = report.substeps_needed * disc.substeps
    while m <= limit:
        candidate = replace(disc, substeps=m)
        if check(spec, candidate, p).stable:
            return candidate
        m += 1
    raise _refusal(spec, report, f"no substeps <= {limit} is stable; ", auto=True)


def widest_range(spec, disc, p=None):
    """``disc`` (stable with its range up to dt_max = dt) with dt_max declared as the largest sample
    time in [dt, DT_MAX_FACTOR dt] at which its substeps are stable over [dt_min, dt_max]
    (bisection to 2^-16, rounded down to three significant digits). The bisection's result is
    cached as ``check``'s reports are (each of its points costs as much as a check: 100 s for
    panda's identified model at 50 sub-steps, every time ``compare`` ran).

    Parameters
    ----------
    spec : ObserverSpec
    disc : codegen.core.target.Discretization
        Stable over [dt_min, dt].
    p : (np,) array or None
        Parameters; None: the spec's defaults.

    Returns
    -------
    codegen.core.target.Discretization
    """
    from dataclasses import replace
    p = np.asarray(spec.p_default if p is None else p, dtype=float).reshape(spec.np)

    def bisect():
        lin = linearisation(spec, disc, key["spec"])

        def ok(h):
            return lin.stable(p, sample_times(replace(disc, dt_max=h)))
        lo, hi = disc.dt, DT_MAX_FACTOR * disc.dt
        for _ in range(BISECTIONS):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if ok(mid) else (lo, mid)
        return lo
    key = {"version": VERSION, "widest_range": DT_MAX_FACTOR, "spec": _digest(spec), "disc": disc.to_dict(),
           "p": p.tolist(), "points": POINTS, "bisections": BISECTIONS}
    lo = float(cached_json("stability", key, bisect))
    scale = 10.0 ** (math.floor(math.log10(lo)) - 2)
    h = max(disc.dt, float(f"{math.floor(lo / scale) * scale:.3g}"))
    widest = replace(disc, dt_max=h)
    return widest if check(spec, widest, p).stable else replace(disc, dt_max=disc.dt)


def stable_defaults(spec, disc, margin=0.9):
    """``spec`` with its designed default gains inside the stable region of ``disc``: while the
    check fails, each declared gain (in order) whose largest stable value is below it is set to
    ``margin`` times that value. For the families' designs ("the design never returns an
    unstable default"); gains given explicitly are checked at compile time instead.

    Returns
    -------
    (spec, StabilityReport) -- the spec itself when it is stable."""
    from dataclasses import replace
    report = check(spec, disc)
    for gain, slots in spec.gains.items():
        if report.stable:
            break
        g = report.gains[gain]
        if not g["max_stable"] or not g["limit_found"] or g["max_stable"] >= g["value"]:
            continue
        idx = [spec.p_names.index(s) for s in slots]
        p = spec.p_default.copy()
        p[idx] *= margin * g["max_stable"] / g["value"]
        spec = replace(spec, p_default=p)
        report = check(spec, disc)
    return spec, report
