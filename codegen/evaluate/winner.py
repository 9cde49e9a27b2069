"""The observer a comparison on a log recommends, as a target to build.

The winner is the observer with the lowest truth-free error estimate among those that did not
fail: the forward validation's ``validation_rms`` (codegen.logs.tune), which needs neither the
truth nor the offline reference. Its target carries what the comparison ran: the family, its
variant, the build inputs (the sensor measured on the log, the torque uncertainty measured or
stated), the gains tuned on the log, and the log's sample clock as the discretisation: dt its
median interval, [dt_min, dt_max] the range of its intervals (a longer one, a dropped sample, is
split by the C), each value's source in ``Target.sources`` (the folder's design report and
header state them).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.target import AUTO, Discretization, Target
from .compare import parse_observer

SPLIT_FROM = 2.0           # dt_max at most this x dt: a longer interval is split into sub-intervals
SHORTEST = 0.01            # dt_min at least this x dt (bunched stamps: the step tends to the identity)


def winner(cmp):
    """The observer Entry of the Comparison ``cmp`` with the lowest ``validation_rms`` among those
    that did not fail (``Comparison.failure``), or None."""
    ok = [e for e in cmp.ok() if e.kind == "observer" and math.isfinite(e.metrics.get("validation_rms", math.nan))]
    return min(ok, key=lambda e: e.metrics["validation_rms"]) if ok else None


def interval_range(t, dt):
    """(dt_min, dt_max) of the sample times ``t`` (s) at the median step ``dt``: the shortest
    interval (at least SHORTEST dt, at most dt) and the longest (at least dt, at most SPLIT_FROM dt)."""
    h = np.diff(np.asarray(t, dtype=float))
    h = h[h > 0]
    if not len(h):
        return dt / 4, SPLIT_FROM * dt
    return min(dt, max(float(h.min()), SHORTEST * dt)), max(dt, min(float(h.max()), SPLIT_FROM * dt))


def winner_target(cmp, robot, t, dt, log_name, stated=None, stepping=None, name=None):
    """(Target, Entry): the ``winner`` of ``cmp`` (run on ``robot`` over the log ``log_name``'s
    sample times ``t`` at median step ``dt``) as a target, every value's source stated; ``stated``
    (input name -> source text) names the build inputs the user gave (the others were measured on
    the log), ``stepping`` the method, hold and substeps the comparison ran with. ValueError when
    no observer qualifies."""
    e = winner(cmp)
    if e is None:
        raise ValueError("no observer to build: none ran without failing (the table says why)")
    family, given = parse_observer(e.name)
    stated = dict(stated or {})
    tuned = dict(e.tuned.params) if e.tuned is not None else {}
    lo, hi = interval_range(t, dt)
    vrms = e.metrics["validation_rms"]
    sources = {k: stated.get(k) or ("given by the user" if k in given else f"measured on the log {log_name}")
               for k in (e.build or {})}
    sources.update({k: f"tuned on the log {log_name} (forward validation, est. RMS error {vrms:.3g} rad/s)"
                    for k in tuned})
    sources.update({"dt": f"the median sample interval of the log {log_name}",
                    "dt_min": f"the shortest interval of the log {log_name} (at least {SHORTEST:g} dt)",
                    "dt_max": f"the longest interval of the log {log_name} (at most {SPLIT_FROM:g} dt; a longer "
                              "one is split)"})
    disc = Discretization(**{"substeps": AUTO, **(stepping or {}), "dt": float(dt), "dt_min": float(lo),
                             "dt_max": float(hi)})
    target = Target(robot=robot.source, family=family, variant=e.variant, build=dict(e.build or {}), params=tuned,
                    discretization=disc, name=name, sources=sources)
    return target, e
