"""What to build and how: the ``Target`` value (docs/architecture.md §3) and its ``Discretization``.

Plain data (no CasADi, no symbolic code): a targets file, the CLI and Python calls are parsed
into a Target; ``emit`` receives it and records it in the metadata JSON; the independent
reference rebuilds its discretisation from it. The default discretisation is defined once,
here (``DEFAULT_DISCRETIZATION``).
"""
from __future__ import annotations

import json
import math
import numbers
import re
from dataclasses import asdict, dataclass, field, replace

METHODS = ("euler", "rk4", "etdrk4", "expmid", "expmid1")
AUTO = "auto"          # substeps: the fewest that make the discrete observer stable
HOLDS = ("zoh", "foh")
PRECISIONS = ("double", "float")
# C type of each precision (the typedef <prefix>_real of the generated header)
REAL_TYPES = {"double": "double", "float": "float"}


# the default range of the elapsed time between samples, in units of dt (Discretization.dt_range)
DT_MIN_FACTOR = 0.25
DT_MAX_FACTOR = 2.0
# the contract of the elapsed-time step (the generated C's step_dt and run_t, and the reference):
# an elapsed time above dt_max is integrated in m = ceil(elapsed / dt_max) <= SPLIT_MAX equal
# sub-intervals (longer: refused; 1000 is 2 s of outage at the 1 kHz default range), and an
# interval between two time stamps within STAMP_ULPS eps max(|t_k-1|, |t_k|) of dt is dt (the
# stamps' own rounding: k dt rounded to the nearest real is off by half an ulp, a difference of
# two such stamps by about one ulp), eps that of the real type
SPLIT_MAX = 1000
STAMP_ULPS = 4
# the most sub-steps of one sample, given or found by "auto" (codegen.discrete.stability.auto_substeps):
# every sub-step is unrolled into the C of the step, so its size and compile time grow with them
# (seed000_2r reduced_order: 16 sub-steps 0.15 MB of kernels built in 16 s, 64 0.87 MB in 84 s,
# 256 still compiling after 11 min); the stiffest default (xarm7's wrist) needs 19. An observer
# that needs more wants a smaller dt (or the etdrk4 method, exact on its linear gain term).
SUBSTEPS_MAX = 64


def split_count(elapsed, dt_max):
    """m = ceil(elapsed / dt_max) as the generated C computes it (1 when elapsed <= dt_max):
    the number of equal sub-intervals one step integrates ``elapsed`` (s) in."""
    if not elapsed > dt_max:
        return 1
    m = int(elapsed / dt_max)
    return m + 1 if m * dt_max < elapsed else m


def interval(a, b, dt, eps=2.0 ** -52):
    """b - a (s) between the time stamps a and b, or ``dt`` when it is dt up to their rounding
    (|b - a - dt| <= STAMP_ULPS eps max(|a|, |b|), ``eps`` that of the real type; b - a itself when
    it is not finite)."""
    h = b - a
    return dt if math.isfinite(h) and abs(h - dt) <= STAMP_ULPS * eps * max(abs(a), abs(b)) else h


def _seconds(name, value):
    """``value`` as a positive finite float (s), or ValueError naming ``name``."""
    if isinstance(value, (bool, str)) or not isinstance(value, numbers.Real):     # "1e-3": refused, not converted
        raise ValueError(f"{name} must be a positive finite number of seconds, got {value!r} "
                         f"({type(value).__name__})")
    x = float(value)
    if not (math.isfinite(x) and x > 0):
        raise ValueError(f"{name} must be a positive finite number of seconds, got {value!r}")
    return x


def check_substeps(value):
    """``value`` if it is "auto" or an integer in [1, SUBSTEPS_MAX], else ValueError (one line)."""
    if isinstance(value, str) and value == AUTO:
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise ValueError(f'substeps must be a positive integer or "auto", got {value!r}')
    if value > SUBSTEPS_MAX:
        raise ValueError(f"substeps must be at most {SUBSTEPS_MAX}, got {value}: every sub-step is unrolled "
                         f"into the C step (64 on a 2R: 0.87 MB of C, 84 s to build); for a stiffer observer "
                         f"lower dt, or use method etdrk4")
    return int(value)


@dataclass(frozen=True)
class Discretization:
    """How a continuous-time observer is stepped: the designed sample time, the declared range of
    the elapsed time between samples, the integrator and the measurement hold.

    Parameters
    ----------
    dt : float
        Sample time (s), > 0 and finite.
    method : {"expmid1", "expmid", "etdrk4", "rk4", "euler"}
        Integrator used over each sub-step. "etdrk4": exponential time
        differencing RK4 (Cox & Matthews 2002) for families that declare a linear gain rate a
        (flow g(x, y, u, p) - a x on some states): the linear part is integrated exactly, RK4
        sees only the smooth remainder; families without a rate get classical RK4. "expmid":
        the model (M, C, g, F) at one configuration per sub-step, its midpoint, evaluated at the
        sub-step's start and at its midpoint state predicted from it, the gain and injection
        terms by ETD-RK4 with the midpoint model held (families that declare their model part,
        ObserverSpec.model; the others get "etdrk4"; codegen.discrete.discretize). "expmid1"
        (the default): the same with the model evaluated once per sub-step, the prediction made
        with the model's last value, which the step keeps as memory (in the C's state struct).
    hold : {"foh", "zoh"}
        How the measurement behaves between samples: "zoh" holds y and u over [t_k, t_k+1];
        "foh" brings the state from t_k-1 to t_k with y linear in between and u_k-1 held,
        then forms the estimate (causal, no k0 dt sampling bias; see codegen.discrete.discretize).
    substeps : int or "auto"
        Equal sub-steps of ``method`` per sample (>= 1); "auto": a request for the fewest that make
        the discretised observer stable (codegen.discrete.stability.auto_substeps), resolved into a
        number when the target is made (codegen.pipeline.stages.make): what a generated folder
        and its metadata record is always the number. ``DEFAULT_DISCRETIZATION`` has 1; the
        targets file, the CLI and ``compile_observer`` ask "auto" unless substeps are given.
    dt_min, dt_max : float or None
        The declared range of the elapsed time between samples (s), dt_min <= dt <= dt_max: the
        step takes the elapsed time as an input (``<prefix>_step_dt``), the discrete stability
        check holds over the whole range, and a longer interval is integrated in
        ceil(elapsed / dt_max) equal sub-intervals. None (the default): ``DT_MIN_FACTOR`` dt and
        ``DT_MAX_FACTOR`` dt, i.e. [dt/4, 2 dt] (a 1 kHz loop jittering 0.7-1.6 ms stays in one
        step); ``dt_range`` gives the resolved pair.
    """

    dt: float = 1e-3
    method: str = "expmid1"
    hold: str = "foh"
    substeps: int = 1
    dt_min: float | None = None
    dt_max: float | None = None

    def __post_init__(self):
        dt = _seconds("dt", self.dt)
        object.__setattr__(self, "dt", dt)
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.hold not in HOLDS:
            raise ValueError(f"hold must be one of {HOLDS}, got {self.hold!r}")
        object.__setattr__(self, "substeps", check_substeps(self.substeps))
        for name in ("dt_min", "dt_max"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _seconds(name, value))
        lo, hi = self.dt_range
        if not lo <= dt <= hi:
            raise ValueError(f"dt_min <= dt <= dt_max must hold, got dt_min = {lo:g}, dt = {dt:g}, "
                             f"dt_max = {hi:g} (s)")

    @property
    def dt_range(self):
        """(dt_min, dt_max) in s: the declared values, or [DT_MIN_FACTOR dt, DT_MAX_FACTOR dt]."""
        return (self.dt_min if self.dt_min is not None else DT_MIN_FACTOR * self.dt,
                self.dt_max if self.dt_max is not None else DT_MAX_FACTOR * self.dt)

    def to_dict(self):
        """JSON-able dict (the Target's "discretization"): dt, method, hold, substeps, and dt_min,
        dt_max only when declared (None: relative to dt, see ``dt_range``)."""
        return {k: v for k, v in asdict(self).items() if v is not None or k not in ("dt_min", "dt_max")}

    @classmethod
    def from_dict(cls, d):
        """Inverse of ``to_dict``: the Discretization of the dict ``d``; unknown keys are refused."""
        unknown = set(d) - set(FIELDS)
        if unknown:
            raise ValueError(f"discretization: unknown keys {sorted(unknown)}")
        return cls(**d)


FIELDS = ("dt", "method", "hold", "substeps", "dt_min", "dt_max")


DEFAULT_DISCRETIZATION = Discretization()


def discretization(value=None, **overrides):
    """A Discretization from None (the default), a Discretization, or a dict, with keyword
    overrides (dt, method, hold, substeps, dt_min, dt_max) whose value is not None."""
    if value is None:
        value = DEFAULT_DISCRETIZATION
    elif isinstance(value, dict):
        value = Discretization.from_dict(value)
    elif not isinstance(value, Discretization):
        raise TypeError(f"discretization must be a Discretization or a dict, got {type(value).__name__}")
    changes = {k: v for k, v in overrides.items() if v is not None}
    return replace(value, **changes) if changes else value


def _jsonable(value, what):
    """A canonical JSON round-trip of ``value`` (dicts with sorted keys), or ValueError."""
    try:
        return json.loads(json.dumps(value, sort_keys=True, allow_nan=False))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be plain JSON data (numbers, strings, lists, dicts): {exc}") from None


def sanitize(text):
    """A C identifier made from user data ``text``: lowercase, [a-z0-9_], not starting with a digit."""
    s = re.sub(r"[^0-9a-zA-Z_]", "_", str(text)).lower()
    s = re.sub(r"_+", "_", s).strip("_") or "x"
    return s if not s[0].isdigit() else "t_" + s


# Prefixes a generated folder cannot carry: CMake's reserved target names (policy CMP0037: the
# build tool's own goals, and test/package once CTest/CPack are on, e.g. in a parent project
# that adds the folder), and the libraries the build links (add_library(m) "links to itself";
# lib<c>.a beside the objects would shadow the C library).
RESERVED_PREFIXES = frozenset({"all", "clean", "help", "install", "preinstall", "edit_cache",
                               "rebuild_cache", "test", "package", "package_source", "m", "c"})
# The longest prefix: it names the folder, its files and the cache folders, the longest being
# <prefix>ConfigVersion.cmake (+ 20 characters) and the cache's <prefix>-<16 hex> temporaries,
# within the 255 bytes a file name may have (NAME_MAX on ext4, xfs, btrfs, tmpfs).
MAX_PREFIX = 100


def check_prefix(prefix):
    """``prefix`` if a generated folder can carry it, else ValueError naming the fix (too long,
    or reserved: ``RESERVED_PREFIXES``)."""
    if len(prefix) > MAX_PREFIX:
        raise ValueError(f"name {prefix[:20]}... has {len(prefix)} characters, at most {MAX_PREFIX} "
                         "(it names the folder, its files and the C symbols): choose a shorter --name")
    if prefix in RESERVED_PREFIXES:
        why = "a library the build links" if len(prefix) == 1 else "a target name CMake reserves"
        raise ValueError(f"name {prefix!r} is {why} (the generated CMakeLists.txt's target is "
                         f"named after it): choose another --name, e.g. {prefix}_observer")
    return prefix


def default_name(robot, family, variant=None, precision="double"):
    """``<robot>_<family>[_<variant>][_float]`` (``_float`` when ``precision`` is "float"),
    sanitized (the default prefix of a Target)."""
    parts = [robot, family] + ([variant] if variant else []) + ([precision] if precision != "double" else [])
    return sanitize("_".join(parts))


@dataclass(frozen=True)
class Target:
    """One generated observer: what to build and how.

    Parameters
    ----------
    robot : dict
        The robot source (``RobotModel.source``): how to rebuild the robot from data, e.g.
        ``{"kind": "catalog", "name": "ur5"}`` or a URDF path with locked joints.
    family : str
        Observer family (a module of ``codegen.families.observers``) or control law.
    variant : str or None
        Family variant (e.g. "O2" of ``ciccarella_germani``), None when the family has none.
    build : dict
        Keyword arguments of the family's ``build`` (design inputs, generation options, gains
        given explicitly); plain JSON data.
    params : dict
        Runtime parameters overriding the designed defaults, name -> value.
    discretization : Discretization
        How the continuous-time observer is stepped (default ``DEFAULT_DISCRETIZATION``).
    precision : {"double", "float"}
        Real type of the generated C (one type for state, API and kernels; "float" also uses the
        single-precision math functions, for FPUs such as the Cortex-M4F's).
    name : str or None
        Symbol prefix and folder name; default ``<robot>_<family>[_<variant>][_float]``.
    inline : "auto", bool
        Code shape of the step: one flat expression (True), calls to one RHS routine (False),
        or by size ("auto", see codegen.discrete.discretize).
    sources : dict
        Where a value of ``params`` or ``build`` came from, name -> text (e.g. "tuned on the log
        log.csv", "measured on the log log.csv"); a value without one was given by the user. The
        folder's design report and header state it.
    """

    robot: dict
    family: str
    variant: str | None = None
    build: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    discretization: Discretization = DEFAULT_DISCRETIZATION
    precision: str = "double"
    name: str | None = None
    inline: object = "auto"
    sources: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.family, str) or not self.family:
            raise ValueError(f"family must be a non-empty string, got {self.family!r}")
        object.__setattr__(self, "robot", _jsonable(self.robot, "robot"))
        object.__setattr__(self, "build", _jsonable(dict(self.build), "build"))
        params = _jsonable(dict(self.params), "params")
        for k, v in params.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ValueError(f"params[{k!r}] must be a number, got {v!r}")
        object.__setattr__(self, "params", params)
        sources = _jsonable(dict(self.sources), "sources")
        bad = [k for k, v in sources.items() if not isinstance(v, str)]
        if bad:
            raise ValueError(f"sources[{bad[0]!r}] must be a text, got {sources[bad[0]]!r}")
        object.__setattr__(self, "sources", sources)
        object.__setattr__(self, "discretization", discretization(self.discretization))
        if self.precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}, got {self.precision!r}")
        if self.inline not in ("auto", True, False):
            raise ValueError(f"inline must be 'auto', True or False, got {self.inline!r}")
        for key in ("variant", "name"):
            value = getattr(self, key)
            if value is not None and not isinstance(value, str):       # ["a", "b"] is not "a_b"
                raise ValueError(f"{key} must be a string, got {value!r} ({type(value).__name__})")
        if self.name is not None:
            object.__setattr__(self, "name", sanitize(self.name))
        check_prefix(self.prefix)

    @property
    def robot_name(self):
        """The robot's name in its source (catalog name or URDF stem)."""
        return str(self.robot.get("name") or self.robot.get("kind") or "robot")

    @property
    def prefix(self):
        """The C symbol prefix and folder name."""
        if self.name:
            return self.name
        return default_name(self.robot_name, self.family, self.variant, self.precision)

    def with_discretization(self, value=None, **overrides):
        """A copy with another discretisation: ``discretization(value, **overrides)``, ``value``
        (Discretization, dict, or None: the current one) with the fields in ``overrides`` replaced."""
        return replace(self, discretization=discretization(value or self.discretization, **overrides))

    def to_dict(self):
        """JSON-able dict (the metadata's "target")."""
        d = asdict(self)
        d["discretization"] = self.discretization.to_dict()
        return d

    @classmethod
    def from_dict(cls, d):
        """Inverse of ``to_dict``: the Target of the dict ``d``; unknown keys are refused."""
        known = {f for f in cls.__dataclass_fields__}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"target: unknown keys {sorted(unknown)}; known: {sorted(known)}")
        d = dict(d)
        if "discretization" in d:
            d["discretization"] = discretization(d["discretization"])
        return cls(**d)
