"""ObserverSpec: a continuous-time observer as CasADi functions (docs/architecture.md §1, §3).

Every observer family builds one of these; ``discretize``, ``emit``, ``build`` and
``runtime`` only ever see this shape, never a particular observer.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .options import DEFAULT_INPUTS, InputRanges, Options
from .target import Target, default_name, discretization, sanitize  # noqa: F401  (sanitize re-exported)


ON_A_LOG = "on the log"      # in a value's source (Target.sources): it was tuned or measured on a log


class DesignReport(dict):
    """A family's design report: a plain dict (JSON-able; the metadata JSON records it), printed
    as text: the report's own ``summary`` when the design wrote one, its choice and why, the
    designed values, then each section (the guarantee, the stability check) indented."""

    FIRST = ("summary", "choice", "why")
    WIDTH = 12          # numbers of a longer list are elided after this many
    STATED = ("parameters", "inputs", "sources")     # the sections of the built values' sources (source_lines)

    def why(self):
        """Why the designed defaults are what they are: the report's choice and reason, its
        summary's first line, "given (no design)" or "the family's defaults"."""
        return ("given (no design)" if self.get("given") else
                ": ".join(str(self[k]) for k in ("choice", "why") if k in self) or
                (str(self["summary"]).splitlines()[0] if "summary" in self else "the family's defaults"))

    def assumption(self):
        """What the design's predicted error takes for granted, as data, or None: a design that
        predicts its error (``predicted_error``) from the robot's model without a model or torque
        uncertainty stated assumes the model exact; ``{"assumes": "exact model", "text": one line,
        "measure_on": "log"}`` (a log of the robot measures the error: codegen.evaluate.compare).
        None too when its gains were tuned on a log (a parameter's source names ON_A_LOG)."""
        if "predicted_error" not in self or self.get("variant") == "kinematic":
            return None
        if any(ON_A_LOG in str(r.get("source")) for r in (self.get("parameters") or {}).values()):
            return None                 # its gains were scored on a log of the robot: measured there
        stated = [v for v in (self.get("uncertainty"), self.get("torque_uncertainty")) if v is not None]
        if any(np.any(np.asarray(v, dtype=float) > 0) for v in stated):
            return None
        return {"assumes": "exact model", "measure_on": "log",
                "text": "its predicted error assumes the robot's model exact (no model or torque uncertainty "
                        "stated); on a real arm the error can be far larger"}

    def source_lines(self):
        """One line per value whose source the report states (codegen.pipeline.emit.with_params):
        ``name = value: source (designed D)`` per parameter, ``input name = value: source`` per
        build argument, ``name: source`` per other value (the discretisation's)."""
        lines = []
        for k, r in (self.get("parameters") or {}).items():
            designed = "" if r["designed"] == r["value"] else f" (designed {_report_value(r['designed'])})"
            lines.append(f"{k} = {_report_value(r['value'])}: {r['source']}{designed}")
        for k, r in (self.get("inputs") or {}).items():
            lines.append(f"input {k} = {_report_value(r['value'])}: {r['source']}")
        lines += [f"{k}: {text}" for k, text in (self.get("sources") or {}).items()]
        return lines

    def __str__(self):
        lines = [*str(self["summary"]).splitlines()] if "summary" in self else []
        for k in self.FIRST[1:]:
            if k in self:
                lines.append(f"{k}: {self[k]}")
        a = self.assumption()
        if a:
            lines.append(f"assumes: {a['text']}: measure it on a log of the robot (codegen.evaluate.compare)")
        stated = self.source_lines()
        if stated:
            lines += ["built with (the design's own values below are its defaults):"] + [f"  {t}" for t in stated]
        lines += report_lines({k: v for k, v in self.items() if k not in (*self.FIRST, *self.STATED)}, "")
        return "\n".join(lines)

    def brief(self, params, stability=None):
        """A few lines for ``build``: the gains ``params`` (name -> value) and why (the design's
        choice and reason, or that they were given; a value whose source the report states,
        ``source_lines``, with its source), then what the stability check found: the report
        ``stability`` of the built target (its metadata's, after substeps "auto" was resolved)
        when given, else the design's own check."""
        stated = self.get("parameters") or {}
        rest = {k: v for k, v in params.items() if k not in stated}
        gains = ", ".join(f"{k} = {_report_value(v)}" for k, v in rest.items()) or "no parameters"
        lines = [f"{gains}: {self.why()}"] if rest or not stated else []
        lines += self.source_lines()
        st = stability if stability is not None else self.get("stability")
        if isinstance(st, dict) and "stable" in st:
            top = "; ".join(f"{g} stable up to {_report_value(r['max_stable'])}"
                            for g, r in (st.get("gains") or {}).items() if isinstance(r, dict)
                            and r.get("max_stable") is not None)
            lines.append(f"discrete stability at dt {_report_value(st.get('dt'))} s ({st.get('method')}, "
                         f"{st.get('hold')}, {st.get('substeps')} substeps): "
                         f"{'stable' if st['stable'] else 'UNSTABLE'}, spectral radius "
                         f"{_report_value(st.get('spectral_radius'))} (the largest |eigenvalue| of the linearised "
                         f"step; at most 1: no mode grows, 1: its slowest mode barely decays in a step)"
                         + (f"; {top}" if top else ""))
        if "lowered_to_stable" in self:
            lines.append(f"lowered into the stable region: {_report_value(self['lowered_to_stable'])}")
        return lines


def _report_value(v):
    """One value of a design report as short text (numbers to 6 significant digits)."""
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return str(v)
    if isinstance(v, numbers.Real):
        return f"{float(v):.6g}"
    if isinstance(v, (list, tuple)):
        items = [_report_value(x) for x in v[:DesignReport.WIDTH]]
        more = f", ... ({len(v)} values)" if len(v) > DesignReport.WIDTH else ""
        return "[" + ", ".join(items) + more + "]"
    return str(v)


def report_lines(d, indent=""):
    """``d``'s entries as ``name: value`` lines (numbers to 6 significant digits), nested dicts
    and text of several lines as indented sections (a design report, a scenario's summary);
    every line starts with ``indent`` (a string of spaces)."""
    lines = []
    for k, v in d.items():
        if isinstance(v, dict) and v:
            lines.append(f"{indent}{k}:")
            lines += report_lines(v, indent + "  ")
        elif isinstance(v, str) and "\n" in v.strip():
            lines.append(f"{indent}{k}:")
            lines += [f"{indent}  {line}" for line in v.strip("\n").splitlines()]
        else:
            lines.append(f"{indent}{k}: {_report_value(v)}")
    return lines


@dataclass
class ObserverSpec:
    """A continuous-time observer (optionally hybrid).

    Flat float64 vectors with named slots:
      x  observer state          y  measurement        u  known input (torque)
      p  runtime parameters (gains, with designed defaults)
      est  the estimate the observer outputs

    Functions (casadi.Function):
      rhs(x, y, u, p)    -> xdot            the flow
      rhs_split(x, y_cfg, y, u, p) -> xdot  (or None)  the flow with its use of y split into the
                                            configuration of the model (M, C, g, F at y_cfg) and
                                            the output injection (the gain terms, at y);
                                            rhs(x, y, u, p) = rhs_split(x, y, y, u, p). The
                                            first-order hold freezes y_cfg at the sub-step's
                                            midpoint (codegen.discrete.discretize)
      model(x, y_cfg, y, u, p) -> m         (or None, with rhs_model)  the model's part of the flow
                                            (the forward dynamics: M, C, g, F at y_cfg and at the
                                            velocity the state x and y give it)
      rhs_model(x, y, u, p, m) -> xdot      the flow with that part given as m (the gain and
                                            injection terms): rhs_split(x, y_cfg, y, u, p) =
                                            rhs_model(x, y, u, p, model(x, y_cfg, y, u, p)); the
                                            methods "expmid1" (once) and "expmid" (twice)
                                            evaluate model at one configuration per sub-step.
                                            ``model_correction``: the flow stands without it
                                            (rhs_model at m = 0), which then predicts the
                                            midpoint state under "expmid1" (no memory)
      output(x, y, u, p) -> est             the estimate at the current sample
      init(y0, est0, p)  -> x0              state from a first measurement and an initial estimate
      jump(x, y, p)      -> x+   (or None)  hybrid jump map, applied before each step
      rate(x, p)         -> a    (or None)  the flow's linear gain rate: rhs = N - a x on the
                                            states ``rate_states`` (a constant along the flow),
                                            integrated exactly by "etdrk4", "expmid" and "expmid1"
      retune(x, y, p_old, p_new) -> x+  (or None: identity)  the state after a parameter change
                                            at measurement y that keeps the estimate continuous
      measurement(est)   -> y    (or None)  the measurement of a plant in the estimated state
                                            (families estimating the whole state): consistent
                                            working points for the stability check
      phases(x, y, p)    -> [x_1 .. x_K]  (or None)  the state x moved to each phase of its logic
                                            or clock slots (K columns, the estimate kept): the
                                            stability check linearises at every one, so that
                                            every gain the observer can switch to is checked

    Declared data (what the reference and the cross-check read, never guessed):
      variant     the family's variant (None if it has none)
      options     typed generation options (codegen.core.options), e.g. the quadrature order
      inputs      where the cross-check draws random inputs (codegen.core.options.InputRanges)
      design      the design report (a DesignReport: a JSON-able dict of why the default gains
                  are what they are, printed as text)
      build_args  the keyword arguments ``observers.build`` received (plain data, for Target)
      rate_states names of the states the linear gain term acts on (with ``rate``)
      gains       gain name -> the parameter slots it scales together (non-negative gains the
                  discrete stability check bisects on, codegen.discrete.stability)
      clocks      clock state name -> the parameter (a time, s) it counts up to, s' = 1: the
                  stability check refuses a time the clock cannot reach in the precision
      model_correction  the model part m corrects a flow complete without it (rhs_model at
                  m = 0: kalman_model's kinematic filter); "expmid1" then predicts the sub-step's
                  midpoint with that flow and keeps no memory (codegen.discrete.discretize)
      limits      the ranges of y and u the user declared (None: the robot's declared limits with
                  their margins; "none": no range; codegen.core.limits); ``input_limits`` are the
                  ranges the C checks every sample against
    """

    family: str
    robot: object
    x_names: list
    y_names: list
    u_names: list
    p_names: list
    est_names: list
    p_default: np.ndarray
    rhs: ca.Function
    output: ca.Function
    init: ca.Function
    jump: ca.Function | None = None
    rhs_split: ca.Function | None = None
    rate: ca.Function | None = None
    model: ca.Function | None = None
    rhs_model: ca.Function | None = None
    retune: ca.Function | None = None
    measurement: ca.Function | None = None
    phases: ca.Function | None = None
    variant: str | None = None
    options: Options = field(default_factory=Options)
    inputs: InputRanges = DEFAULT_INPUTS
    design: dict = field(default_factory=dict)     # a DesignReport once set (__setattr__)
    build_args: dict = field(default_factory=dict)
    rate_states: tuple = ()
    gains: dict = field(default_factory=dict)
    clocks: dict = field(default_factory=dict)
    model_correction: bool = False
    limits: object = None

    @property
    def input_limits(self):
        """The declared ranges of y and u (codegen.core.limits.input_ranges: ``y_lower``,
        ``y_upper``, ``u_max``, None where a slot is not checked, and the ``rule``)."""
        from .limits import input_ranges
        return input_ranges(self.robot, self.y_names, self.u_names, self.limits)

    def __setattr__(self, name, value):
        """Every design report assigned (at construction or later) is a DesignReport."""
        if name == "design" and not isinstance(value, DesignReport):
            value = DesignReport(value or {})
        super().__setattr__(name, value)

    def __post_init__(self):
        self.p_default = np.asarray(self.p_default, dtype=float).reshape(-1)
        if self.p_default.size != len(self.p_names):
            raise ValueError(f"p_default has {self.p_default.size} entries, p_names {len(self.p_names)}")
        for name, v in zip(self.p_names, self.p_default):
            if not np.isfinite(v):
                raise ValueError(f"{self.family}: the default of parameter {name!r} is {v}; "
                                 f"parameters must be finite")
        for f, ins, outs in ((self.rhs, (self.nx, self.ny, self.nu, self.np), (self.nx,)),
                             (self.output, (self.nx, self.ny, self.nu, self.np), (self.nest,)),
                             (self.init, (self.ny, self.nest, self.np), (self.nx,))) + \
                (() if self.rhs_split is None else
                 ((self.rhs_split, (self.nx, self.ny, self.ny, self.nu, self.np), (self.nx,)),)):
            got_in = tuple(f.size1_in(i) * f.size2_in(i) for i in range(f.n_in()))
            got_out = tuple(f.size1_out(i) * f.size2_out(i) for i in range(f.n_out()))
            if got_in != ins or got_out != outs:
                raise ValueError(f"{self.family}: function {f.name()} has sizes {got_in}->{got_out}, "
                                 f"expected {ins}->{outs}")
        self._check_model()
        self.rate_states = tuple(self.rate_states)
        unknown = [s for s in self.rate_states if s not in self.x_names]
        if unknown or (self.rate is None) != (not self.rate_states):
            raise ValueError(f"{self.family}: rate_states {list(self.rate_states)} must name states "
                             f"and come with a rate function")
        self.gains = {str(g): tuple(slots) for g, slots in self.gains.items()}
        for g, slots in self.gains.items():
            if not slots or any(s not in self.p_names for s in slots):
                raise ValueError(f"{self.family}: gain {g!r} scales unknown parameters {list(slots)}")
        if self.phases is not None and (
                tuple(self.phases.numel_in(i) for i in range(3)) != (self.nx, self.ny, self.np)
                or self.phases.size1_out(0) != self.nx):
            raise ValueError(f"{self.family}: phases must map (x, y, p) to nx = {self.nx} rows (one column per phase)")
        self.clocks = {str(c): str(t) for c, t in self.clocks.items()}
        for c, t in self.clocks.items():
            if c not in self.x_names or t not in self.p_names:
                raise ValueError(f"{self.family}: clock {c!r} -> {t!r} must name a state and a parameter")

    def _check_model(self):
        """model and rhs_model come together, with a flow split like rhs_split, sizes matching."""
        if (self.model is None) != (self.rhs_model is None) or (self.model is not None and self.rhs_split is None):
            raise ValueError(f"{self.family}: model and rhs_model come together, with rhs_split")
        if self.model is None:
            if self.model_correction:
                raise ValueError(f"{self.family}: model_correction needs a model part (model, rhs_model)")
            return
        nm = self.model.size1_out(0) * self.model.size2_out(0)
        for f, ins in ((self.model, (self.nx, self.ny, self.ny, self.nu, self.np)),
                       (self.rhs_model, (self.nx, self.ny, self.nu, self.np, nm))):
            got = tuple(f.size1_in(i) * f.size2_in(i) for i in range(f.n_in()))
            if got != ins:
                raise ValueError(f"{self.family}: function {f.name()} has inputs {got}, expected {ins}")

    @property
    def model_size(self):
        """Entries of the model's part m (``model``), 0 without one."""
        return 0 if self.model is None else self.model.size1_out(0) * self.model.size2_out(0)

    nx = property(lambda self: len(self.x_names))
    ny = property(lambda self: len(self.y_names))
    nu = property(lambda self: len(self.u_names))
    np = property(lambda self: len(self.p_names))
    nest = property(lambda self: len(self.est_names))

    @property
    def robot_source(self):
        """How the independent reference rebuilds the robot (see RobotModel.source)."""
        return self.robot.source

    @property
    def params(self):
        """Default parameters as a name -> value dict."""
        return dict(zip(self.p_names, self.p_default.tolist()))

    def target(self, value=None, *, precision="double", name=None, inline="auto", **overrides):
        """The Target that builds this spec with discretisation ``value`` (None: the default;
        keyword overrides dt, dt_min, dt_max, method, hold, substeps), ``precision``, ``name`` (default
        ``<robot>_<family>[_<variant>][_float]``) and ``inline``."""
        build = {k: v for k, v in self.build_args.items() if k != "variant"}
        return Target(robot=self.robot_source, family=self.family, variant=self.variant, build=build,
                      discretization=discretization(value, **overrides), precision=precision,
                      name=name or default_name(self.robot.name, self.family, self.variant, precision),
                      inline=inline)

    def describe(self):
        """Plain data (JSON-able) the reference rebuilds this observer from: family, variant,
        robot source, slot names, default parameters, options, whether it is hybrid, its rate states
        whether it splits its flow's y (``rhs_split``), the size of its model part (``model``;
        0: none), the declared ranges of its inputs (``input_limits``) and, when it is a
        correction (``model_correction``), "model_correction": True."""
        return {"family": self.family, "variant": self.variant, "robot": self.robot_source,
                "names": {"x": list(self.x_names), "y": list(self.y_names), "u": list(self.u_names),
                          "p": list(self.p_names), "est": list(self.est_names)},
                "p_default": [float(v) for v in self.p_default], "options": self.options.to_dict(),
                "hybrid": self.jump is not None, "rate_states": list(self.rate_states),
                "rhs_split": self.rhs_split is not None, "rhs_model": self.model_size,
                "gains": {g: list(slots) for g, slots in self.gains.items()},
                "limits": self.input_limits,
                **({"model_correction": True} if self.model_correction else {})}


def split_flow(x, y_cfg, y, u, p, xdot):
    """(rhs, rhs_split) of a flow ``xdot`` (SX) written with its model at the configuration
    ``y_cfg`` and its output injection at the measurement ``y`` (ObserverSpec.rhs_split);
    rhs(x, y, u, p) is it at y_cfg = y. x, y_cfg, y, u, p: the SX symbols it depends on."""
    return (ca.Function("rhs", [x, y, u, p], [ca.substitute(xdot, y_cfg, y)]),
            ca.Function("rhs_split", [x, y_cfg, y, u, p], [xdot]))


def split_model(x, y_cfg, y, u, p, m, model, xdot):
    """(rhs, rhs_split, model, rhs_model) of a flow ``xdot`` (SX) written with the model's part as
    the symbol ``m`` and that part ``model`` (SX, at the configuration ``y_cfg``): the flow is
    ``xdot`` with m = model (ObserverSpec.model, .rhs_model; ``split_flow``). x, y_cfg, y, u, p:
    the SX symbols they depend on."""
    rhs, rhs_split = split_flow(x, y_cfg, y, u, p, ca.substitute(xdot, m, model))
    return (rhs, rhs_split, ca.Function("model", [x, y_cfg, y, u, p], [model]),
            ca.Function("rhs_model", [x, y, u, p, m], [xdot]))


def real_number(name, value):
    """float(value) for a finite real number (not a bool or text), else ValueError naming ``name``."""
    if isinstance(value, complex):
        raise ValueError(f"{name}: expected a finite real number, got the complex number {value!r}")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: expected a finite real number, got {type(value).__name__} {value!r}")
    try:
        v = float(value)
    except OverflowError:
        raise ValueError(f"{name}: {value} is too large for a double") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite real number, got {v}")
    return v


def checked_args(args, name=None):
    """The keyword arguments ``args`` (dict) of a family's build, every number in them (also in
    lists, arrays and dicts) checked by ``real_number`` under its name (k0, K1[2], bounds['m']);
    text and other objects are left to the family. ``name``: the name of ``args`` when it is one
    value (recursion), None for the top-level dict."""
    if name is None:
        for k, v in args.items():
            checked_args(v, k)
    elif isinstance(args, dict):
        for k, v in args.items():
            checked_args(v, f"{name}[{k!r}]")
    elif isinstance(args, (list, tuple, np.ndarray)):
        for i, v in enumerate(args):
            checked_args(v, f"{name}[{i}]")
    elif isinstance(args, numbers.Number) and not isinstance(args, bool):
        real_number(name, args)
    return args


def plain(value):
    """``value`` as plain JSON data: numpy arrays and scalars as lists and floats, design reports
    through their ``as_dict``; anything else unchanged (Target refuses what is not JSON)."""
    if hasattr(value, "as_dict"):
        value = value.as_dict()
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    return value

