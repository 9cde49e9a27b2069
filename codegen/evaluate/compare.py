"""Observers against the baselines a user would otherwise write, on one recorded run.

    cmp = compare(recording, robot)        # observers compiled (loop in C), baselines tuned
    print(cmp.table())                     # ends with the verdict line
    cmp.figures(out_dir)

Every observer family in ``families`` is built with its designed gains (``design`` is passed to
``observers.build``), compiled at the recording's (median) sample time with the default
discretisation and run over the samples (``run_observer``). Every baseline of
``codegen.evaluate.baselines`` is run once per value of its own parameter grid
(``baselines.GRIDS``) on the same samples, with the log's own time stamps, and the value with the
lowest RMS after ``t_ss`` is kept: the baselines are tuned, the observers are not. The robot's own
velocity signal (``qdm_<joint>`` columns), when logged, is one more row.

What the estimates are measured against (``Reference``): the true velocity when the recording
has it (a simulation); otherwise, as on every real log, the offline zero-phase reference of
``codegen.logs.smoothing.reference_velocity`` (4th-order Butterworth forward and backward at
``ref_cutoff`` Hz on a uniform resampling), on the samples away from its edges. Its uncertainty u
(RMS of its spread between cutoff/sqrt 2 and cutoff sqrt 2) is reported; an estimate whose RMS
error against it is at most u cannot be ranked. The baselines are tuned on the same reference.
Measures are those of ``codegen.evaluate.metrics``.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import baselines, metrics
from ..logs import smoothing
from ..logs.reference import Reference, reference_of
from ..core.estimator import velocity_slots
from ..verify.measure import saturated_samples

DEFAULT_FAMILIES = ("kalman_model", "reduced_order_switched", "reduced_order", "extended_state", "nicosia_tomei")
SIGNAL = "robot's velocity signal"          # the row of the qdm_<joint> columns
UNRANKED = "within the reference's uncertainty: cannot be ranked"


def measure(ref, t, est, t_ss, level):
    """``metrics.summarize`` of the estimate ``est`` (N, n) against the Reference ``ref`` on its
    valid samples; ``t`` (N,) s, ``t_ss`` (s) and ``level`` (rad/s) as there."""
    v = ref.valid
    return metrics.summarize(t[v], est[v], ref.qd[v], t_ss, level)


@dataclass
class Entry:
    """One method on the run: its name, kind ("observer", "baseline" or "signal": the robot's
    own velocity), the parameters it ran with (for a tuned baseline: the best of its grid), its
    estimate (N, n) and its metrics."""

    name: str
    kind: str
    params: dict
    est: np.ndarray
    metrics: dict
    note: str = ""


@dataclass
class Comparison:
    """The entries of one run, with the run's t, the velocity measured against (``truth``: the
    true velocity or the reference's, ``ref`` says which) and the windows the metrics used."""

    t: np.ndarray
    truth: np.ndarray
    entries: list
    t_ss: float
    level: float
    title: str = ""
    info: dict = field(default_factory=dict)
    ref: Reference | None = None

    def __getitem__(self, name):
        for e in self.entries:
            if e.name == name:
                return e
        raise KeyError(f"no method {name!r}; have {', '.join(e.name for e in self.entries)}")

    @property
    def uncertainty(self):
        """The reference's uncertainty over the steady-state window (rad/s); 0 for the truth."""
        return 0.0 if self.ref is None else self.ref.uncertainty(self.t, self.t_ss)

    def _best(self, kind):
        ok = [e for e in self.entries if e.kind == kind and np.isfinite(e.metrics["rms"])
              and not e.metrics["diverged"]]
        return min(ok, key=lambda e: e.metrics["rms"]) if ok else None

    def best_baseline(self):
        """The baseline entry with the lowest RMS after t_ss (NaN/diverged ones excluded)."""
        return self._best("baseline")

    def best_observer(self):
        """The observer entry with the lowest RMS after t_ss (NaN/diverged ones excluded)."""
        return self._best("observer")

    def verdict(self):
        """One line: ``use X: N x better than the best tuned filter (Y)`` or ``no observer beats
        the best tuned filter here``.

        Against a reference of uncertainty u, the RMS errors a (observer) and b (filter) are each
        off their true values by at most the reference's own RMS error (the triangle inequality
        of the RMS norm); taking that error as u, the observer is better by at least
        (b - u) / (a + u), and it is said to win only when that bound exceeds 1.
        """
        return self._verdict()

    def _verdict(self):
        obs, bl, u = self.best_observer(), self.best_baseline(), self.uncertainty
        if bl is None:
            return "no tuned filter ran: nothing to compare the observers with"
        b = bl.metrics["rms"]
        if b == 0:
            return (f"no observer beats the best tuned filter here: {bl.name} has no error after t_ss "
                    f"(ratios to it are undefined)")
        if obs is None:
            return f"no observer beats the best tuned filter here ({bl.name}): no observer ran"
        a = obs.metrics["rms"]
        if not a < b:
            return (f"no observer beats the best tuned filter here ({bl.name}, RMS {b:.3g} rad/s; "
                    f"best observer {obs.name}, {a:.3g} rad/s)")
        if u == 0:
            if a == 0:                      # b / a undefined: say what the errors are
                return f"use {obs.name}: no error after t_ss, the best tuned filter ({bl.name}) {b:.3g} rad/s RMS"
            return f"use {obs.name}: {b / a:.3g} x better than the best tuned filter ({bl.name})"
        low = (b - u) / (a + u)
        if low > 1:
            return (f"use {obs.name}: {b / a:.3g} x better than the best tuned filter ({bl.name}) "
                    f"against the reference; at least {low:.3g} x if the reference is off by its "
                    f"uncertainty {u:.3g} rad/s")
        return (f"no observer beats the best tuned filter here beyond the reference's uncertainty "
                f"({obs.name} {a:.3g}, {bl.name} {b:.3g}, uncertainty {u:.3g} rad/s)")

    def rows(self):
        """Plain-data rows (JSON-able): name, kind, params, the metrics, the RMS ratio to the
        best baseline and, against a reference, whether the RMS is within its uncertainty."""
        best, u = self.best_baseline(), self.uncertainty
        out = []
        for e in self.entries:
            r = {"name": e.name, "kind": e.kind, "params": e.params, **e.metrics}
            # undefined (NaN) when the best baseline has no error (the verdict says so)
            r["rms_over_best_baseline"] = (e.metrics["rms"] / best.metrics["rms"]
                                           if best and best.metrics["rms"] > 0 else float("nan"))
            r["within_uncertainty"] = bool(u > 0 and e.metrics["rms"] <= u)
            if e.note:
                r["note"] = e.note
            out.append(r)
        return out

    def header(self):
        """The lines above the table: title, the recording's stamps, what the estimates are
        measured against and its uncertainty."""
        lines = [self.title] if self.title else []
        if "recording" in self.info:
            lines.append(f"recording: {self.info['recording']}")
        if self.ref is not None:
            lines.append(f"reference: {self.ref.label}")
            if not self.ref.is_truth:
                u = self.uncertainty
                first = self.t[self.ref.valid][0]
                lines.append(f"reference uncertainty: {u:.3g} rad/s RMS for t >= {self.t_ss:g} s; an "
                             f"RMS error at most this is marked ({UNRANKED}); convergence times "
                             f"count from t = {first:.6g} s, its first valid sample"
                             + (f" (below {self.level:g} rad/s: not measurable)" if u > self.level else ""))
        return lines

    def table(self):
        """The metrics table as text: the header lines, one line per method (every parameter,
        in full, last), then the verdict line."""
        rows = self.rows()
        w = max([16] + [len(r["name"]) for r in rows])
        head = (f"{'method':{w}s} {'RMS t>=' + format(self.t_ss, 'g') + 's':>12s} "
                f"{'max':>9s} {'settle s':>9s} {'gain':>8s} {'lag ms':>8s} "
                f"{'/best bl':>8s}  parameters")
        lines = self.header() + [
            f"errors in rad/s; settle: the time after which the error's RMS over the last "
            f"{metrics.WINDOW:g} s stays below {self.level:g} rad/s (inf: its noise or bias stays above); "
            f"gain, lag: the fit est(t) = gain qd(t - lag) for t >= {self.t_ss:g} s", head]
        for r in rows:
            par = ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                            for k, v in r["params"].items())
            notes = [n for n in (r.get("note"), UNRANKED if r["within_uncertainty"] else "") if n]
            lines.append(
                f"{r['name']:{w}s} {r['rms']:12.3e} {r['max']:9.2e} "
                f"{r['t_settle']:9.3f} {r['gain']:8.4f} {1e3 * r['lag']:8.3f} "
                f"{r['rms_over_best_baseline']:8.3f}  {par or '-'}" + ("  DIVERGED" if r["diverged"] else "")
                + "".join(f"  ({n})" for n in notes))
        lines.append(self.verdict())
        return "\n".join(lines)

    HIGHLIGHT = 3          # the figures' coloured methods: the best few (and the best filter)

    def shown(self):
        """(highlighted, muted, left out) method names of the figures: the HIGHLIGHT lowest RMS
        (finite, not diverged) and the best tuned filter, coloured; the others thin and gray,
        but the worst baseline (the backward difference, as a rule), which would hide the rest
        on a log axis, and the diverged ones, left out."""
        ok = sorted((e for e in self.entries if np.isfinite(e.metrics["rms"]) and not e.metrics["diverged"]),
                    key=lambda e: e.metrics["rms"])
        best = [e.name for e in ok[:self.HIGHLIGHT]]
        bl = self.best_baseline()
        if bl is not None and bl.name not in best:
            best.append(bl.name)
        baselines_ok = [e for e in ok if e.kind == "baseline"]
        out = [e.name for e in self.entries if e not in ok]
        if len(baselines_ok) > 1:
            out.append(baselines_ok[-1].name)
        return best, [e.name for e in ok if e.name not in best and e.name not in out], out

    def figures(self, out, joint=0, zoom=None):
        """Write to the folder ``out`` ``errors.png`` (||qd - qd_hat|| on a log axis) and
        ``joint<j>.png`` (estimates of ``joint`` j, 0-based as in the file name and the title,
        against the truth or the reference over ``zoom`` = (t0, t1) s, default the first 0.5 s
        after t_ss), the methods as ``shown`` says (the best few highlighted, the worst baseline
        left out), legends beside the axes. Against a reference, only its valid samples are
        drawn. Returns the paths."""
        from .sim import plots
        out = Path(out)
        v = np.ones(len(self.t), bool) if self.ref is None else self.ref.valid
        t, truth = self.t[v], self.truth[v]
        best, muted, left = self.shown()
        est = {e.name: e.est[v] for e in self.entries}
        zoom = zoom or (self.t_ss, min(t[-1], self.t_ss + 0.5))
        m = (t >= zoom[0]) & (t <= zoom[1])
        label = "true" if self.ref is None or self.ref.is_truth else "reference"
        note = f"\n{', '.join(left)} left out" if left else ""
        ylabel = "||qd - qd_hat|| [rad/s]" if label == "true" else "||qd_ref - qd_hat|| [rad/s]"
        name = self.info.get("joint_names", [None] * (joint + 1))[joint]
        return [plots.error_norms(out / "errors.png", t, {k: est[k] - truth for k in best},
                                  levels=(self.level,), ylabel=ylabel, title=self.title + note,
                                  muted={k: est[k] - truth for k in muted}),
                plots.panels(out / f"joint{joint}.png", t[m],
                             [plots.Panel({label: truth[m, joint], **{k: est[k][m, joint] for k in best}},
                                          ylabel=f"qd_{joint} [rad/s]",
                                          muted={k: est[k][m, joint] for k in muted})],
                             title=f"{self.title}\njoint {joint}" + (f" ({name})" if name else "")
                             + note.replace("\n", ", "),
                             cell=(8, 3.4))]


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


def run_observer(spec, Y, U, dt, reference=False, t=None, stepping=None):
    """Estimate (N, nest) of an observer spec over samples Y, U with the default discretisation
    at dt: compiled C (the loop in C) or the numpy reference; (estimate of NaN, message) when
    the observer fails; UnstableDiscretization when no discretisation of it is stable (the
    refusal at dt).

    Two things of a real log the step at the median dt cannot take are handled here, each said
    in the note:

    * a stiff mode that no ``SUBSTEPS_MAX`` sub-steps of dt hold (an identified friction's sharp
      sign on a light wrist, at a log's 5 ms steps): with substeps "auto" and stamps, the
      observer is designed at dt / SUBSTEPS_MAX instead and each interval of the log is split
      into sub-intervals by the C (at most ``SPLIT_MAX`` of them, as any gap beyond dt_max);
    * an interval longer than the observer's ``dt_limit`` (SPLIT_MAX x dt_max: a pause in the
      logging): the observer is reset from the first sample after it, as after an outage.

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec
    Y, U : (N, ny), (N, nu) arrays
        Measurements and inputs.
    dt : float
        Sample time the observer is discretised at (s): the median step of a jittered log.
    reference : bool
        The numpy reference instead of the compiled C.
    t : (N,) array, optional
        The samples' time stamps (s): each step covers the elapsed time since the last sample
        (``run(Y, U, t=t)``; the C splits a gap beyond the declared dt_max); None: every sample
        advances by ``dt``.
    stepping : dict, optional
        ``method``, ``hold``, ``substeps`` of the discretisation (``build``'s options; default
        the default one with substeps "auto").

    Returns
    -------
    (estimate (N, nest), note str)
    """
    from dataclasses import replace

    from ..core.target import SUBSTEPS_MAX, discretization
    from ..discrete.stability import UnstableDiscretization
    from ..pipeline.load import ObserverError
    from .sim.blocks import block
    # the fewest stable sub-steps (xarm7 at 1 kHz needs 6)
    disc = discretization(None, **{"substeps": "auto", **(stepping or {}), "dt": dt})
    notes = []
    try:
        try:
            obs = block(spec, disc, reference=reference)
        except UnstableDiscretization as at_dt:
            if disc.substeps != "auto" or t is None:
                raise                   # stepping the user chose: refused in its own words
            try:
                obs = block(spec, replace(disc, dt=dt / SUBSTEPS_MAX), reference=reference)
            except UnstableDiscretization:
                raise at_dt from None
            notes.append(f"no substeps <= {SUBSTEPS_MAX} of the median step {dt:.3g} s is stable: designed at "
                         f"{obs.dt:.3g} s, each interval split into sub-intervals of at most {obs.dt_range[1]:.3g} s")
        est = np.empty((len(Y), spec.nest))
        cuts = [0, len(Y)] if t is None else _segments(t, obs.dt_limit)
        for a, b in zip(cuts[:-1], cuts[1:]):
            obs.reset(Y[a])
            # each step over the log's own elapsed time (a gap beyond dt_max split inside the C)
            est[a:b] = obs.run(Y[a:b], U[a:b]) if t is None else obs.run(Y[a:b], U[a:b], t=t[a:b])
        if len(cuts) > 2:
            notes.append(f"reset after {len(cuts) - 2} interval(s) longer than {obs.dt_limit:.3g} s "
                         f"(split_max x dt_max)")
        return est, "; ".join(notes)
    except (ObserverError, FloatingPointError) as e:
        return np.full((len(Y), spec.nest), np.nan), str(e)


def _segments(t, limit):
    """Indices [0, k_1, ..., N] cutting the stamps ``t`` (N,) (s) before each sample that
    follows an interval longer than ``limit`` (s)."""
    return [0, *(np.flatnonzero(np.diff(t) > limit) + 1).tolist(), len(t)]


def tune(name, Y, t, truth, t_ss, dt, grid=None, valid=None):
    """The baseline ``name`` run over each value of its ``grid`` (None: baselines.GRIDS) that it
    accepts at this dt; returns (params, estimate (N, n)) of the value with the lowest RMS of
    est - ``truth`` (N, n) after t_ss (s) (the only value for an untuned baseline).

    Parameters
    ----------
    name : str
        A baseline of ``baselines.BASELINES``.
    Y : (N, n) array
        Measured positions (rad).
    t : (N,) array
        Their time stamps (s); each baseline runs with them (``Baseline.run(Y, t=t)``).
    truth : (N, n) array
        The velocity it is tuned on (rad/s): the true one or the zero-phase reference.
    t_ss : float
        Start of the window the RMS is taken over (s).
    dt : float
        The nominal (median) step (s): what the filters are designed at.
    grid : list of float, optional
        Values of the baseline's tuned parameter.
    valid : (N,) bool array, optional
        The samples the RMS is taken over (default all).
    """
    cls = baselines.BASELINES[name]
    values = [None] if cls.tuned is None else (grid or baselines.GRIDS[name])
    v = slice(None) if valid is None else valid
    best = None
    for value in values:
        try:
            b = cls(Y.shape[1], dt) if value is None else cls(Y.shape[1], dt, **{cls.tuned: value})
        except ValueError:
            continue                    # a value this sample time cannot take (cutoff >= Nyquist)
        b.reset(Y[0])
        est = b.run(Y, t=t)
        r = metrics.rms_after(t[v], est[v] - truth[v], t_ss)
        if best is None or (np.isfinite(r) and not r >= best[0]):
            best = (r, b.params, est)
    return best[1], best[2]


def compare(rec, robot, families=DEFAULT_FAMILIES, design=None, t_ss=None, level=1e-2,
            baseline_names=None, reference=False, title="", ref_cutoff=smoothing.DEFAULT_CUTOFF,
            progress=False, stepping=None):
    """Observers, tuned baselines and the robot's own velocity signal on one recorded run.

    Parameters
    ----------
    rec : codegen.logs.recording.Recording
        Time stamps (jitter and gaps allowed), measured positions (what the observers receive),
        applied torques and, when known, the true velocities and the robot's velocity signal.
    robot : models.RobotModel
        The nominal model the observers are built on.
    families : sequence of str
        Observer families (``codegen.families.observers.FAMILIES``) with y = q, u = tau, est = qd_hat
        (an elastic robot: y = link q, u = motor torque, the link velocity of its state estimate;
        default ELASTIC_FAMILIES),
        each optionally with given build arguments, ``"reduced_order:k0=25"`` (see
        ``parse_observer``).
    design : dict, optional
        Keyword arguments of ``observers.build`` for every family (design inputs).
    t_ss : float, optional
        Start of the steady-state window (s); default the middle of the run.
    level : float
        Convergence threshold (rad/s).
    baseline_names : sequence of str, optional
        Default: all of ``codegen.evaluate.baselines.BASELINES``.
    reference : bool
        Run the observers with the numpy reference instead of the compiled C.
    title : str
        Title of the table and figures.
    ref_cutoff : float
        Cut-off (Hz) of the zero-phase reference used when ``rec`` has no true velocity.
    progress : bool
        A progress bar over the methods on stderr (tqdm).
    stepping : dict, optional
        ``method``, ``hold``, ``substeps`` the observers step with (``run_observer``).

    Returns
    -------
    Comparison
    """
    from tqdm import tqdm

    from ..families import observers
    if families is DEFAULT_FAMILIES and hasattr(robot, "state_names"):
        families = ELASTIC_FAMILIES                   # an elastic robot's log
    if list(rec.joint_names) != list(robot.joint_names):
        raise ValueError(f"rec: joints {rec.joint_names} differ from the robot's {robot.joint_names}")
    t, Y, U, dt = rec.t, rec.q, rec.tau, rec.dt
    if not np.any(np.ptp(Y, axis=0) > 0):   # before the (slow) runs: nothing to estimate
        raise ValueError(f"rec: the robot does not move (q constant on every joint over the {len(t)} samples): "
                         "its velocity is 0, which any difference filter gives exactly, so the methods cannot "
                         "be compared; record a run with motion")
    t_ss = float(t[0] + (t[-1] - t[0]) / 2 if t_ss is None else t_ss)
    ref = reference_of(rec, ref_cutoff)
    parsed = [(item, *parse_observer(item)) for item in families]
    bad = [fam for _, fam, _ in parsed if fam not in observers.FAMILIES]
    if bad:                                 # every name checked before the slow part
        raise ValueError(f"observers: unknown family {bad[0]!r}; known: {', '.join(observers.FAMILIES)}")
    names = list(baseline_names or baselines.BASELINES)
    unknown = [b for b in names if b not in baselines.BASELINES]
    if unknown:
        raise ValueError(f"baselines: unknown {unknown[0]!r}; known: {', '.join(baselines.BASELINES)}")
    entries = []
    bar = tqdm(total=len(parsed) + len(names) + (rec.qdm is not None), desc="compare", unit="method",
               file=sys.stderr, disable=not progress, leave=False)
    with bar:
        for item, fam, given in parsed:
            bar.set_postfix_str(item)
            inputs, designed_for = {**design_for(fam, design), **given}, ""
            try:
                try:
                    spec = observers.build(fam, robot, **inputs)
                except ValueError:
                    # an exact sensor (a simulation's q) that a family cannot design for (the
                    # Kalman gains divide by the noise): its default encoder, said in the row
                    if inputs.get("quantization") != 0.0 or inputs.get("noise") != 0.0:
                        raise
                    spec = observers.build(fam, robot, **{k: v for k, v in inputs.items()
                                                          if k not in ("quantization", "noise")})
                    designed_for = "designed for the default encoder: the exact sensor gives it no noise"
            except TypeError as e:
                raise ValueError(f"observers: {item!r}: {e}") from None
            slots = _link_velocity_slots(spec, robot)
            if slots is None or spec.ny != robot.n:
                raise ValueError(f"families: {fam!r} does not estimate qd from q (ny = {spec.ny}, "
                                 f"est = {', '.join(spec.est_names)})")
            full, note = run_observer(spec, Y, U, dt, reference, t=t, stepping=stepping)
            est = full[:, slots]
            hits = saturated_samples(full, spec)        # samples with q̇̂ beyond the model's bound
            note = "; ".join(filter(None, [designed_for, note, hits and f"{hits} samples at the velocity bound"]))
            params = {k: float(v) for k, v in zip(spec.p_names, spec.p_default)}
            entries.append(Entry(item, "observer", params, est, measure(ref, t, est, t_ss, level), note))
            bar.update()
        for name in names:
            bar.set_postfix_str(name)
            params, est = tune(name, Y, t, ref.qd, t_ss, dt, valid=ref.valid)
            entries.append(Entry(name, "baseline", params, est, measure(ref, t, est, t_ss, level)))
            bar.update()
        if rec.qdm is not None:
            bar.set_postfix_str("qdm")
            entries.append(Entry(SIGNAL, "signal", {"columns": "qdm_<joint>"}, rec.qdm,
                                 measure(ref, t, rec.qdm, t_ss, level)))
            bar.update()
    return Comparison(t=t, truth=ref.qd, entries=entries, t_ss=t_ss, level=level, title=title,
                      info={"recording": rec.describe(), "joint_names": list(robot.joint_names)}, ref=ref)


ELASTIC_FAMILIES = ("ciccarella_germani",)      # the default of an elastic robot: y = link q, u = tau


def _link_velocity_slots(spec, robot):
    """The estimate's slots of the link velocities, in joint order, by name: ``qd_hat_<joint>``
    (extended_state appends tau_d_hat), or an elastic observer's ``q1d_<joint>_hat`` (its state
    estimate x = [q1; q1'; q2; q2'], docs/papers/seed004.md §6); None when it has none."""
    try:
        return velocity_slots(spec.est_names, robot.joint_names)
    except ValueError:
        names = list(spec.est_names)
        link = [f"q1d_{j}_hat" for j in robot.joint_names]
        return [names.index(s) for s in link] if all(s in names for s in link) else None


def robot_by_name(name):
    """A catalog robot, or a URDF robot when ``name`` is a path to a .urdf file; ValueError
    naming the valid choices otherwise."""
    from models import load_robot, names
    if name in names():
        return load_robot(name)
    if str(name).endswith(".urdf") and Path(name).is_file():
        return load_robot(urdf=name)
    raise ValueError(f"unknown robot {name!r}; valid: {', '.join(names())} or a path to a .urdf file")


def design_inputs(quantization=0.0, noise=0.0, uncertainty=0.0, torque_uncertainty=None):
    """Keyword arguments of ``observers.build`` describing the sensor (``quantization`` step and
    Gaussian ``noise`` std, rad), the relative model ``uncertainty`` and the
    ``torque_uncertainty`` (N m, a number or one per joint; None: not stated) (the noise-aware
    design of codegen.families.design.noise). quantization and noise both None: the sensor is not
    stated, the design assumes its default encoder; 0 and 0: a noise-free sensor, the guarantee
    gains."""
    sensor = ({} if quantization is None and noise is None else
              {"quantization": float(quantization or 0.0), "noise": float(noise or 0.0)})
    torque = {} if torque_uncertainty is None else {"torque_uncertainty": torque_uncertainty}
    return {**sensor, "uncertainty": float(uncertainty or 0.0), **torque}


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
