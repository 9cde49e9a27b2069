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
