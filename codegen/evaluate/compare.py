"""Observers against the baselines a user would otherwise write, on one recorded run.

    rec, clock = codegen.logs.recording.read_log("log.csv", robot.joint_names)   # on its sample clock
    cmp = compare(rec, robot, clock=clock)  # observers compiled (loop in C), everything tuned on the log
    print(cmp.table())                      # ends with the verdict line
    cmp.figures(out_dir); cmp.write_estimates(out_dir / "estimates.csv", clock)

The log speaks for itself: its sample clock is rebuilt (codegen.logs.clock), its noise measured
(codegen.logs.noise), and, with ``tune="log"`` (the default), every family of ``families`` is
designed for the measured sensor and its bandwidth chosen on the log without truth, by forward
validation (codegen.logs.tune): each estimate is scored against the velocity the samples after
it imply, which ranks estimators as their true error does. kalman_model is tried without and with
the model (the torque uncertainty measured on the log, unless stated) and the better kept. Every
baseline of ``codegen.evaluate.baselines`` has its own parameter chosen the same way. The
observers are compiled at the log's (median) sample time with the default discretisation and run
over the samples at their times (``run_observer``). The robot's own velocity signal
(``qdm_<joint>`` columns), when logged, is one more row. ``tune="none"`` keeps the designed gains
and tunes the baselines against the reference, as before the log was read as a measurement.

What the estimates are measured against (``Reference``): the true velocity when the recording
has it (a simulation); otherwise, as on every real log, the offline zero-phase reference of
``codegen.logs.reference`` (4th-order Butterworth forward and backward at each joint's measured
motion band, or ``ref_cutoff`` Hz, on a uniform resampling of the clock), on the samples away
from its edges. Its uncertainty u (RMS of its spread between cutoff/sqrt 2 and cutoff sqrt 2) is
reported; an estimate whose RMS error against it is at most u cannot be ranked. Each row also
carries the forward validation's own estimate of its RMS error (``validation_rms``), which needs
no reference. Measures are those of ``codegen.evaluate.metrics``.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import baselines, metrics
from ..logs import tune as tuning
from ..logs.reference import Reference, reference_of
from ..core.estimator import velocity_slots
from ..verify.measure import saturated_samples

DEFAULT_FAMILIES = ("kalman_model", "reduced_order_switched", "reduced_order", "extended_state", "nicosia_tomei")
SIGNAL = "robot's velocity signal"          # the row of the qdm_<joint> columns
UNRANKED = "within the reference's uncertainty: cannot be ranked"
# A method failed (shown FAILED with the reason, never ranked, recommended nor highlighted) when its
# estimate is not finite, has left the scale of the motion (metrics.diverged), sits at the velocity
# bound on more than FAIL_AT_BOUND of the samples (its model evaluated at the bound, not at its
# estimate: the estimate has run away and only the clamp holds it, codegen.families.observers._bound),
# or has an RMS error above FAIL_RATIO x the median of the others' and above the convergence level
# (an error below the level is converged by the table's own measure): an estimate two orders of
# magnitude off has lost the motion (a restart missed after a pause: 7.1 rad/s against 0.03); the
# worst method that tracks, the untuned backward difference, is 43 x the median of the others on
# seed000_2r's 4 s test log (a 2^16 encoder at 1 kHz: its noise, 0.064 rad/s against 1.5e-3).
FAIL_AT_BOUND = 0.01
SAME_ESTIMATE = 1e-3       # two estimates closer than this x the RMS error are the same (one verdict)
CAUTION = 0.9              # a gain tuned above this part of its stable bound is flagged (little margin)
FAIL_RATIO = 100.0
PARAMS_SHOWN = 8           # a row with more parameters shows only those a user sets (``shown_params``)


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
    variant: str | None = None
    tuned: object = None                  # codegen.logs.tune.Tuned, when tuned on the log
    build: dict | None = None             # an observer's build arguments (what rebuilds its spec)


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

    def failure(self, e):
        """Why the entry ``e`` failed (the rule of ``FAIL_AT_BOUND`` and ``FAIL_RATIO``), or "" when
        it did not: a non-finite estimate, diverged (metrics.diverged), at the velocity bound on
        more than FAIL_AT_BOUND of the samples, or an RMS error above FAIL_RATIO x the median of
        the others' (finite ones) and above the convergence level (an error below it is converged
        by the table's own measure); or its estimate that of a method which failed (within
        SAME_ESTIMATE of its RMS error): the same estimate, the same verdict."""
        own = self._own_failure(e)
        if own or not np.isfinite(e.metrics["rms"]):
            return own
        for o in self.entries:
            if o is not e and np.isfinite(o.metrics["rms"]) and self._own_failure(o):
                gap = np.sqrt(np.nanmean(np.sum((o.est - e.est) ** 2, axis=1)))
                if gap <= SAME_ESTIMATE * e.metrics["rms"]:
                    return f"its estimate is {o.name}'s, which failed: {self._own_failure(o)}"
        return ""

    def _own_failure(self, e):
        """``failure``'s rules on ``e`` alone."""
        rms = e.metrics["rms"]
        if not (np.isfinite(rms) and np.all(np.isfinite(e.est))):
            return "non-finite estimate"
        if e.metrics["diverged"]:
            return "diverged: its error left the scale of the motion"
        hits, N = int(e.metrics.get("at_bound", 0)), len(self.t)
        if hits > FAIL_AT_BOUND * N:
            return (f"at the velocity bound on {hits} of {N} samples ({100 * hits / N:.3g} % > "
                    f"{100 * FAIL_AT_BOUND:g} %): its model saw the bound, not the estimate")
        others = [o.metrics["rms"] for o in self.entries if o is not e and np.isfinite(o.metrics["rms"])]
        if others and rms > max(FAIL_RATIO * np.median(others), self.level):
            return (f"RMS {rms:.3g} rad/s > {FAIL_RATIO:g} x the median of the others' "
                    f"({np.median(others):.3g}): it lost the motion")
        return ""

    def ok(self):
        """The entries that did not fail (``failure``), in table order."""
        return [e for e in self.entries if not self.failure(e)]

    def _best(self, kind):
        ok = [e for e in self.ok() if e.kind == kind]
        return min(ok, key=lambda e: e.metrics["rms"]) if ok else None

    def best_baseline(self):
        """The baseline entry with the lowest RMS after t_ss (failed ones excluded: ``failure``)."""
        return self._best("baseline")

    def best_observer(self):
        """The observer entry with the lowest RMS after t_ss (failed ones excluded: ``failure``)."""
        return self._best("observer")

    def _failed(self, kind):
        """'' or ' (N failed: names)' for the entries of ``kind`` that failed."""
        bad = [e.name for e in self.entries if e.kind == kind and self.failure(e)]
        return f" ({len(bad)} failed: {', '.join(bad)})" if bad else ""

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
            return f"no tuned filter ran{self._failed('baseline')}: nothing to compare the observers with"
        b = bl.metrics["rms"]
        if b == 0:
            return (f"no observer beats the best tuned filter here: {bl.name} has no error after t_ss "
                    f"(ratios to it are undefined)")
        if obs is None:
            return f"no observer beats the best tuned filter here ({bl.name}): no observer ran{self._failed('observer')}"
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
        return (f"{obs.name} ({a:.3g} rad/s) and {bl.name} ({b:.3g}) cannot be ranked: the reference may be "
                f"off by its uncertainty {u:.3g} rad/s, which leaves the ratio at least {low:.3g} (not above 1)")

    def ranking(self):
        """The verdict as data: the best observer and filter (not failed), their RMS errors, the
        reference's uncertainty u, the ratio's lower bound (b - u) / (a + u) (``verdict``) and
        ``within_uncertainty``: the two cannot be ranked (the bound not above 1; False when u is 0)."""
        obs, bl, u = self.best_observer(), self.best_baseline(), self.uncertainty
        if obs is None or bl is None:
            return {"observer": obs and obs.name, "baseline": bl and bl.name, "within_uncertainty": False}
        a, b = obs.metrics["rms"], bl.metrics["rms"]
        low = (b - u) / (a + u) if a + u > 0 else float("inf")
        return {"observer": obs.name, "baseline": bl.name, "rms_observer": a, "rms_baseline": b,
                "uncertainty": u, "ratio_at_least": low, "within_uncertainty": bool(u > 0 and a < b and low <= 1)}

    def rows(self):
        """Plain-data rows (JSON-able): name, kind, params (every runtime parameter), the variant,
        the metrics, the RMS ratio to the best baseline, against a reference whether the RMS is
        within its uncertainty, and ``failed``: why the method failed ("" when it did not)."""
        best, u = self.best_baseline(), self.uncertainty
        out = []
        for e in self.entries:
            r = {"name": e.name, "kind": e.kind, "params": e.params, **e.metrics, "failed": self.failure(e)}
            if e.variant is not None:
                r["variant"] = e.variant
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
        if "clock" in self.info:
            lines.append(self.info["clock"])
        if "recording" in self.info:
            lines.append(f"recording: {self.info['recording']}")
        lines += self.info.get("noise", [])
        if self.info.get("tune") == "log":
            v = self.info.get("validation", {})
            lines.append(f"gains tuned on the log without truth: forward validation (each estimate against the "
                         f"velocity the next {v.get('window')} samples imply; est. RMS = its implied RMS error)")
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
        """The metrics table as text: the header lines, one line per method (the parameters a user
        sets last, ``shown_params``; every one in ``rows``), a failed method marked FAILED with the
        reason and without a ratio, then the verdict line."""
        rows = self.rows()
        w = max([16] + [len(r["name"]) for r in rows])
        head = (f"{'method':{w}s} {'RMS t>=' + format(self.t_ss, 'g') + 's':>12s} "
                f"{'max':>9s} {'settle s':>9s} {'gain':>8s} {'lag ms':>8s} "
                f"{'/best bl':>8s}  parameters")
        lines = self.header() + [
            f"errors in rad/s; settle: the time after which the error's RMS over the last "
            f"{metrics.WINDOW:g} s stays below {self.level:g} rad/s (inf: its noise or bias stays above); "
            f"gain, lag: the fit est(t) = gain qd(t - lag) for t >= {self.t_ss:g} s", head]
        for e, r in zip(self.entries, rows):
            par = ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                            for k, v in shown_params(e).items())
            notes = [n for n in (r.get("note"), UNRANKED if r["within_uncertainty"] and not r["failed"] else "")
                     if n]
            ratio = f"{'FAILED':>8s}" if r["failed"] else f"{r['rms_over_best_baseline']:8.3f}"
            lines.append(
                f"{r['name']:{w}s} {r['rms']:12.3e} {r['max']:9.2e} "
                f"{r['t_settle']:9.3f} {r['gain']:8.4f} {1e3 * r['lag']:8.3f} "
                f"{ratio}  {par or '-'}" + (f"  FAILED: {r['failed']}" if r["failed"] else "")
                + "".join(f"  ({n})" for n in notes))
        lines.append(self.verdict())
        return "\n".join(lines)

    HIGHLIGHT = 3          # the figures' coloured methods: the best few (and the best filter)

    def shown(self):
        """(highlighted, muted, left out) method names of the figures: the HIGHLIGHT lowest RMS
        (not failed: ``failure``) and the best tuned filter, coloured; the others thin and gray,
        but the worst baseline (the backward difference, as a rule), which would hide the rest
        on a log axis, and the failed ones, left out."""
        ok = sorted(self.ok(), key=lambda e: e.metrics["rms"])
        best = [e.name for e in ok[:self.HIGHLIGHT]]
        bl = self.best_baseline()
        if bl is not None and bl.name not in best:
            best.append(bl.name)
        baselines_ok = [e for e in ok if e.kind == "baseline"]
        out = [e.name for e in self.entries if e not in ok]
        if len(baselines_ok) > 1:
            out.append(baselines_ok[-1].name)
        return best, [e.name for e in ok if e.name not in best and e.name not in out], out

    def write_estimates(self, path, clock=None):
        """``path`` (CSV, written atomically): the log's ``t`` and, for every method, one column per
        joint ``<method>.qd_<joint>`` at the log's rows (a row dropped as a repeat of the previous one
        carries the estimate of the row it repeats); ``clock`` (codegen.logs.clock.Clock) maps the
        rows, None: the estimates' own rows. Returns the path."""
        from ..core.columns import write_columns
        if clock is None:
            t, rows = self.t, np.arange(len(self.t))
        else:
            t, rows = clock.stamps, clock.row_of()
        joints = self.info.get("joint_names") or [str(j) for j in range(self.truth.shape[1])]
        cols = {"t": t}
        for e in self.entries:
            for j, name in enumerate(joints):
                cols[f"{e.name}.qd_{name}"] = e.est[rows, j]
        return write_columns(path, cols)

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


def shown_params(e):
    """The parameters of the Entry ``e`` the table shows (every one is in ``Comparison.rows``): all
    of them when they are at most PARAMS_SHOWN; otherwise those a user sets: the bandwidth a log
    tunes (the family's ``TUNE``, codegen.logs.tune.bandwidth), the variant, the torque
    uncertainty the design used (N m per joint) and how many more there are (a model-based
    Kalman filter's fitted poles and partial-fraction coefficients)."""
    if len(e.params) <= PARAMS_SHOWN:
        return dict(e.params) if e.variant is None else {**e.params, "variant": e.variant}
    family = parse_observer(e.name)[0]
    out = {k: e.params[k] for k in tuning.bandwidth(family, list(e.params))}
    if e.variant is not None:
        out["variant"] = e.variant
    used = (e.build or {}).get("torque_uncertainty")
    if used is not None:
        out["torque_uncertainty"] = "[" + ", ".join(f"{v:.3g}" for v in np.atleast_1d(used)) + "]"
    out["more"] = f"{len(e.params) - len(set(out) & set(e.params))} in compare.json"
    return out


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


def observer_block(spec, dt, reference=False, stamped=True, stepping=None):
    """(block, notes): an observer spec stepped at dt with the default discretisation, compiled
    C (or the numpy reference), with the fallback a real log's stiff mode needs: when no
    ``SUBSTEPS_MAX`` sub-steps of dt hold it (an identified friction's sharp sign on a light wrist,
    at a log's 5 ms steps) and the log has stamps (``stamped``), the observer is designed at
    dt / SUBSTEPS_MAX and each interval is split by the C (at most ``SPLIT_MAX`` sub-intervals, as
    any gap beyond dt_max). UnstableDiscretization when no discretisation of it is stable (the
    refusal at dt). ``stepping``: ``method``, ``hold``, ``substeps`` (default the default
    discretisation with substeps "auto")."""
    from dataclasses import replace

    from ..core.target import SUBSTEPS_MAX, discretization
    from ..discrete.stability import UnstableDiscretization
    from .sim.blocks import block
    # the fewest stable sub-steps (xarm7 at 1 kHz needs 6)
    disc = discretization(None, **{"substeps": "auto", **(stepping or {}), "dt": dt})
    try:
        return block(spec, disc, reference=reference), []
    except UnstableDiscretization as at_dt:
        if disc.substeps != "auto" or not stamped:
            raise                   # stepping the user chose: refused in its own words
        try:
            obs = block(spec, replace(disc, dt=dt / SUBSTEPS_MAX), reference=reference)
        except UnstableDiscretization:
            raise at_dt from None
    return obs, [f"no substeps <= {SUBSTEPS_MAX} of the median step {dt:.3g} s is stable: designed at "
                 f"{obs.dt:.3g} s, each interval split into sub-intervals of at most {obs.dt_range[1]:.3g} s"]


def run_observer(spec, Y, U, dt, reference=False, t=None, stepping=None, p=None):
    """Estimate (N, nest) of an observer spec over samples Y, U with the default discretisation
    at dt: compiled C (the loop in C) or the numpy reference; (estimate of NaN, message) when
    the observer fails; UnstableDiscretization when no discretisation of it is stable (the
    refusal at dt).

    Two things of a real log the step at the median dt cannot take are handled here, each said
    in the note: a stiff mode (``observer_block``'s fallback), and an interval longer than the
    observer's ``dt_limit`` (SPLIT_MAX x dt_max: a pause in the logging), after which the observer
    is reset from the first sample, as after an outage (codegen.logs.tune.run_over).

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
    p : (np,) array, optional
        Runtime parameters (checked stable); default the designed ones.

    Returns
    -------
    (estimate (N, nest), note str)
    """
    from ..pipeline.load import ObserverError
    obs, notes = observer_block(spec, dt, reference, stamped=t is not None, stepping=stepping)
    try:
        if p is not None:
            obs.check_params(p)
        if t is None:
            obs.reset(Y[0])
            if p is not None:
                obs.params = p
            return obs.run(Y, U), "; ".join(notes)
        est, resets = _run_checked(obs, p, Y, U, t)
        if resets:
            notes.append(f"reset after {resets} interval(s) longer than {obs.dt_limit:.3g} s (split_max x dt_max)")
        return est, "; ".join(notes)
    except (ObserverError, FloatingPointError) as e:
        return np.full((len(Y), spec.nest), np.nan), str(e)


def _run_checked(obs, p, Y, U, t):
    """(estimate, resets): ``obs`` over the log with the (checked) parameters ``p`` (None: its
    own), reset after every interval beyond its dt_limit; errors propagate."""
    cuts = tuning.segments(t, obs.dt_limit)
    est = np.empty((len(Y), obs.nest))
    for a, b in zip(cuts[:-1], cuts[1:]):
        obs.reset(Y[a], p=p)
        est[a:b] = obs.run(Y[a:b], U[a:b], t=t[a:b])
    return est, len(cuts) - 2


def dt_limit(dt):
    """The longest interval (s) a method crosses without a restart on a log of median step dt:
    SPLIT_MAX x the default dt_max (2 dt), the observers' own limit (``CompiledObserver.dt_limit``)."""
    from ..core.target import SPLIT_MAX
    return SPLIT_MAX * 2.0 * dt


def tune_on_reference(name, Y, t, truth, t_ss, dt, grid=None, valid=None):
    """The baseline ``name`` run over each value of its ``grid`` (None: baselines.GRIDS) that it
    accepts at this dt; returns (params, estimate (N, n)) of the value with the lowest RMS of
    est - ``truth`` (N, n) after t_ss (s) (the only value for an untuned baseline). Tuned against
    a reference (``compare(..., tune="reference")``); ``tune_baseline`` tunes without one.

    Parameters
    ----------
    name : str
        A baseline of ``baselines.BASELINES``.
    Y : (N, n) array
        Measured positions (rad).
    t : (N,) array
        Their time stamps (s); each baseline runs with them (``Baseline.run(Y, t=t)``), restarted
        after an interval longer than ``dt_limit(dt)`` as the observers are.
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
        est = tuning.run_over(b, Y, None, t, dt_limit(dt))[0]
        r = metrics.rms_after(t[v], est[v] - truth[v], t_ss)
        if best is None or (np.isfinite(r) and not r >= best[0]):
            best = (r, b.params, est)
    return best[1], best[2]


def baseline_options(name, noise):
    """The options of baseline ``name`` fixed by the log's measured ``noise`` (codegen.logs.noise):
    the Kalman filter's measurement variance r (the joints' mean sigma^2)."""
    return {"r": float(np.mean(noise.sigma ** 2))} if name == "kalman" and noise is not None else {}


def tune_baseline(name, Y, t, dt, val, noise=None, t_from=None):
    """(params, estimate (N, n), Tuned or None): the baseline ``name`` with its tuned parameter
    chosen on the log without truth (codegen.logs.tune: forward validation ``val``), searched in
    log scale over the span of its grid (baselines.GRIDS); restarted after intervals longer than
    ``dt_limit(dt)``. ``Y`` (N, n) the log's positions (rad) at its times ``t`` (N,) (s), ``dt`` its
    median step; ``noise``: the log's measured noise (the Kalman filter's r); rows scored from
    ``t_from`` (s; default after the first 5 % of the log)."""
    cls = baselines.BASELINES[name]
    extra = baseline_options(name, noise)
    limit = dt_limit(dt)
    t_from = float(t[0] + 0.05 * (t[-1] - t[0])) if t_from is None else t_from

    def run(value):
        b = cls(Y.shape[1], dt, **extra) if value is None else cls(Y.shape[1], dt, **{cls.tuned: value}, **extra)
        return b, tuning.run_over(b, Y, None, t, limit)[0]

    if cls.tuned is None:
        b, est = run(None)
        return b.params, est, None
    grid = baselines.GRIDS[name]

    def score(value):
        try:
            return val.score(run(value)[1], t_from)
        except ValueError:
            return math.inf                 # a value this sample time cannot take (cutoff >= Nyquist)
    lo, hi = min(grid), max(grid)
    found = tuning.search(score, math.sqrt(lo * hi), lo, hi, grid=max(9, int(round(math.log10(hi / lo))) + 1))
    b, est = run(found.best)
    return b.params, est, tuning.Tuned(name, {cls.tuned: found.best}, found.best, found.score,
                                       val.rms(est, t_from), found.tried)


def _build(fam, robot, inputs, item):
    """(spec, note): ``observers.build(fam, robot, **inputs)``, or, for an exact sensor a family
    cannot design for (the Kalman gains divide by the noise), its default encoder, said in the note."""
    from ..families import observers
    try:
        try:
            return observers.build(fam, robot, **inputs), ""
        except ValueError:
            if inputs.get("quantization") != 0.0 or inputs.get("noise") != 0.0:
                raise
            return (observers.build(fam, robot, **{k: v for k, v in inputs.items() if k not in ("quantization", "noise")}),
                    "designed for the default encoder: the exact sensor gives it no noise")
    except TypeError as e:
        raise ValueError(f"observers: {item!r}: {e}") from None


def _variants(fam, robot, inputs, item, noise):
    """The (inputs, spec, note) a family is tried as: its build with ``inputs``; and, when it has a model and a
    model-free variant (its build takes ``variant``), no torque uncertainty is stated and the log
    measured one, also the model variant with the measured torque uncertainty (the better of the
    two on the log is kept)."""
    import importlib
    import inspect
    out = [(inputs, *_build(fam, robot, inputs, item))]
    takes = inspect.signature(importlib.import_module(f"codegen.families.observers.{fam}").build).parameters
    if ("variant" in takes and "torque_uncertainty" in takes and "torque_uncertainty" not in inputs
            and noise is not None and noise.torque_uncertainty is not None):
        with_model = {**inputs, "torque_uncertainty": [float(v) for v in noise.torque_uncertainty]}
        out.append((with_model, *_build(fam, robot, with_model, item)))
    return out


def _observer_entry(item, fam, given, robot, rec, design, noise, val, tune_on, reference, stepping, ref,
                    t_ss, level, progress):
    """The Entry of one family on the log: built (designed for the log's sensor), tuned on it
    when ``tune_on`` (the better variant kept), run."""
    from ..discrete.stability import UnstableDiscretization
    from ..pipeline.load import ObserverError
    t, Y, U, dt = rec.t, rec.q, rec.tau, rec.dt
    inputs = {**design_for(fam, design), **given}
    candidates = []
    for used, spec, designed_for in _variants(fam, robot, inputs, item, noise if tune_on else None):
        slots = _link_velocity_slots(spec, robot)
        if slots is None or spec.ny != robot.n:
            raise ValueError(f"families: {fam!r} does not estimate qd from q (ny = {spec.ny}, "
                             f"est = {', '.join(spec.est_names)})")
        tuned, p = (None, np.array(spec.p_default, dtype=float))
        try:
            obs, notes = observer_block(spec, dt, reference, stamped=True, stepping=stepping)
        except UnstableDiscretization as e:     # this family (variant) cannot run on the log: a failure, not the run's
            if any(v is not None for v in (stepping or {}).values()):
                raise                           # the stepping the user chose: refused in its own words
            candidates.append((np.inf, spec, p, np.full((len(Y), spec.nest), np.nan), slots, None,
                               [designed_for, f"no stable discretisation on this log's steps: {e}"], used))
            continue
        if tune_on and not given:
            tuned, p = tuning.tune_observer(obs, spec, fam, Y, U, t, val, obs.dt_limit, slots,
                                            progress=progress, t_from=t_ss)
        try:
            try:
                full, resets = _run_checked(obs, p, Y, U, t)
            except ValueError as e:             # a tuned value the full stability check refuses
                notes.append(f"tuned parameters refused ({e}); the designed ones")
                tuned, p = None, np.array(spec.p_default, dtype=float)
                full, resets = _run_checked(obs, p, Y, U, t)
            if resets:
                notes.append(f"reset after {resets} interval(s) longer than {obs.dt_limit:.3g} s")
        except (ObserverError, FloatingPointError) as e:
            full, notes = np.full((len(Y), spec.nest), np.nan), notes + [str(e)]
        J = tuned.score if tuned is not None else val.score(full[:, slots], t_ss)
        candidates.append((J, spec, p, full, slots, tuned, [designed_for] + notes, used))
    J, spec, p, full, slots, tuned, notes, used = min(candidates, key=lambda c: c[0] if np.isfinite(c[0]) else np.inf)
    if len(candidates) > 1 and np.isfinite(J):
        other = [c for c in candidates if c[1] is not spec][0]
        notes.append(f"variant {spec.variant} (forward-validation error {math.sqrt(J):.3g} rad/s; "
                     f"{other[1].variant}: {math.sqrt(other[0]):.3g})")
    if tuned is not None and tuned.params:
        notes.append("tuned on the log: " + ", ".join(f"{k} = {v:.4g}" for k, v in tuned.params.items()))
        notes += _margin(obs, tuned)
    elif tuned is not None:
        notes.append(f"not tuned, its designed gains: {tuned.note or 'no candidate scored'}")
    est = full[:, slots]
    hits = saturated_samples(full, spec)        # samples with q̇̂ beyond the model's bound
    note = "; ".join(filter(None, notes + [hits and f"{hits} samples at the velocity bound"]))
    params = {k: float(v) for k, v in zip(spec.p_names, p)}
    m = measure(ref, t, est, t_ss, level)
    m["at_bound"] = hits
    m["validation_rms"] = val.rms(est, t_ss)
    return Entry(item, "observer", params, est, m, note, variant=spec.variant, tuned=tuned, build=used)


def _margin(obs, tuned):
    """A caution per tuned gain at more than CAUTION of its recorded stable bound (the observer's
    metadata, codegen.discrete.stability: the largest value stable with the others at their
    defaults), or tuned onto the bound by the stability check: little margin for a longer dt."""
    gains = ((getattr(obs, "meta", None) or {}).get("stability") or {}).get("gains") or {}
    out = []
    for k, v in tuned.params.items():
        top = [g["max_stable"] for g in gains.values() if list(g.get("slots", [])) == [k]
               and g.get("max_stable") and g.get("limit_found")]
        if top and v > CAUTION * top[0]:
            out.append(f"caution: {k} = {v:.4g} is {100 * v / top[0]:.0f} % of its stable bound {top[0]:.4g}: "
                       "little margin for a longer dt")
        elif "at the stability bound" in (tuned.note or ""):
            out.append(f"caution: {k} = {v:.4g} tuned onto its stability bound: little margin for a longer dt")
    return out


def compare(rec, robot, families=DEFAULT_FAMILIES, design=None, t_ss=None, level=1e-2,
            baseline_names=None, reference=False, title="", ref_cutoff=None, progress=False, stepping=None,
            tune="log", clock=None, noise=None, jobs=None):
    """Observers, baselines and the robot's own velocity signal on one recorded run, every gain
    and every baseline's parameter chosen on the log without truth (``tune="log"``).

    Parameters
    ----------
    rec : codegen.logs.recording.Recording
        On its sample clock (codegen.logs.clock: a logger's receive times rebuilt on the robot's
        tick): measured positions (what the observers receive), applied torques and, when known,
        the true velocities and the robot's velocity signal.
    robot : models.RobotModel
        The nominal model the observers are built on.
    families : sequence of str
        Observer families (``codegen.families.observers.FAMILIES``) with y = q, u = tau, est = qd_hat
        (an elastic robot: y = link q, u = motor torque, the link velocity of its state estimate;
        default ELASTIC_FAMILIES),
        each optionally with given build arguments, ``"reduced_order:k0=25"`` (see
        ``parse_observer``; given gains are not tuned).
    design : dict, optional
        Keyword arguments of ``observers.build`` for every family (design inputs); a sensor not
        stated (no quantization nor noise) is the one measured on the log (``noise``).
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
    ref_cutoff : float, optional
        Cut-off (Hz) of the zero-phase reference used when ``rec`` has no true velocity; default
        each joint's measured motion band (codegen.logs.noise).
    progress : bool
        A progress bar over the methods on stderr (codegen.core.progress: lines off a terminal).
    stepping : dict, optional
        ``method``, ``hold``, ``substeps`` the observers step with (``run_observer``).
    tune : {"log", "none", "reference"}
        log: every family's bandwidth and every baseline's parameter chosen on the log by forward
        validation (codegen.logs.tune), without truth, and kalman_model's variant (with the
        model or without) by the same criterion; none: the designed gains, the baselines tuned
        against the reference (or the truth) as a user with the truth would; reference: the
        same for the baselines only.
    clock : codegen.logs.clock.Clock, optional
        The clock ``rec`` is on (its line opens the header).
    noise : codegen.logs.noise.Noise, optional
        The log's measured noise (default measured here).
    jobs : int, optional
        Families built, compiled, tuned and run in this many processes at once (default one per
        core; 1: in this process).

    Returns
    -------
    Comparison
    """
    from ..core.progress import bar as progress_bar

    from ..families import observers
    from ..logs import noise as noise_of
    if tune not in ("log", "none", "reference"):
        raise ValueError(f"tune: expected log, none or reference, got {tune!r}")
    if families is DEFAULT_FAMILIES and hasattr(robot, "state_names"):
        families = ELASTIC_FAMILIES                   # an elastic robot's log
    if list(rec.joint_names) != list(robot.joint_names):
        raise ValueError(f"rec: joints {rec.joint_names} differ from the robot's {robot.joint_names}")
    t, Y, U = rec.t, rec.q, rec.tau
    if not np.any(np.ptp(Y, axis=0) > 0):   # before the (slow) runs: nothing to estimate
        raise ValueError(f"rec: the robot does not move (q constant on every joint over the {len(t)} samples): "
                         "its velocity is 0, which any difference filter gives exactly, so the methods cannot "
                         "be compared; record a run with motion")
    t_ss = float(t[0] + (t[-1] - t[0]) / 2 if t_ss is None else t_ss)
    parsed = [(item, *parse_observer(item)) for item in families]
    bad = [fam for _, fam, _ in parsed if fam not in observers.FAMILIES]
    if bad:                                 # every name checked before the slow part
        raise ValueError(f"observers: unknown family {bad[0]!r}; known: {', '.join(observers.FAMILIES)}")
    names = list(baseline_names or baselines.BASELINES)
    unknown = [b for b in names if b not in baselines.BASELINES]
    if unknown:
        raise ValueError(f"baselines: unknown {unknown[0]!r}; known: {', '.join(baselines.BASELINES)}")
    if noise is None:
        noise = noise_of.measure(t, Y, U, robot if not hasattr(robot, "state_names") else None)
    design = dict(design or {})
    if "quantization" not in design and "noise" not in design:
        design.update(noise.design_inputs(torque=False))     # the sensor the log has
    ref = reference_of(rec, noise_of.reference_cutoff(noise) if ref_cutoff is None else ref_cutoff)
    val = tuning.validation(t, Y, noise.sigma, psd=noise_of.motion_psd(noise, noise.spectrum))
    entries = []
    bar = progress_bar(total=len(parsed) + len(names) + (rec.qdm is not None), desc="compare", unit="method",
                       file=sys.stderr, disable=not progress, leave=False)
    with bar:
        work = [(_observer_entry, item, fam, given, robot, rec, design, noise, val, tune == "log", reference,
                 stepping, ref, t_ss, level) for item, fam, given in parsed]
        work += [(_baseline_entry, name, rec, val, noise, tune == "log", ref, t_ss, level) for name in names]
        for entry in _entries(work, jobs, bar, progress):
            entries.append(entry)
        if rec.qdm is not None:
            bar.set_postfix_str("qdm")
            m = measure(ref, t, rec.qdm, t_ss, level)
            m["validation_rms"] = val.rms(rec.qdm, t_ss)
            entries.append(Entry(SIGNAL, "signal", {"columns": "qdm_<joint>"}, rec.qdm, m))
            bar.update()
    info = {"recording": rec.describe(), "joint_names": list(robot.joint_names), "noise": noise.lines(),
            "noise_data": noise.to_dict(),
            "tune": tune, "validation": {"window": val.window, "constant": val.constant, **val.details}}
    if clock is not None:
        info["clock"] = clock.describe()
    return Comparison(t=t, truth=ref.qd, entries=entries, t_ss=t_ss, level=level, title=title, info=info, ref=ref)


_WORK = None          # the families' arguments, inherited by the forked workers of ``_entries``


def _baseline_entry(name, rec, val, noise, tune_on, ref, t_ss, level, progress=None):
    """The Entry of the baseline ``name`` on the recording ``rec``: tuned on the log (forward
    validation ``val``, the measured ``noise``) with ``tune_on``, else against the reference ``ref``."""
    t, Y, dt = rec.t, rec.q, rec.dt
    if tune_on:
        params, est, tuned = tune_baseline(name, Y, t, dt, val, noise, t_ss)
    else:
        (params, est), tuned = tune_on_reference(name, Y, t, ref.qd, t_ss, dt, valid=ref.valid), None
    m = measure(ref, t, est, t_ss, level)
    m["validation_rms"] = val.rms(est, t_ss)
    return Entry(name, "baseline", params, est, m, "tuned on the log (forward validation)" if tuned is not None else "",
                 tuned=tuned)


def _entry_job(i):
    return _WORK[i][0](*_WORK[i][1:], None)


def _entries(work, jobs, bar, progress):
    """The entries of ``work`` (each a function, ``_observer_entry`` or ``_baseline_entry``, and its
    arguments but the progress), in order: in this process, or ``jobs`` forked processes at a time
    (the robot and the log are inherited, not pickled; the entries come back), the bar advanced as
    each finishes."""
    import multiprocessing as mp
    import os
    from concurrent.futures import ProcessPoolExecutor, as_completed
    global _WORK
    jobs = max(1, min(jobs or os.cpu_count() or 1, len(work)))
    if jobs == 1:
        for job, *args in work:
            bar.set_postfix_str(args[0])
            yield job(*args, (lambda text: bar.set_postfix_str(text)) if progress else None)
            bar.update()
        return
    _WORK = work
    try:
        with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork")) as pool:
            futures = {pool.submit(_entry_job, i): i for i in range(len(work))}
            done = {}
            for f in as_completed(futures):
                done[futures[f]] = f.result()
                bar.set_postfix_str(work[futures[f]][1])
                bar.update()
        for i in range(len(work)):
            yield done[i]
    finally:
        _WORK = None


def design_on_log(rec, robot, family, design=None, clock=None, noise=None, reference=False, stepping=None,
                  t_from=None, progress=None):
    """One family designed for the log's measured sensor and tuned on it without truth (what
    `design LOG.csv --family F` prints, and a targets file's ``tune = "log.csv"``).

    Parameters
    ----------
    rec : codegen.logs.recording.Recording
        On its sample clock (``codegen.logs.recording.read_log``).
    robot : models.RobotModel
    family : str
        An observer family, optionally with given gains (``parse_observer``; given gains are kept).
    design : dict, optional
        Design inputs; a sensor not stated is the measured one.
    clock, noise : optional
        The log's Clock and its measured Noise (default measured here).
    reference, stepping : as ``compare``.
    t_from : float, optional
        Rows scored from this time (s); default after the family's start-up.
    progress : callable, optional
        Called with each candidate's text.

    Returns
    -------
    (Entry, Noise, Validation)
        The entry's ``params`` are the tuned runtime parameters, ``build`` the build arguments
        they go with (the measured sensor, and kalman_model's torque uncertainty when its model
        variant won), ``tuned`` the search (codegen.logs.tune.Tuned).
    """
    from ..logs import noise as noise_of
    item, (fam, given) = family, parse_observer(family)
    if noise is None:
        noise = noise_of.measure(rec.t, rec.q, rec.tau, robot if not hasattr(robot, "state_names") else None)
    design = dict(design or {})
    if "quantization" not in design and "noise" not in design:
        design.update(noise.design_inputs(torque=False))
    val = tuning.validation(rec.t, rec.q, noise.sigma, psd=noise_of.motion_psd(noise, noise.spectrum))
    if rec.qd is None:
        ref = reference_of(rec, noise_of.reference_cutoff(noise))
    else:
        ref = reference_of(rec)
    t0 = float(rec.t[0] + 0.05 * (rec.t[-1] - rec.t[0])) if t_from is None else t_from
    entry = _observer_entry(item, fam, given, robot, rec, design, noise, val, True, reference, stepping, ref,
                            t0, 1e-2, progress)
    return entry, noise, val


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
