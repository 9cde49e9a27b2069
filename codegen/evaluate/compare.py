"""Observers against the baselines a user would otherwise write, on one recorded run.

    cmp = compare(recording, robot)        # observers compiled (loop in C), baselines tuned
    print(cmp.table())
    cmp.figures(out_dir)

Every observer family in ``families`` is built with its designed gains (``design`` is passed to
``observers.build``), compiled at the recording's sample time with the default discretisation
and run over the samples. Every baseline of ``codegen.evaluate.baselines`` is run once per value of its
own parameter grid (``baselines.GRIDS``) on the same samples and the value with the lowest RMS
after ``t_ss`` is kept: the baselines are tuned with the truth, the observers are not.
Measures are those of ``codegen.evaluate.metrics``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import baselines, metrics

DEFAULT_FAMILIES = ("reduced_order_switched", "reduced_order", "extended_state", "nicosia_tomei")


@dataclass
class Entry:
    """One method on the run: its name, kind ("observer" or "baseline"), the parameters it ran
    with (for a tuned baseline: the best of its grid), its estimate (N, n) and its metrics."""

    name: str
    kind: str
    params: dict
    est: np.ndarray
    metrics: dict
    note: str = ""


@dataclass
class Comparison:
    """The entries of one run, with the run's t, truth and the windows the metrics used."""

    t: np.ndarray
    truth: np.ndarray
    entries: list
    t_ss: float
    level: float
    title: str = ""
    info: dict = field(default_factory=dict)

    def __getitem__(self, name):
        for e in self.entries:
            if e.name == name:
                return e
        raise KeyError(f"no method {name!r}; have {', '.join(e.name for e in self.entries)}")

    def best_baseline(self):
        """The baseline entry with the lowest RMS after t_ss (NaN/diverged ones excluded)."""
        ok = [e for e in self.entries if e.kind == "baseline" and np.isfinite(e.metrics["rms"])
              and not e.metrics["diverged"]]
        return min(ok, key=lambda e: e.metrics["rms"]) if ok else None

    def rows(self):
        """Plain-data rows (JSON-able): name, kind, params, the metrics and the RMS ratio to
        the best baseline."""
        best = self.best_baseline()
        out = []
        for e in self.entries:
            r = {"name": e.name, "kind": e.kind, "params": e.params, **e.metrics}
            r["rms_over_best_baseline"] = (e.metrics["rms"] / best.metrics["rms"]) if best else float("nan")
            if e.note:
                r["note"] = e.note
            out.append(r)
        return out

    def table(self):
        """The metrics table as text (one line per method)."""
        rows = self.rows()
        w = max([16] + [len(r["name"]) for r in rows])
        head = (f"{'method':{w}s} {'parameters':26s} {'RMS t>=' + format(self.t_ss, 'g') + 's':>12s} "
                f"{'max':>9s} {'t<' + format(self.level, 'g'):>9s} {'gain':>8s} {'lag ms':>8s} "
                f"{'/best bl':>8s}")
        lines = [self.title, head] if self.title else [head]
        for r in rows:
            par = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                            for k, v in r["params"].items())
            lines.append(
                f"{r['name']:{w}s} {par[:26]:26s} {r['rms']:12.3e} {r['max']:9.2e} "
                f"{r['t_conv']:9.3f} {r['gain']:8.4f} {1e3 * r['lag']:8.3f} "
                f"{r['rms_over_best_baseline']:8.3f}" + ("  DIVERGED" if r["diverged"] else "")
                + (f"  ({r['note']})" if r.get("note") else ""))
        return "\n".join(lines)

    def figures(self, out, joint=0, zoom=None):
        """Write to the folder ``out`` ``errors.png`` (||qd - qd_hat|| on a log axis, every method)
        and ``joint<j>.png`` (estimates of ``joint`` j (0-based) against the truth over ``zoom`` =
        (t0, t1) s, default the first 0.5 s after t_ss). Returns the paths."""
        from .sim import plots
        out = Path(out)
        errs = {e.name: e.est - self.truth for e in self.entries}
        zoom = zoom or (self.t_ss, min(self.t[-1], self.t_ss + 0.5))
        m = (self.t >= zoom[0]) & (self.t <= zoom[1])
        curves = {"true": self.truth[m, joint], **{e.name: e.est[m, joint] for e in self.entries}}
        return [plots.error_norms(out / "errors.png", self.t, errs, levels=(self.level,), title=self.title),
                plots.panels(out / f"joint{joint}.png", self.t[m],
                             [plots.Panel(curves, ylabel=f"qd{joint + 1} [rad/s]")],
                             title=f"{self.title}, joint {joint + 1}", cell=(8, 3.4))]


def parse_observer(text):
    """``text`` = ``"family[:name=value[:name=value...]]"`` -> (family, {name: float value}).

    >>> parse_observer("nicosia_tomei:kd=50:kp=625")
    ('nicosia_tomei', {'kd': 50.0, 'kp': 625.0})
    """
    family, *pairs = str(text).split(":")
    given = {}
    for pair in pairs:
        name, eq, value = pair.partition("=")
        try:
            given[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"observers: expected name=number after {family!r}, got {pair!r}") from None
        if not eq or not name.strip():
            raise ValueError(f"observers: expected name=number after {family!r}, got {pair!r}")
    return family.strip(), given


def run_observer(spec, Y, U, dt, reference=False):
    """Estimate (N, nest) of an observer spec over samples Y, U with the default discretisation
    at dt: compiled C (the loop in C) or the numpy reference; (estimate of NaN, message) when
    the observer fails."""
    from ..pipeline.load import ObserverError
    from .sim.blocks import block
    from ..core.target import discretization
    try:
        obs = block(spec, discretization(None, dt=dt), reference=reference)
        obs.reset(Y[0])
        return obs.run(Y, U), ""
    except (ObserverError, FloatingPointError) as e:
        return np.full((len(Y), spec.nest), np.nan), str(e)


def tune(name, Y, t, truth, t_ss, dt, grid=None):
    """The baseline ``name`` run over each value of its ``grid`` (None: baselines.GRIDS) that it
    accepts at this dt (s); returns (params, estimate (N, n)) of the value with the lowest RMS of
    est - ``truth`` (N, n) after t_ss (s) (the only value for an untuned baseline). ``Y`` (N, n):
    measured positions (rad) at the times ``t`` (N,) s."""
    cls = baselines.BASELINES[name]
    values = [None] if cls.tuned is None else (grid or baselines.GRIDS[name])
    best = None
    for v in values:
        try:
            b = cls(Y.shape[1], dt) if v is None else cls(Y.shape[1], dt, **{cls.tuned: v})
        except ValueError:
            continue                    # a value this sample time cannot take (cutoff >= Nyquist)
        b.reset(Y[0])
        est = b.run(Y)
        r = metrics.rms_after(t, est - truth, t_ss)
        if best is None or (np.isfinite(r) and not r >= best[0]):
            best = (r, b.params, est)
    return best[1], best[2]


def compare(rec, robot, families=DEFAULT_FAMILIES, design=None, t_ss=None, level=1e-2,
            baseline_names=None, reference=False, title=""):
    """Observers and tuned baselines on one recorded run.

    Parameters
    ----------
    rec : codegen.core.recording.Recording
        Measured positions (what the observers receive), applied torques and the true
        velocities (needed for the metrics and the tuning).
    robot : models.RobotModel
        The nominal model the observers are built on.
    families : sequence of str
        Observer families (``codegen.families.observers.FAMILIES``) with y = q, u = tau, est = qd_hat,
        each optionally with given build arguments, ``"reduced_order:k0=25"`` (see
        ``parse_observer``).
    design : dict, optional
        Keyword arguments of ``observers.build`` for every family (design inputs).
    t_ss : float, optional
        Start of the steady-state window (s); default half the run.
    level : float
        Convergence threshold (rad/s).
    baseline_names : sequence of str, optional
        Default: all of ``codegen.evaluate.baselines.BASELINES``.
    reference : bool
        Run the observers with the numpy reference instead of the compiled C.
    title : str
        Title of the table and figures.

    Returns
    -------
    Comparison
    """
    from ..families import observers
    if rec.qd is None:
        raise ValueError("rec: the recording has no true velocity (qd_<joint> columns); "
                         "the metrics and the baseline tuning need it")
    if list(rec.joint_names) != list(robot.joint_names):
        raise ValueError(f"rec: joints {rec.joint_names} differ from the robot's {robot.joint_names}")
    t, Y, U, truth, dt = rec.t, rec.q, rec.tau, rec.qd, rec.dt
    t_ss = float(t[-1] / 2 if t_ss is None else t_ss)
    entries = []
    for item in families:
        fam, given = parse_observer(item)
        try:
            spec = observers.build(fam, robot, **{**design_for(fam, design), **given})
        except TypeError as e:
            raise ValueError(f"observers: {item!r}: {e}") from None
        if spec.nest != robot.n or spec.ny != robot.n:
            raise ValueError(f"families: {fam!r} does not estimate qd from q (ny = {spec.ny}, "
                             f"nest = {spec.nest})")
        est, note = run_observer(spec, Y, U, dt, reference)
        params = {k: float(v) for k, v in zip(spec.p_names, spec.p_default)}
        entries.append(Entry(item, "observer", params, est, metrics.summarize(t, est, truth, t_ss, level), note))
    for name in baseline_names or baselines.BASELINES:
        params, est = tune(name, Y, t, truth, t_ss, dt)
        entries.append(Entry(name, "baseline", params, est, metrics.summarize(t, est, truth, t_ss, level)))
    return Comparison(t=t, truth=truth, entries=entries, t_ss=t_ss, level=level, title=title)


def robot_by_name(name):
    """A catalog robot, or a URDF robot when ``name`` is a path to a .urdf file; ValueError
    naming the valid choices otherwise."""
    from models import load_robot, names
    if name in names():
        return load_robot(name)
    if str(name).endswith(".urdf") and Path(name).is_file():
        return load_robot(urdf=name)
    raise ValueError(f"unknown robot {name!r}; valid: {', '.join(names())} or a path to a .urdf file")


def design_inputs(quantization=0.0, noise=0.0, uncertainty=0.0):
    """Keyword arguments of ``observers.build`` describing the sensor (rad) and the relative
    model uncertainty (the noise-aware design of codegen.families.design.noise). quantization and noise
    both None: the sensor is not stated, the design assumes its default encoder; 0 and 0: a
    noise-free sensor, the guarantee gains."""
    sensor = ({} if quantization is None and noise is None else
              {"quantization": float(quantization or 0.0), "noise": float(noise or 0.0)})
    return {**sensor, "uncertainty": float(uncertainty or 0.0)}


def design_for(family, design):
    """The keywords of ``design`` that ``family``'s build takes (families without a noise-aware
    design ignore the sensor description)."""
    import importlib
    import inspect

    from ..families.observers import FAMILIES
    if family not in FAMILIES:
        return {}                     # observers.build names the valid families
    params = inspect.signature(importlib.import_module(f"codegen.families.observers.{family}").build).parameters
    return {k: v for k, v in (design or {}).items() if k in params}
