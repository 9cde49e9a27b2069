"""Whether a design tuned on a log is a design (``design LOG --family F``, a targets file's
``tune = "log.csv"``): a failed or saturated one is refused, never printed as a build.

Refused: no candidate scored (the log too short for the scoring to start, codegen.logs.tune.too_short,
or none ran finite and stable); a run over the log that stopped (its estimate not finite: a
non-finite result, the state rolled back); or more than SATURATED of the samples with a velocity
estimate at the model's bound (the model then saw the bound, not the motion).
"""
from __future__ import annotations

import math

import numpy as np

SATURATED = 0.1     # [ASSUMPTION] a design at its bound on more of the samples is no design


def design_failure(entry, family):
    """(why, remedy) of the design ``entry`` (codegen.evaluate.compare.design_on_log's Entry) of
    ``family`` when it is no design, else None; ``remedy`` is a (design input, what to do) pair
    or None (the command line renders it)."""
    tuned, n = entry.tuned, len(entry.est)
    if tuned is not None and not math.isfinite(tuned.score):
        return f"{family}: no design: {tuned.note or 'no candidate ran finite and stable'}", None
    bad = ~np.all(np.isfinite(entry.est), axis=1)
    if bad.any():
        parts = (entry.note or "").split("; ")
        stop = [k for k, part in enumerate(parts) if "stopped at sample" in part]
        why = "; ".join(parts[stop[0]:stop[0] + 2]) if stop else f"a non-finite estimate at sample {int(np.argmax(bad))}"
        return f"{family}: no design: its run over the {n} samples of the log failed ({why})", None
    hits = int(entry.metrics.get("at_bound") or 0)
    if hits > SATURATED * n:
        return (f"{family}: no design: saturated, {hits} of {n} samples with the velocity estimate at the "
                f"model's bound (more than {SATURATED:.0%})"), ("v_max", "raise the bound")
    return None
