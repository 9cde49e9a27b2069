"""Typed generation options of the observer families (plain data, no CasADi).

A family declares, as fields of a frozen dataclass, what the independent reference needs to
rebuild the same observer (variant, quadrature nodes, non-minimal rows, ...), and, as an
``InputRanges`` value, where the cross-check draws its random inputs. ``ObserverSpec`` carries
both; the metadata JSON records them (``to_dict``) and the reference reads them back
(``options_from_dict``), never strings or dict keys it has to guess.
"""
from __future__ import annotations

import math
from dataclasses import MISSING, asdict, dataclass, fields


def _tuple(value, kind):
    return tuple(kind(v) for v in value)


@dataclass(frozen=True)
class Options:
    """No options: the family is fully described by its robot, slot names and parameters."""

    def to_dict(self):
        """JSON-able dict of the fields, with the class name under "kind"."""
        return {"kind": type(self).__name__, **asdict(self)}


def _bounds(value):
    """``value`` as a tuple of positive finite floats (rad/s), or ValueError naming v_bound."""
    out = _tuple(value, float)
    if not all(math.isfinite(v) and v > 0 for v in out):
        raise ValueError(f"v_bound must be positive finite speeds (rad/s), got {list(out)}")
    return out


@dataclass(frozen=True)
class VelocityBoundOptions(Options):
    """A velocity observer that evaluates its model at the estimate saturated per joint,
    FD(y, sat(v), tau) with sat(v)_j = min(max(v_j, -b_j), b_j), b = ``v_bound`` (rad/s; one per
    joint): the right-hand side grows at most linearly in the state, so a large model error
    cannot drive the Coriolis term (quadratic in v) into a finite escape
    (codegen.families.observers._bound). Empty: no saturation (a target generated before it)."""

    v_bound: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "v_bound", _bounds(self.v_bound))


@dataclass(frozen=True)
class HybridOptions(Options):
    """Hybrid reduced-order observer (docs/papers/seed000.md §1.3): the logic state r lives in [1, r_max]; the
    model is evaluated at the estimate saturated to ``v_bound`` as in VelocityBoundOptions."""

    r_max: int
    v_bound: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "r_max", int(self.r_max))
        object.__setattr__(self, "v_bound", _bounds(self.v_bound))


@dataclass(frozen=True)
class QuadratureOptions(Options):
    """I&I observers (docs/papers/seed003.md §4, §5): beta by N-node Gauss-Legendre, the intervals of the joints
    flagged ``periodic`` reduced modulo 2 pi with an N_period-node trapezoid per period."""

    N: int
    periodic: tuple
    N_period: int

    def __post_init__(self):
        object.__setattr__(self, "N", int(self.N))
        object.__setattr__(self, "N_period", int(self.N_period))
        object.__setattr__(self, "periodic", _tuple(self.periodic, bool))


@dataclass(frozen=True)
class NonMinimalOptions(Options):
    """Seed 002's non-minimal coordinates (docs/papers/seed002.md §3.1): which rows of the stacked CoM positions
    are measured, which joints are observable from them, and the gravity vector g_o."""

    rows: tuple
    joints: tuple
    g_o: tuple

    def __post_init__(self):
        object.__setattr__(self, "rows", _tuple(self.rows, int))
        object.__setattr__(self, "joints", _tuple(self.joints, int))
        object.__setattr__(self, "g_o", _tuple(self.g_o, float))


@dataclass(frozen=True)
class VariantOptions(Options):
    """A family with named variants (Ciccarella-Germani O1..O4, docs/papers/seed004.md §8.4)."""

    variant: str


KINDS = {cls.__name__: cls for cls in (Options, VelocityBoundOptions, HybridOptions, QuadratureOptions,
                                       NonMinimalOptions, VariantOptions)}


def options_from_dict(d):
    """The typed options recorded by ``Options.to_dict``: the dict ``d`` (None: plain ``Options``)
    holds "kind" (a name in ``KINDS``, default "Options") and that class's fields, those with a
    default optional (a target recorded before the field existed); ValueError on an unknown kind,
    an unknown field or a missing required one."""
    d = dict(d or {"kind": "Options"})
    kind = d.pop("kind", "Options")
    if kind not in KINDS:
        raise ValueError(f"unknown options kind {kind!r}; known: {sorted(KINDS)}")
    cls = KINDS[kind]
    names = {f.name for f in fields(cls)}
    required = {f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING}
    if not required <= set(d) <= names:
        raise ValueError(f"{kind}: expected fields {sorted(names)}, got {sorted(d)}")
    return cls(**d)


U_DRAWS = ("gravity", "scaled", "plain")


@dataclass(frozen=True)
class InputRanges:
    """Where the cross-check draws random (x, y, u) for a family, at physical scales.

    Parameters
    ----------
    y_jitter : float or None
        None: each draw samples fresh configurations in the joint ranges for the joint slots
        of y. A number (rad): configurations from one fixed draw plus N(0, y_jitter^2) noise,
        so that two samples of a draw differ like consecutive fast samples (stiff filters).
    y_extra : tuple of (mean, std)
        Normal distribution of each y slot after the first n (e.g. measured forces, N).
    u : {"gravity", "scaled", "plain"}
        u = g(q) + u_scale N(0, 1) (around the gravity torque), u = u_scale N(0, 1) max(1, |g_i|)
        per joint (zero-mean at the gravity scale), or u = u_scale N(0, 1) (e.g. an unused input).
    u_scale : float
        Standard deviation of u (N m), or its multiplier for "scaled".
    est_scale : float
        Standard deviation of the initial estimate passed to init (velocity-sized).
    init_p : tuple of (parameter name, value)
        Parameters init(y, est, p) is evaluated with to centre the states (the others: the
        spec's defaults), e.g. a filter started on a function of the measurement.
    x_scale : float or tuple
        Standard deviation of the perturbation of the state around init(y, est, p), scalar or
        per slot (nx,).
    x_uniform : tuple of (slot name, lo, hi)
        State slots drawn uniformly in [lo, hi] instead (e.g. a dynamic scaling r).
    x_normal : tuple of (slot name, mean, std)
        State slots drawn from N(mean, std^2) instead (e.g. a filter at its working level).
    x_integer : tuple of (slot name, lo, hi)
        State slots drawn as integers in [lo, hi] (e.g. a hybrid logic state).
    x_about_y : tuple of (state slot name, measurement slot name)
        State slots drawn around a measurement slot instead of around init (e.g. a position
        estimate near the measured position), with their ``x_scale``.
    x_fine : float or None
        On half of the draws the ``x_about_y`` perturbations use this scale instead (e.g. inside
        a tanh boundary layer).
    """

    y_jitter: float | None = None
    y_extra: tuple = ()
    u: str = "scaled"
    u_scale: float = 1.0
    est_scale: float = 2.0
    init_p: tuple = ()
    x_scale: object = 0.1
    x_uniform: tuple = ()
    x_normal: tuple = ()
    x_integer: tuple = ()
    x_about_y: tuple = ()
    x_fine: float | None = None

    def __post_init__(self):
        if self.u not in U_DRAWS:
            raise ValueError(f"u must be one of {U_DRAWS}, got {self.u!r}")
        object.__setattr__(self, "y_extra", tuple((float(m), float(s)) for m, s in self.y_extra))
        object.__setattr__(self, "init_p", tuple((str(k), float(v)) for k, v in self.init_p))
        if not isinstance(self.x_scale, (int, float)):
            object.__setattr__(self, "x_scale", _tuple(self.x_scale, float))
        for name, kind in (("x_uniform", float), ("x_normal", float), ("x_integer", int)):
            object.__setattr__(self, name, tuple((str(k), kind(a), kind(b)) for k, a, b in getattr(self, name)))
        object.__setattr__(self, "x_about_y", tuple((str(a), str(b)) for a, b in self.x_about_y))

    def to_dict(self):
        """JSON-able dict of the fields."""
        return asdict(self)


DEFAULT_INPUTS = InputRanges()
