"""Independent reference observers: numpy + pinocchio, written from the papers' equations (docs/papers/).

Never imports CasADi, ``models`` or the symbolic ``codegen`` modules (docs/architecture.md §1), so a
cross-check of the generated C against it compares two independent implementations.
It reads only plain data: an ObserverSpec's ``describe()`` (family, variant, robot source,
slot names, default parameters, typed options, hybrid flag), or the same keys in a generated
target's metadata JSON, and a ``codegen.core.target.Discretization`` (plain data too).

    ref = reference_observer(spec)                      # the default discretisation
    ref = reference_observer(spec, dt=1e-3, method="rk4", substeps=1, hold="foh")
    ref.reset(y0, est0=None, p=None)
    est = ref.step(y, u)          # est from the current state, then x advances over dt
    est = ref.step(y, u, dt=h)    # the elapsed time h (s) instead of dt (a jittered loop)
    EST = ref.run(Y, U)           # (N, ny), (N, nu) -> (N, nest)
    EST = ref.run(Y, U, t)        # over time stamps t (N,) (a jittered log)

The elapsed time follows the contract of the generated C's step_dt and run_t (codegen.core.target:
``SPLIT_MAX``, ``STAMP_ULPS``): longer than dt_max, it is integrated in m = ceil(h / dt_max)
equal sub-intervals, at virtual samples where y is interpolated linearly (first-order hold; held,
zero-order) and the last input is held; an interval between stamps equal to dt up to their
rounding is dt.

A family module gives ``rhs(robot, x, y, u, p)``, ``output(robot, x, y, u, p)``,
``init(robot, y0, est0, p)``, ``sizes(robot)``, optionally ``P_NAMES``, for hybrid
observers ``jump(robot, x, y, p)``, for a flow split like the spec's (``rhs_split`` in its
description) ``rhs_split(robot, x, y_cfg, y, u, p)`` (the model at y_cfg, which the first-order
hold puts at each sub-step's midpoint configuration), for a flow whose model part is apart
(``rhs_model`` in its description; the method expmid) ``model(robot, x, y_cfg, y, u, p)`` and
``rhs_model(robot, x, y, u, p, m)``, and, when it needs the spec's declared
options, ``configure(robot, options) -> family`` (options: the typed value of codegen.core.options): the
module's functions with those options bound as keyword arguments (reference/_family.py),
never state stored on the robot.

Robots (reference/robots.py ``reference_robot``) are rebuilt from the spec's plain-data
robot source: closed forms (rigid.py), URDF through pinocchio (urdf.py), DH tables by
Newton-Euler (dh.py) and elastic joints over any of them (elastic.py).
"""
from __future__ import annotations

import importlib
import itertools
import pkgutil

import numpy as np

from ..core.arrays import as_matrix, as_vector, positive, time_stamps
from ..core.options import options_from_dict
from ..core.target import SPLIT_MAX, interval, split_count
from ..core.target import discretization as as_discretization
from . import discretize, families
from .robots import SEED_SOURCES, reference_robot

# every public module of reference/families/, named like the symbolic family it checks
FAMILIES = {m.name: importlib.import_module(f"{families.__name__}.{m.name}")
            for m in pkgutil.iter_modules(families.__path__) if not m.name.startswith("_")}

__all__ = ["reference_observer", "reference_robot", "ReferenceObserver", "FAMILIES", "SEED_SOURCES"]


def reference_observer(spec, discretization=None, *, dt=None, method=None, substeps=None, hold=None,
                       dt_min=None, dt_max=None):
    """The numpy reference of an observer, stepped like the generated C.

    Parameters
    ----------
    spec : ObserverSpec or dict
        Anything with ``describe()`` (an ObserverSpec), or its plain-data description (the
        keys of ``ObserverSpec.describe``; a generated target's metadata JSON has them).
    discretization : codegen.core.target.Discretization or dict, optional
        Default: ``codegen.core.target.DEFAULT_DISCRETIZATION`` (for metadata: the recorded one).
        ``dt``, ``dt_min``, ``dt_max`` (s), ``method``, ``substeps`` and ``hold`` override single
        fields.

    Returns
    -------
    ReferenceObserver
    """
    desc = spec.describe() if hasattr(spec, "describe") else dict(spec)
    if "source" in desc["robot"]:                    # a metadata JSON: robot = {name, ..., source}
        desc = {**desc, "robot": desc["robot"]["source"],
                "hybrid": desc.get("hybrid", desc["discretization"]["hybrid"])}
    if discretization is None and "target" in desc:
        discretization = desc["target"]["discretization"]
    disc = as_discretization(discretization, dt=dt, method=method, substeps=substeps, hold=hold,
                             dt_min=dt_min, dt_max=dt_max)
    if disc.substeps == "auto":
        raise ValueError('substeps: "auto" is resolved when the target is made (the metadata JSON of a '
                         "compiled target records the number); give the reference that number")
    return ReferenceObserver(desc, disc)


def _jacobian(f, x, rel=1e-6):
    """Central-difference Jacobian of f at x (steps rel max(1, |x_j|))."""
    cols = []
    for j in range(len(x)):
        h = rel * max(1.0, abs(x[j]))
        e = np.zeros(len(x))
        e[j] = h
        cols.append((np.asarray(f(x + e), float) - np.asarray(f(x - e), float)) / (2 * h))
    return np.column_stack(cols) if cols else np.zeros((0, 0))


class ReferenceObserver:
    """A discretized observer in numpy: same step/run contract as the compiled one.

    Parameters
    ----------
    desc : dict
        Plain-data description (``ObserverSpec.describe()`` keys).
    disc : codegen.core.target.Discretization
    """

    def __init__(self, desc, disc):
        family_name = desc["family"]
        if family_name not in FAMILIES:
            raise ValueError(f"no reference for observer family {family_name!r}; known: {sorted(FAMILIES)}")
        self.disc = disc
        self.dt, self.method, self.substeps, self.hold = disc.dt, disc.method, disc.substeps, disc.hold
        self.dt_range = disc.dt_range
        self.dt_limit = SPLIT_MAX * self.dt_range[1]   # the longest elapsed time of one step
        self._prev = None   # (y, u) of the last sample, for the first-order hold
        self._stamp = None  # time stamp of the last sample (s), set by run(Y, U, t)
        self.robot = reference_robot(desc["robot"])
        family = FAMILIES[family_name]
        configure = getattr(family, "configure", None)
        self.options = options_from_dict(desc.get("options"))
        self.family = configure(self.robot, self.options) if configure else family
        names = desc["names"]
        self.x_names, self.y_names = list(names["x"]), list(names["y"])
        self.u_names, self.est_names = list(names["u"]), list(names["est"])
        self.p_names = list(names["p"])
        self.nx, self.ny, self.nu = len(self.x_names), len(self.y_names), len(self.u_names)
        self.nest, self.np = len(self.est_names), len(self.p_names)

        expected = self.family.sizes(self.robot)
        got = {"nx": self.nx, "ny": self.ny, "nu": self.nu, "nest": self.nest}
        if got != expected:
            raise ValueError(f"{family_name}: spec sizes {got} differ from the reference's {expected}")
        wanted = getattr(self.family, "P_NAMES", None)
        if wanted is not None and tuple(self.p_names) != tuple(wanted):
            raise ValueError(f"{family_name}: p_names {self.p_names} differ from the reference's {list(wanted)}")
        self.hybrid = bool(desc.get("hybrid"))
        if self.hybrid and not hasattr(self.family, "jump"):
            raise ValueError(f"{family_name}: the spec has a jump map but the reference family has none")

        has_rate = bool(desc.get("rate_states"))
        if has_rate != hasattr(self.family, "rate"):
            raise ValueError(f"{family_name}: the spec {'declares' if has_rate else 'has no'} a gain rate "
                             f"but the reference family {'has none' if has_rate else 'does'}")
        self._mask = self.family.rate_states(self.robot) if has_rate else None
        self.split = bool(desc.get("rhs_split"))     # the model at the sub-step's midpoint (foh)
        if self.split and not hasattr(self.family, "rhs_split"):
            raise ValueError(f"{family_name}: the spec splits its flow's y (rhs_split) but the "
                             f"reference family does not")

        self.model_split = bool(desc.get("rhs_model"))   # the model part apart (method expmid)
        if self.model_split and not hasattr(self.family, "model"):
            raise ValueError(f"{family_name}: the spec declares its model part (model, rhs_model) but "
                             f"the reference family does not")
        self.gains = {g: list(slots) for g, slots in (desc.get("gains") or {}).items()}
        self.p_default = as_vector("p_default", desc["p_default"], self.np)
        self._p = self.p_default.copy()
        self._x = None
        # the step's memory under expmid1: the model's last value (zeros after reset and a set state)
        # a model part that corrects a flow complete without it: expmid1 predicts without it, no memory
        self.correction = bool(desc.get("model_correction")) and self.method == "expmid1"
        self.nm = int(desc["rhs_model"]) if self.method == "expmid1" and self.model_split and not self.correction else 0
        self._m = np.zeros(self.nm)
        self._y_last = None   # the last measurement (set by reset and step), for retuning
        # the declared ranges of y and u (codegen.core.limits), the skip mode and the counters of the C
        self.limits = desc.get("limits") or {}
        self.skip, self.skipped, self.clipped = False, 0, 0
        self._pending = 0.0     # first-order hold: the time skipped since the last accepted sample
        bound = getattr(self.options, "v_bound", ()) or ()
        slots = [i for i, s in enumerate(self.est_names) if s.startswith("qd_hat_")]
        self._v = (slots, np.asarray(bound, dtype=float)) if len(bound) == len(slots) and slots else None

    # ------------------------------------------------------------ parameters
    @property
    def params(self):
        """Copy of the runtime parameters."""
        return self._p.copy()

    @params.setter
    def params(self, p):
        """New parameters ``p`` (np,), refused (ValueError) when a declared gain is negative or the step is
        unstable at the current state (``check_params``); the state is then transformed
        (``retune`` of the family, if any) so that the estimate at the last measurement is
        unchanged (bumpless retuning)."""
        p = as_vector("p", p, self.np)
        x = self._retuned(p)
        self.check_params(p, x)
        self._x, self._p = x, p

    def _retuned(self, p):
        """The state that keeps the estimate at the last measurement under parameters p."""
        retune = getattr(self.family, "retune", None)
        if retune is None or self._x is None:
            return self._x
        return np.asarray(retune(self.robot, self._x, self._y_last, self._p, p), dtype=float).reshape(self.nx)

    def check_params(self, p, x=None, explain=True):
        """The reference's own stability check of parameters p (``explain``: as the compiled
        observer's, its refusal costs nothing more either way): each declared gain >= 0, and, at
        the state x (default: the current one, retuned to p; and each of its phases, when the
        family gives ``phases``: every gain it can switch to) and the last measurement held, at
        the sample times dt_min, dt and dt_max of the declared range, the spectral radius of the
        step's Jacobian (central differences) at most that of the exact linearised flow,
        exp(h max Re eig J), J = (J(x) + J(x_next))/2 by central differences, or 1 (relative
        slack 1e-5; a Jacobian that is not finite fails). ValueError naming the gain, dt and
        method otherwise."""
        p = as_vector("p", p, self.np)
        where = f"at dt = {self.dt:g} with {self.method}"
        for gain, slots in self.gains.items():
            values = p[[self.p_names.index(s) for s in slots]]
            if np.any(values < 0):
                raise ValueError(f"{gain} = {values.max():.6g} {where}: {gain} must be >= 0")
        x0 = self._retuned(p) if x is None else x
        if x0 is None:
            return
        y = self._y_last
        u = self._prev[1] if self._prev is not None else np.zeros(self.nu)
        saved = self._p
        flow = lambda x: np.asarray(self.family.rhs(self.robot, x, y, u, p), float)  # noqa: E731
        phases = getattr(self.family, "phases", None)
        states = [x0] if phases is None else phases(self.robot, x0, y, p)
        nx = self.nx

        def step(v, h):                 # (x, memory) -> (x_next, memory_next)
            _, xn, mn = self._advance(v[:nx], (y, u), y, u, h, v[nx:])
            return np.concatenate([xn, mn])
        for h in sorted({self.dt_range[1], self.dt, self.dt_range[0]}, reverse=True):
            for phase, xs in enumerate(states):
                try:
                    self._p = p
                    # with memory: at the model's value at the held measurement
                    v = np.concatenate([xs, self.family.model(self.robot, xs, y, y, u, p) if self.nm else []])
                    with np.errstate(all="ignore"):
                        Phi = _jacobian(lambda v, h=h: step(v, h), v)
                        J = 0.5 * (_jacobian(flow, xs) + _jacobian(flow, step(v, h)[:nx]))
                finally:
                    self._p = saved
                finite = np.all(np.isfinite(Phi)) and np.all(np.isfinite(J))
                rho = np.max(np.abs(np.linalg.eigvals(Phi))) if finite else np.inf
                rho_c = max(1.0, float(np.exp(h * np.max(np.linalg.eigvals(J).real)))) if finite else 1.0
                if not rho <= rho_c * (1 + 1e-5):
                    at = "the current state" if phase == 0 else f"the current state's phase {phase}"
                    raise ValueError(f"parameters {dict(zip(self.p_names, p.tolist()))} {where}: spectral radius "
                                     f"{rho:.4g} > {rho_c:.4g} (the continuous-time observer's) at elapsed time "
                                     f"{h:g} and {at}")

    def _p_or(self, p):
        return self._p if p is None else as_vector("p", p, self.np)

    def rhs(self, x, y, u, p=None):
        """Flow xdot = rhs(x, y, u, p) of the continuous-time observer.

        Parameters
        ----------
        x : (nx,) array
        y : (ny,) array
        u : (nu,) array
        p : (np,) array, optional
            Default: the parameters of the last ``reset`` (``p_default`` before).

        Returns
        -------
        (nx,) array
        """
        return self.family.rhs(self.robot, as_vector("x", x, self.nx), as_vector("y", y, self.ny),
                               as_vector("u", u, self.nu), self._p_or(p))

    def output(self, x, y, u, p=None):
        """Estimate est = output(x, y, u, p) (nest,); arguments as in ``rhs``."""
        return self.family.output(self.robot, as_vector("x", x, self.nx), as_vector("y", y, self.ny),
                                  as_vector("u", u, self.nu), self._p_or(p))

    def jump(self, x, y, p=None):
        """Hybrid jump map x+ = jump(x, y, p) (nx,), the identity for non-hybrid families;
        arguments as in ``rhs``."""
        x = as_vector("x", x, self.nx)
        if not self.hybrid:
            return x
        return self.family.jump(self.robot, x, as_vector("y", y, self.ny), self._p_or(p))

    # ------------------------------------------------------------ discrete time
    @property
    def state(self):
        """Copy of the observer state x (None before reset)."""
        return None if self._x is None else self._x.copy()

    @state.setter
    def state(self, x):
        """Set the state to ``x`` (nx,) (ValueError naming x on a bad size or value)."""
        self._x = as_vector("x", x, self.nx)
        self._m = np.zeros(self.nm)

    def reset(self, y0, est0=None, p=None):
        """Start the observer: x = init(y0, est0, p).

        Parameters
        ----------
        y0 : (ny,) array
            First measurement.
        est0 : (nest,) array, optional
            Initial estimate (default zeros).
        p : (np,) array, optional
            Parameters used from now on (default ``p_default``).

        Returns
        -------
        (nx,) array
            A copy of the state.
        """
        y0 = as_vector("y0", y0, self.ny)
        est0 = np.zeros(self.nest) if est0 is None else as_vector("est0", est0, self.nest)
        p = self.p_default.copy() if p is None else as_vector("p", p, self.np)
        x0 = np.asarray(self.family.init(self.robot, y0, est0, p), dtype=float).reshape(self.nx)
        if not np.all(np.isfinite(x0)):
            raise FloatingPointError(f"non-finite initial state {x0}")
        self._refuse(y0, None, "y0")
        self._p, self._x, self._prev, self._y_last, self._stamp = p, x0, None, y0, None
        self._m = np.zeros(self.nm)
        self.skip, self.skipped, self.clipped, self._pending = False, 0, 0, 0.0
        return self.state

    def _outside(self, y, u):
        """(slot name, value, low, high) of the first slot of ``y`` (ny,) or ``u`` (nu,; None: not
        checked) outside the declared ranges ``limits`` (y_lower <= y <= y_upper, |u| <= u_max;
        None: a slot not checked), or None."""
        lim = self.limits
        rows = [(self.y_names, y, lim.get("y_lower"), lim.get("y_upper"), False)]
        if u is not None:
            rows.append((self.u_names, u, None, lim.get("u_max"), True))
        for names, v, lows, highs, symmetric in rows:
            for i, value in enumerate(v):
                high = np.inf if not highs or highs[i] is None else highs[i]
                low = -high if symmetric else (-np.inf if not lows or lows[i] is None else lows[i])
                if not low <= value <= high:
                    return names[i], float(value), low, high
        return None

    def _refuse(self, y, u, what="sample"):
        """ValueError naming the slot of ``y`` (ny,) or ``u`` (nu,; None: not checked) outside the
        declared ranges (the C's ERR_OUT_OF_RANGE), nothing when both are inside."""
        bad = self._outside(y, u)
        if bad is not None:
            name, value, lo, hi = bad
            raise ValueError(f"{what}: {name} = {value:.6g} outside [{lo:.6g}, {hi:.6g}], the declared range "
                             f"(ERR_OUT_OF_RANGE)")

    def _accepted(self, y, u, prev, what="sample"):
        """(y, u, skipped): the sample as stepped: itself when inside the declared ranges; else, in
        the skip mode after the first sample (``prev`` the last accepted (y, u)), that one held
        (the C's SKIPPED); else ValueError (``_refuse``)."""
        if self._outside(y, u) is None:
            return y, u, False
        if self.skip and prev is not None:
            return prev[0], prev[1], True
        self._refuse(y, u, what)

    def _at_bound(self, est):
        """1 when a velocity estimate of ``est`` lies beyond the model's velocity bound (the C's
        clip counter), else 0."""
        if self._v is None:
            return 0
        slots, bound = self._v
        return int(np.any(np.abs(est[slots]) > bound))

    def _sample(self, x, prev, mem, pending, y, u, h, what="sample"):
        """(est, x_next, memory_next, pending_next, skipped) of one sample as the C's step_dt takes it
        (``_accepted``): a skipped sample under the first-order hold leaves x and the memory at the
        last accepted sample, its estimate integrates the time since (``pending`` + h, y held), and
        the next accepted one integrates all of it; otherwise (zero-order hold: the held sample
        stepped) the step of the elapsed time ``h`` (+ ``pending``, first-order)."""
        y, u, skipped = self._accepted(y, u, prev, what)
        total = h + pending if self.hold == "foh" else h
        if not total <= self.dt_limit:
            raise ValueError(f"{what}: {total:g} s since the last accepted sample, more than {self.dt_limit:g} s "
                             f"(split_max x dt_max)")
        if skipped and self.hold == "foh":
            return self._advance(x, prev, y, u, total, mem)[0], x, mem, pending + h, True
        est, x, mem = self._advance(x, prev, y, u, total, mem)
        return est, x, mem, 0.0, skipped

    def _flow(self, x, y_of_t, u, dt, m, midpoint=False):
        """(x, m) advanced over dt with y = y_of_t(t) and u held; ``midpoint`` (first-order hold
        of a family with ``rhs_split``): its model at y of each sub-step's midpoint, the rest at
        y(t); expmid and expmid1 (a family with its model part apart): at y of each sub-step's
        midpoint always, expmid1 with the model's last value m in its predictor (m returned as it
        came by the other methods)."""
        p, robot, family = self._p, self.robot, self.family
        rate = family.rate(robot, x, p) if self._mask is not None else None
        if self.method in ("expmid", "expmid1") and self.model_split:   # the model at each sub-step's midpoint
            x, mem = discretize.integrate_expmid(
                lambda t, xi, mi: family.rhs_model(robot, xi, y_of_t(t), u, p, mi),
                lambda tm, t, xi: family.model(robot, xi, y_of_t(tm), y_of_t(t), u, p),
                x, dt, self.substeps, rate, self._mask, memory=m if self.nm else None,
                correction=self.correction)
            return x, (m if mem is None else mem)
        method = "etdrk4" if self.method in ("expmid", "expmid1") else self.method   # without a model part
        if midpoint and self.split:
            return discretize.integrate(
                lambda t, xi, tm: family.rhs_split(robot, xi, y_of_t(tm), y_of_t(t), u, p),
                x, dt, method, self.substeps, rate, self._mask, midpoint=True), m
        return discretize.integrate(lambda t, xi: family.rhs(robot, xi, y_of_t(t), u, p),
                                    x, dt, method, self.substeps, rate, self._mask), m

    def _jumped(self, x, y):
        """x after the jump map at measurement y (the identity for non-hybrid families)."""
        return self.family.jump(self.robot, x, y, self._p) if self.hybrid else x

    def _advance(self, x, prev, y, u, dt=None, memory=None):
        """(est, x_next, memory_next) for one sample from state x and the step's memory (expmid1:
        the model's last value; default the current one) after the elapsed time ``dt`` (s,
        default the designed dt; first-order hold: since the last sample ``prev`` = (y, u),
        nothing to integrate when it is None, the memory then the model at (x, y, u); zero-order
        hold: to the next sample), in m = ceil(dt / dt_max) equal sub-intervals h, each ending
        at a virtual sample with its jump (module docstring); raises on a non-finite result."""
        p, dt = self._p, self.dt if dt is None else dt
        mem = self._m if memory is None else memory
        m = split_count(dt, self.dt_range[1])
        h = dt / m
        if self.hold == "foh":
            if prev is not None:
                yp, up = prev
                ya = yp
                for j in range(1, m + 1):       # y linear from yp to y, the last input held
                    yb = y if j == m else yp + (j / m) * (y - yp)
                    x, mem = self._flow(x, lambda t, a=ya, b=yb: a + (t / h) * (b - a), up, h, mem, midpoint=True)
                    if j < m:
                        x = self._jumped(x, yb)
                    ya = yb
            elif self.nm:
                mem = np.asarray(self.family.model(self.robot, x, y, y, u, p), dtype=float).reshape(self.nm)
            x = self._jumped(x, y)
            est = np.asarray(self.family.output(self.robot, x, y, u, p), dtype=float).reshape(self.nest)
            x_next = x
        else:                                   # y and u held over the interval after the sample
            x = self._jumped(x, y)
            est = np.asarray(self.family.output(self.robot, x, y, u, p), dtype=float).reshape(self.nest)
            x_next, mem = self._flow(x, lambda t: y, u, h, mem)
            for _ in range(m - 1):
                x_next, mem = self._flow(self._jumped(x_next, y), lambda t: y, u, h, mem)
        if not (np.all(np.isfinite(est)) and np.all(np.isfinite(x_next)) and np.all(np.isfinite(mem))):
            raise FloatingPointError(f"non-finite result (est={est}, x={x_next}); state unchanged")
        return est, x_next, np.asarray(mem, dtype=float).reshape(self.nm)

    def _elapsed(self, dt):
        """The elapsed time ``dt`` (s) of a step: positive, finite, at most ``dt_limit``; None: dt."""
        if dt is None:
            return self.dt
        h = positive("dt", dt)
        if h > self.dt_limit:
            raise ValueError(f"dt must be at most {self.dt_limit:g} s (split_max x dt_max), got {dt!r}")
        return h

    def _require_reset(self):
        if self._x is None:
            raise RuntimeError("call reset(y0, est0=None, p=None) before step/run")

    def step(self, y, u, dt=None):
        """One sample: est from the current state (after the first-order-hold interval and
        the jump map, if any), then x advances over dt (zero-order hold).

        Parameters
        ----------
        y : (ny,) array
        u : (nu,) array
        dt : float, optional
            The elapsed time (s): first-order hold, since the last sample (unused on the first
            after reset); zero-order hold, to the next sample. Default: the designed dt.

        Returns
        -------
        (nest,) array
        """
        self._require_reset()
        h = self._elapsed(dt)
        y = as_vector("y", y, self.ny)
        u = as_vector("u", u, self.nu)
        est, self._x, self._m, self._pending, skipped = self._sample(self._x, self._prev, self._m, self._pending,
                                                                     y, u, h)
        if self._prev is not None and self._stamp is not None:
            self._stamp += h
        if not skipped:
            self._prev, self._y_last = (y, u), y
        self.skipped += skipped
        self.clipped += self._at_bound(est)
        return est

    def estimate(self, y, u, dt=None):
        """The estimate (nest,) ``step(y, u, dt)`` would return, without advancing the state."""
        self._require_reset()
        h = self._elapsed(dt)
        y, u = as_vector("y", y, self.ny), as_vector("u", u, self.nu)
        return self._sample(self._x, self._prev, self._m, self._pending, y, u, h)[0]

    def run(self, Y, U, t=None):
        """Repeated ``step``, all-or-nothing: on an error the state is left unchanged.

        Parameters
        ----------
        Y : (N, ny) array
        U : (N, nu) array
        t : (N,) array, optional
            Time stamps (s, increasing). First-order hold: the step before sample k covers
            t[k] - t[k-1], before sample 0 the time since the last sample's stamp (the last
            stamp of a previous ``run(..., t)`` plus the dt of the steps since; nothing right
            after ``reset``; ValueError when the last sample has no stamp). Zero-order hold: the
            step after sample k covers t[k+1] - t[k], after the last one dt. An interval equal to
            dt up to its stamps' rounding (codegen.core.target.interval) is dt.
            Default: the samples dt apart.

        Returns
        -------
        (N, nest) array
        """
        self._require_reset()
        Y = as_matrix("Y", Y, self.ny)
        U = as_matrix("U", U, self.nu, rows=Y.shape[0])
        N = Y.shape[0]
        H = np.full(N, self.dt)
        if t is not None:
            t = time_stamps("t", t, N)
            if self.hold == "foh":
                for k in range(N):
                    if k > 0:
                        H[k] = interval(t[k - 1], t[k], self.dt)
                    elif self._prev is not None:
                        if self._stamp is None:
                            raise ValueError("t: the observer's last sample has no time stamp (stepped "
                                             "without one since reset): reset it, or step it with dt")
                        H[0] = interval(self._stamp, t[0], self.dt)
            else:
                H[:-1] = [interval(a, b, self.dt) for a, b in itertools.pairwise(t)]
            bad = np.flatnonzero(~((H > 0) & (H <= self.dt_limit)))
            if len(bad):
                raise ValueError(f"t: the interval of sample {int(bad[0])} is {H[bad[0]]:g} s, expected "
                                 f"0 < interval <= {self.dt_limit:g} s (split_max x dt_max)")
        x, prev, stamp, mem, pending = self._x, self._prev, self._stamp, self._m, self._pending
        EST = np.empty((N, self.nest))
        skipped = clipped = 0
        for k in range(N):
            EST[k], x, mem, pending, skip = self._sample(x, prev, mem, pending, Y[k], U[k], float(H[k]), f"sample {k}")
            if prev is not None and stamp is not None:
                stamp += H[k]
            if not skip:
                prev = (Y[k], U[k])
            if t is not None:
                stamp = float(t[k])
            skipped, clipped = skipped + skip, clipped + self._at_bound(EST[k])
        self._x, self._prev, self._stamp, self._m, self._pending = x, prev, stamp, mem, pending
        self.skipped, self.clipped = self.skipped + skipped, self.clipped + clipped
        if len(Y):
            self._y_last = prev[0]
        return EST
