"""The error measures of every check: C against the reference (``relative_error``, per sample)
and one build against another over a run (``run_relative_error``, scaled by the run's largest
value: a float run's samples near zero have no relative meaning)."""
from __future__ import annotations

import numpy as np


def relative_error(a, b):
    """Worst relative error of the rows of ``a`` against the rows of ``b``.

    Parameters
    ----------
    a, b : array_like, shape (N, m) or (m,)
        Candidate and reference.

    Returns
    -------
    float
        max over rows of ||a - b|| / ||b|| (rows with ||b|| = 0 compare absolutely); NaN if
        anything is not finite, so that a comparison ``<= tol`` fails.
    """
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return float("nan")
    nb = np.linalg.norm(b, axis=1)
    return float(np.max(np.linalg.norm(a - b, axis=1) / np.where(nb > 0, nb, 1.0)))


def run_relative_error(a, b):
    """max |a - b| / max |b| over a whole run (NaN if anything is not finite)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return float("nan")
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), np.finfo(float).tiny))


def _bound_and_names(observer):
    """(v_bound (n,) array or None, est_names) of a spec, a compiled or reference observer, or
    a description / metadata dict."""
    if isinstance(observer, dict):
        desc = observer
    elif hasattr(observer, "meta"):                       # CompiledObserver: its metadata JSON
        desc = observer.meta
    elif hasattr(observer, "describe"):                   # ObserverSpec
        desc = observer.describe()
    else:                                                 # ReferenceObserver
        desc = {"options": {"v_bound": getattr(observer.options, "v_bound", ())},
                "names": {"est": observer.est_names}}
    options = desc.get("options") or {}
    bound = options.get("v_bound") if isinstance(options, dict) else getattr(options, "v_bound", None)
    return (np.asarray(bound, dtype=float) if bound else None), list(desc["names"]["est"])


def saturation_mask(est, observer):
    """Where the velocity estimate is beyond the model's velocity bound: |qd_hat_j| > v_bound_j,
    i.e. where the observer evaluated its model at the bound, not at the estimate
    (codegen.families.observers._bound). For Nicosia–Tomei the model's argument is x1hat', not the
    estimate x2hat: the mask is that of the estimate (an approximation there).

    Parameters
    ----------
    est : (N, nest) array
        Estimates of a run (``obs.run(Y, U)``).
    observer : ObserverSpec, CompiledObserver, ReferenceObserver or dict
        What produced them: the bound is read from its declared options (the metadata JSON's
        "options" for a compiled target) and the velocity slots from its estimate names.

    Returns
    -------
    (N, n) bool array
        Per sample and velocity slot (in the order of the ``qd_hat_<joint>`` slots); all False
        when the observer declares no bound.
    """
    from ..core.estimator import velocity_slots
    bound, names = _bound_and_names(observer)
    idx = velocity_slots(names)
    v = np.atleast_2d(np.asarray(est, dtype=float))[:, idx]
    if bound is None:
        return np.zeros(v.shape, dtype=bool)
    if bound.shape != (len(idx),):
        raise ValueError(f"v_bound has {bound.size} entries, the estimate {len(idx)} velocity slots")
    return np.abs(v) > bound


def saturated_samples(est, observer):
    """How many samples (rows of ``est``) had at least one velocity estimate beyond the model's
    velocity bound (``saturation_mask``; arguments as there). 0 for an observer without a bound."""
    return int(np.count_nonzero(saturation_mask(est, observer).any(axis=1)))
