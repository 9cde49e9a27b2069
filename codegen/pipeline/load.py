"""ctypes loader: CompiledObserver with step() and run(), the loop of run() in C.

Buffers are preallocated once; ``step`` copies y and u into them and calls the C step
(``step(y, u, dt)``: the C's step_dt with the elapsed time dt; ``run(Y, U, t)``: its run_t over
time stamps). Bad input (shape, NaN/Inf, dt <= 0, stamps that do not increase) raises before
reaching C; a non-zero C status raises ObserverError naming the status. A single-precision target (metadata "precision": "float")
gets float32 buffers: inputs are rounded to float32 at the boundary (a value beyond float32's
range is refused), results come back as float64 arrays.

Before any buffer is passed, the library is checked against its build record
(``codegen.pipeline.compile.verify``) and the metadata's sizes against the library's own
(``<prefix>_sizes``, ``check_sizes``): metadata of another build is refused, never trusted.
"""
from __future__ import annotations

import ctypes as ct
import json
from pathlib import Path

import numpy as np

from ..core.arrays import as_matrix, as_vector, positive, time_stamps
from .compile import MANIFEST, verify

REALS = {"double": (np.float64, ct.c_double), "float": (np.float32, ct.c_float)}  # precision -> types


class ObserverError(RuntimeError):
    """A C function returned a non-zero status; the observer state is as it was before the call
    (a failing run() is rolled back to its start)."""


class OutOfRange(ObserverError, ValueError):
    """A sample outside the declared ranges of the target's inputs (status ERR_OUT_OF_RANGE; the
    message names the slot, its value and the range); the state is as it was."""


class LibraryMismatch(ValueError):
    """The metadata does not describe the library (its sizes or prefix differ from the library's
    own): no buffer is passed to it."""


SIZES = ("nx", "ny", "nu", "np", "nest")      # the order of <prefix>_sizes(n)


def library_sizes(lib, prefix, lib_path=""):
    """{"nx", "ny", "nu", "np", "nest"} as the library ``lib`` (a ctypes.CDLL) reports them through
    its ``<prefix>_sizes(long n[5])``; LibraryMismatch, naming the file ``lib_path``, when it has
    no such function."""
    try:
        fn = getattr(lib, f"{prefix}_sizes")
    except AttributeError:
        raise LibraryMismatch(f"{lib_path}: exports no {prefix}_sizes: not the library of observer {prefix!r} "
                              "(or built by an older codegen); compile_library() rebuilds it") from None
    fn.argtypes, fn.restype = [ct.POINTER(ct.c_long)], ct.c_int
    n = (ct.c_long * len(SIZES))()
    if fn(n) != 0:
        raise LibraryMismatch(f"{lib_path}: {prefix}_sizes failed")
    return dict(zip(SIZES, n))


def check_sizes(lib, prefix, sizes, lib_path=""):
    """LibraryMismatch (one line, naming the file ``lib_path``) unless the metadata's ``sizes``
    (dict) equal the library's own (``library_sizes`` of ``lib``, a ctypes.CDLL, for the symbol
    ``prefix``): buffers sized from the metadata are only passed to the library they fit."""
    own = library_sizes(lib, prefix, lib_path)
    bad = [f"{k} = {sizes.get(k)!r} (library: {v})" for k, v in own.items()
           if not (type(sizes.get(k)) is int and sizes.get(k) == v)]
    if bad:
        raise LibraryMismatch(f"{lib_path}: the metadata's sizes differ from the library's own: {', '.join(bad)}; "
                              "load it with the metadata it was built from (codegen.pipeline.load.load), or "
                              "regenerate and rebuild")


class CompiledObserver:
    """A generated observer loaded from its shared library.

    ``obs.reset(y0, est0=None, p=None)``, ``obs.step(y, u, dt=None) -> est``,
    ``obs.run(Y, U, t=None) -> EST``, ``obs.rhs(x, y, u)``; ``obs.state``, ``obs.params``;
    ``obs.meta`` is the target's metadata. ``dt`` (s) is the elapsed time of a jittered loop
    (default: the designed ``obs.dt``), ``t`` the time stamps of a jittered log (see ``run``).

    New parameters (``obs.params = p``, ``reset(..., p=p)``) are checked for discrete stability
    by the full check (codegen.discrete.stability: all gains jointly, in the target's precision)
    on ``obs.spec`` (``compile_observer`` attaches it) or, without it, on the spec rebuilt from the
    metadata's target; one gain moved alone is checked against its recorded bound (>= 0 and
    below its largest stable value, which holds with the others at their defaults). Setting them is
    bumpless: the C transforms the state so that the estimate at the last measurement is kept.
    Results are float64 arrays whatever the target's precision (``obs.dtype`` is the C's).
    """

    spec = None
    _rebuilt = None        # the spec rebuilt from the metadata (check_params), when needed

    def __init__(self, lib_path, meta):
        self.lib_path = Path(lib_path).resolve()
        self.meta = meta if isinstance(meta, dict) else json.loads(Path(meta).read_text())
        self.prefix = self.meta["prefix"]
        s = self.meta["sizes"]
        self.nx, self.ny, self.nu, self.np, self.nest = s["nx"], s["ny"], s["nu"], s["np"], s["nest"]
        d = self.meta["discretization"]
        self.dt = d["dt"]
        self.foh = d["hold"] == "foh"
        # the longest elapsed time one step_dt takes (longer: ERR_BAD_ARG); older metadata: DT
        self.dt_range = (d.get("dt_min", self.dt), d.get("dt_max", self.dt))
        self.dt_limit = d.get("split_max", 1) * self.dt_range[1]
        self.status_names = {v: k for k, v in self.meta["status"].items()}
        self.precision = self.meta.get("precision", "double")
        self.dtype, ctype = REALS[self.precision]
        R = ct.POINTER(ctype)
        self._R = R
        lib = ct.CDLL(str(verify(self.lib_path)))  # absolute path: never LD_LIBRARY_PATH
        check_sizes(lib, self.prefix, s, self.lib_path)   # before any buffer is passed
        f = lambda name: getattr(lib, f"{self.prefix}_{name}")  # noqa: E731
        self._lib = lib
        self._state_size = f("state_size")
        self._state_size.restype = ct.c_long
        self._init, self._step, self._run, self._rhs = f("init"), f("step"), f("run"), f("rhs")
        self._estimate = f("estimate")
        self._estimate.argtypes = [ct.c_void_p, R, R, R]
        self._step_dt, self._estimate_dt, self._run_t = f("step_dt"), f("estimate_dt"), f("run_t")
        for g in (self._step_dt, self._estimate_dt):
            g.argtypes = [ct.c_void_p, ctype, R, R, R]
        self._run_t.argtypes = [ct.c_void_p, ct.c_long, R, R, R, R, ct.POINTER(ct.c_long)]
        self._ctype = ctype
        self._set_params, self._get_state, self._set_state = f("set_params"), f("get_state"), f("set_state")
        self._get_params = f("get_params")
        self._init.argtypes = [ct.c_void_p, R, R, R]
        self._step.argtypes = [ct.c_void_p, R, R, R]
        self._run.argtypes = [ct.c_void_p, ct.c_long, R, R, R, ct.POINTER(ct.c_long)]
        self._rhs.argtypes = [ct.c_void_p, R, R, R, R]
        for g in (self._set_params, self._get_params, self._get_state, self._set_state):
            g.argtypes = [ct.c_void_p, R]
        self._default_params = f("default_params")
        self._default_params.argtypes = [R]
        self._default_params.restype = None
        self._set_skip, self._counters = f("set_skip"), f("counters")
        self._set_skip.argtypes = [ct.c_void_p, ct.c_int]
        self._counters.argtypes = [ct.c_void_p, ct.POINTER(ct.c_ulong)]
        self.limits = self.meta.get("limits") or {}
        self._ok = {0, self.meta["status"].get("SKIPPED", 0)}    # SKIPPED: predicted through, no error
        # preallocated buffers
        self._s = ct.create_string_buffer(self._state_size())
        self._buf = {k: np.zeros(max(1, m), self.dtype) for k, m in
                     (("y", self.ny), ("u", self.nu), ("est", self.nest), ("x", self.nx),
                      ("xdot", self.nx), ("p", self.np))}
        self._ptr = {k: v.ctypes.data_as(R) for k, v in self._buf.items()}
        self._default_params(self._ptr["p"])
        self.p_default = self._out("p", self.np)
        lo, hi = (self.limits.get(k) or [None] * self.ny for k in ("y_lower", "y_upper"))
        self.reset([min(max(0.0, -np.inf if a is None else a), np.inf if b is None else b)
                    for a, b in zip(lo, hi)])     # 0 clamped into the declared ranges

    # -------------------------------------------------------------- helpers
    def _check(self, status, what, y=None, u=None):
        if status in self._ok:
            return
        name = self.status_names.get(status, "unknown")
        if name == "ERR_OUT_OF_RANGE":
            raise OutOfRange(f"{self.prefix}_{what} returned {status} ({name}: "
                             f"{self.range_error(y, u)}); state unchanged")
        raise ObserverError(f"{self.prefix}_{what} returned {status} ({name}); state unchanged")

    def range_error(self, y=None, u=None):
        """Which slot of the sample ``y`` (ny,), ``u`` (nu,) lies outside the declared ranges
        (``obs.limits``, codegen.core.limits): "<slot> = <value> outside [low, high]", or ""."""
        from ..core.limits import out_of_range
        bad = out_of_range(self.limits, y, u)
        if bad is None:
            return ""
        kind, i, value, (lo, hi) = bad
        name = self.meta["names"][kind][i]
        return f"{name} = {value:.6g} outside [{lo:.6g}, {hi:.6g}], its declared range"

    @property
    def skip(self):
        """The skip mode (bool): a sample out of the declared ranges (or not finite) is predicted
        through with the last accepted one held, not refused (the C's set_skip; off after reset)."""
        return bool(self._skip)

    @skip.setter
    def skip(self, on):
        """Turn the skip mode on or off (``on`` a bool)."""
        self._check(self._set_skip(self._s, int(bool(on))), "set_skip")
        self._skip = bool(on)

    @property
    def counters(self):
        """{"clipped": steps whose velocity estimate ended beyond the model's velocity bound,
        "skipped": samples skipped} since the last reset (the C's counters)."""
        c = (ct.c_ulong * 2)()
        self._check(self._counters(self._s, c), "counters")
        return {"clipped": int(c[0]), "skipped": int(c[1])}

    @property
    def clipped(self):
        """Steps since reset whose velocity estimate ended beyond the model's velocity bound."""
        return self.counters["clipped"]

    @property
    def skipped(self):
        """Samples skipped since reset (skip mode)."""
        return self.counters["skipped"]

    def _load(self, key, name, value, size):
        self._buf[key][:size] = as_vector(name, value, size, self.dtype)
        return self._ptr[key]

    def _out(self, key, size):
        """A float64 copy of the first ``size`` entries of buffer ``key``."""
        return self._buf[key][:size].astype(np.float64)

    # -------------------------------------------------------------- API
    def reset(self, y0, est0=None, p=None):
        """Initialise from the first measurement y0 (ny,) and an initial estimate est0 (nest,)
        (default zeros), with parameters ``p`` (np,) (default p_default; checked by
        :meth:`check_params`)."""
        y0 = as_vector("y0", y0, self.ny, self.dtype)
        est0 = as_vector("est0", np.zeros(self.nest) if est0 is None else est0, self.nest, self.dtype)
        p = as_vector("p", self.p_default if p is None else self.check_params(p), self.np, self.dtype)
        arr = [np.ascontiguousarray(a) for a in (p, y0, est0)]
        self._check(self._init(self._s, *(a.ctypes.data_as(self._R) for a in arr)), "init", y=y0)
        self._primed, self._stamp, self._skip = False, None, False   # as the C state's primed, stamped/t_last, skip

    def _elapsed(self, dt):
        """dt (s) as the C's real: positive, finite and at most ``dt_limit``, or ValueError."""
        if dt is None:
            return None
        value = positive("dt", dt)
        if value > self.dt_limit:
            raise ValueError(f"dt must be at most {self.dt_limit:g} s (split_max x dt_max), got {dt!r}: "
                             f"after an outage that long, reset the observer")
        return self.dtype(value)

    def _stepped(self, dt):
        """Keep the time stamp of the last sample as the C does after a step of ``dt`` (s)."""
        if self._primed and self._stamp is not None:
            self._stamp += float(dt)
        self._primed = True

    def step(self, y, u, dt=None):
        """Estimate at this sample from measurement y (ny,) and input u (nu,).

        ``dt`` (s): the elapsed time (first-order hold: since the last sample; zero-order hold:
        to the next one), default the designed ``obs.dt``; above dt_max it is integrated in
        ceil(dt / dt_max) sub-intervals (the C's step_dt)."""
        h = self._elapsed(dt)
        yp = self._load("y", "y", y, self.ny)
        up = self._load("u", "u", u, self.nu)
        if h is None:
            self._check(self._step(self._s, yp, up, self._ptr["est"]), "step", y, u)
        else:
            self._check(self._step_dt(self._s, h, yp, up, self._ptr["est"]), "step_dt", y, u)
        self._stepped(self.dt if h is None else h)
        return self._out("est", self.nest)

    def estimate(self, y, u, dt=None):
        """The estimate step(y, u, dt) would return, without advancing the state."""
        h = self._elapsed(dt)
        yp = self._load("y", "y", y, self.ny)
        up = self._load("u", "u", u, self.nu)
        if h is None:
            self._check(self._estimate(self._s, yp, up, self._ptr["est"]), "estimate", y, u)
        else:
            self._check(self._estimate_dt(self._s, h, yp, up, self._ptr["est"]), "estimate_dt", y, u)
        return self._out("est", self.nest)

    def bind(self, y, u, est):
        """Zero-copy calls on caller-owned C-contiguous buffers of ``obs.dtype`` (simulation loops):
        ``y`` (>= ny), ``u`` (>= nu) and ``est`` (>= nest) entries (at least one each).

        Returns (step, estimate): functions of no argument that run the C on the buffers' current
        contents, write into ``est`` and raise ObserverError on a non-zero status. Python checks
        nothing (the C still rejects non-finite input); keep the buffers alive while bound."""
        for name, a, size in (("y", y, self.ny), ("u", u, self.nu), ("est", est, self.nest)):
            if not (isinstance(a, np.ndarray) and a.dtype == self.dtype and a.flags.c_contiguous
                    and a.size >= max(1, size)):
                raise ValueError(f"{name}: need a C-contiguous {np.dtype(self.dtype).name} array of at "
                                 f"least {max(1, size)} entries")
        args = (self._s, *(a.ctypes.data_as(self._R) for a in (y, u, est)))
        c_step, c_est, check = self._step, self._estimate, self._check

        def step():
            st = c_step(*args)
            if st:
                check(st, "step", y[:self.ny], u[:self.nu])

        def estimate():
            st = c_est(*args)
            if st:
                check(st, "estimate", y[:self.ny], u[:self.nu])
        return step, estimate

    def c_step(self, y, u, dt=None):
        """The raw C step (``dt`` given: step_dt with that elapsed time, any float) on measurement
        ``y`` (ny,) and input ``u`` (nu,), no Python-side checks: returns (status, est). For tests
        of the C."""
        self._buf["y"][: self.ny] = np.asarray(y, float).reshape(-1)[: self.ny]
        self._buf["u"][: self.nu] = np.asarray(u, float).reshape(-1)[: self.nu]
        if dt is None:
            st = self._step(self._s, self._ptr["y"], self._ptr["u"], self._ptr["est"])
        else:
            with np.errstate(over="ignore"):
                h = self.dtype(dt)
            st = self._step_dt(self._s, h, self._ptr["y"], self._ptr["u"], self._ptr["est"])
        if st in self._ok:
            self._stepped(self.dt if dt is None else dt)
        return st, self._out("est", self.nest)

    def c_set_params(self, p):
        """The raw C set_params with ``p`` (np,), no stability check (a step that is not
        finite, to see the C's status): for tests of the C."""
        self._check(self._set_params(self._s, self._load("p", "p", p, self.np)), "set_params")

    def run(self, Y, U, t=None):
        """Many samples at once (rows of Y, U); the loop runs in C. Returns EST (N, nest).

        ``t`` (N,): the samples' time stamps (s, increasing; the C's run_t): first-order hold,
        the step before sample k covers t[k] - t[k-1], and before sample 0 the time since the
        last sample of the previous ``run(..., t)`` (plus the ``dt`` of steps since; right after
        ``reset`` nothing); zero-order hold, the step after sample k covers t[k+1] - t[k] (after
        the last, dt). An interval equal to dt up to its stamps' rounding is dt, so uniform
        stamps give ``run(Y, U)``'s estimates bit for bit. Default: the samples dt apart.

        On a non-zero status at sample k, ObserverError names k (OutOfRange also the slot and
        the range), and the C has rolled the state back to what it was before the call. In the
        skip mode (``obs.skip = True``) a sample out of range is predicted through instead
        (``obs.skipped`` counts them)."""
        Y = as_matrix("Y", Y, self.ny, dtype=self.dtype)
        U = as_matrix("U", U, self.nu, rows=len(Y), dtype=self.dtype)
        if t is not None:
            t = self._stamps(t, len(Y))
        EST = np.empty((len(Y), self.nest), self.dtype)
        done = ct.c_long(0)
        arrays = (Y, U, EST) if t is None else (t, Y, U, EST)
        st = (self._run if t is None else self._run_t)(self._s, len(Y), *(a.ctypes.data_as(self._R) for a in arrays),
                                                      ct.byref(done))
        if st not in self._ok:
            name = self.status_names.get(st, "unknown")
            k = done.value
            where = (f": {self.range_error(Y[k], U[k] if self.nu else None)}"
                     if name == "ERR_OUT_OF_RANGE" and k < len(Y) else "")
            raise (OutOfRange if where else ObserverError)(
                f"{self.prefix}_{'run' if t is None else 'run_t'} stopped at sample {k} with status {st} "
                f"({name}{where}); state rolled back to before the run")
        if len(Y):
            if t is not None:
                self._stamp = float(t[-1])
            elif self._stamp is not None:
                self._stamp += self.dt * (len(Y) - (0 if self._primed else 1))
            self._primed = True
        return EST.astype(np.float64, copy=False)

    def _stamps(self, t, rows):
        """The time stamps ``t`` of a run of ``rows`` samples as the C's reals, checked (module
        docstring): increasing, intervals (and the one before t[0]) at most ``dt_limit``."""
        t = np.ascontiguousarray(time_stamps("t", t, rows, self.dtype))
        gaps = np.diff(t.astype(float))
        if self.foh and self._primed and rows:
            if self._stamp is None:
                raise ValueError("t: the observer's last sample has no time stamp (it was stepped "
                                 "without one since reset): reset it, or step it with dt")
            gaps = np.concatenate([[float(t[0]) - self._stamp], gaps])
            if gaps[0] <= 0:
                raise ValueError(f"t: t[0] = {float(t[0])!r} is not after the last sample's stamp "
                                 f"{self._stamp!r}")
        if np.any(gaps > self.dt_limit):
            raise ValueError(f"t: an interval of {gaps.max():g} s is longer than {self.dt_limit:g} s "
                             f"(split_max x dt_max): reset the observer after an outage that long")
        return t

    def rhs(self, x, y, u):
        """Continuous-time right-hand side xdot (nx,) at state ``x`` (nx,), measurement ``y`` (ny,) and
        input ``u`` (nu,), with the current parameters."""
        xp = self._load("x", "x", x, self.nx)
        yp = self._load("y", "y", y, self.ny)
        up = self._load("u", "u", u, self.nu)
        self._check(self._rhs(self._s, xp, yp, up, self._ptr["xdot"]), "rhs")
        return self._out("xdot", self.nx)

    @property
    def state(self):
        """The observer state (nx,) (a float64 copy)."""
        self._check(self._get_state(self._s, self._ptr["x"]), "get_state")
        return self._out("x", self.nx)

    @state.setter
    def state(self, x):
        """Set the observer state to ``x`` (nx,) (finite)."""
        self._check(self._set_state(self._s, self._load("x", "x", x, self.nx)), "set_state")

    @property
    def params(self):
        """The runtime parameters (np,) in the order of ``meta["names"]["p"]``."""
        self._check(self._get_params(self._s, self._ptr["p"]), "get_params")
        return self._out("p", self.np)

    @params.setter
    def params(self, p):
        """Set the runtime parameters to ``p`` (np,), checked by :meth:`check_params` (bumpless)."""
        p = self.check_params(p)
        self._check(self._set_params(self._s, self._load("p", "p", p, self.np)), "set_params")

    def check_params(self, p, explain=True):
        """p as a finite vector, refused (codegen.discrete.stability.UnstableDiscretization, a ValueError)
        when the discrete observer would be unstable with it (see the class docstring); ``explain``
        False: a full check's refusal without the stable ranges of the gains (their search is most
        of a refusal's cost: a tuning that only needs the verdict).

        The full check (all gains jointly, every phase, the target's precision) runs on
        ``obs.spec``, or on the spec rebuilt from the metadata's target when p moves more than
        one gain or any other parameter from its default; p moving one gain alone is checked
        against that gain's recorded bound, which holds with the others at their defaults."""
        from ..discrete.stability import UnstableDiscretization, require_stable
        from ..core.target import FIELDS, Discretization
        p = as_vector("p", p, self.np)
        disc = Discretization.from_dict({k: v for k, v in self.meta["discretization"].items() if k in FIELDS})
        spec = self.spec
        names = self.meta["names"]["p"]
        recorded = (self.meta.get("stability") or {}).get("gains") or {}
        groups = {g: [names.index(s) for s in v["slots"]] for g, v in recorded.items()}
        defaults = np.asarray(self.meta["p_default"], dtype=float)
        moved = [g for g, idx in groups.items() if not np.array_equal(p[idx], defaults[idx])]
        others = np.setdiff1d(np.arange(self.np), [i for idx in groups.values() for i in idx])
        if spec is None and (len(moved) > 1 or not np.array_equal(p[others], defaults[others])):
            spec = self._checked_spec(p)
        if spec is not None:
            require_stable(spec, disc, p, precision=self.precision, bounds=False, explain=explain)
            return p
        for gain, g in recorded.items():
            idx = groups[gain]
            value = float(np.max(p[idx]))
            top = g["max_stable"] if g["limit_found"] else None
            if np.any(p[idx] < 0) or (top is not None and value > top):
                raise UnstableDiscretization(
                    f"{self.prefix}: {gain} = {value:.6g} at dt = {disc.dt:g} with {disc.method}: outside the "
                    f"recorded stable range 0 <= {gain} <= {top if top is not None else 'inf'} (the other "
                    f"parameters at their defaults)")
        return p

    @property
    def design(self):
        """The design report the target was built with (a DesignReport: prints as text)."""
        from ..core.spec import DesignReport
        return DesignReport(self.meta.get("design") or {})

    def _checked_spec(self, p):
        """The spec rebuilt from the metadata's target (its parameters applied), kept for the
        next check; ValueError naming p and the fix when it cannot be rebuilt."""
        if getattr(self, "_rebuilt", None) is None:
            from ..core.target import Target
            from .emit import with_params
            from .targets_file import build_spec
            try:
                target = Target.from_dict(self.meta["target"])
                spec = with_params(build_spec(target), target.params, target.sources, target.build)
            except Exception as e:      # any failure to rebuild: refuse, naming it
                raise ValueError(
                    f"{self.prefix}: p = {p.tolist()} moves more than one gain (or a parameter that is not a "
                    f"gain), which the recorded one-gain-at-a-time bounds cannot check, and the spec to check "
                    f"them jointly could not be rebuilt from the metadata ({type(e).__name__}: {e}); attach it: "
                    f"obs.spec = codegen.build_spec(target)") from None
            if spec.p_names != self.meta["names"]["p"] or spec.x_names != self.meta["names"]["x"]:
                raise ValueError(f"{self.prefix}: the spec rebuilt from the metadata has other slots than the "
                                 f"library; attach the one it was built from: obs.spec = ...")
            self._rebuilt = spec
        return self._rebuilt

    def __repr__(self):
        return f"<CompiledObserver {self.prefix} nx={self.nx} dt={self.dt} {self.precision}>"


def load(target_dir, lib_path=None):
    """CompiledObserver from the generated folder ``target_dir`` (e.g. ``generated/ur5_reduced_order``
    written by ``build`` or ``generate``) and its built library ``lib_path``, with the metadata beside
    the library (in the cache: kept by ``codegen.pipeline.compile.compile_library`` and checked against
    its build record), else the folder's; either is checked against the library's sizes.
    ``lib_path`` None: the folder's library from the compile cache (compiled now if the cache does
    not hold it)."""
    if lib_path is None:
        from .compile import compile_library
        lib_path = compile_library(target_dir)
    lib_path = Path(lib_path)
    meta = lib_path.parent / f"{lib_path.stem.removeprefix('lib')}.json"
    if meta.is_file():
        if (meta.parent / MANIFEST).exists():     # a cache folder: as recorded at build
            verify(meta)
    else:
        meta = next(iter(sorted(Path(target_dir).glob("*.json"))))
    return CompiledObserver(lib_path, json.loads(meta.read_text()))
