"""The velocity bound of the model-based velocity observers, numpy (the families' options).

The model is evaluated at the estimate saturated per joint, FD(y, sat(v), tau) with
sat(v)_j = min(max(v_j, -b_j), b_j), b the ``v_bound`` the spec declares
(codegen.core.options.VelocityBoundOptions, HybridOptions); a description without it (a target
generated before the bound existed) gives no saturation.
"""
from __future__ import annotations

import numpy as np


def velocity_bound(robot, options):
    """The declared bound (n,) rad/s, or None when the options declare none.

    Parameters
    ----------
    robot : reference robot (n joints)
    options : codegen.core.options.Options
        Its ``v_bound`` field (a tuple of n speeds), if any.

    Returns
    -------
    (n,) float array or None
    """
    b = tuple(getattr(options, "v_bound", ()) or ())
    if not b:
        return None
    b = np.asarray(b, dtype=float)
    if b.shape != (robot.n,) or not np.all(np.isfinite(b) & (b > 0)):
        raise ValueError(f"v_bound: expected {robot.n} positive finite speeds (rad/s), got {b.tolist()}")
    return b


def saturate(v, bound):
    """min(max(v, -b), b) per entry (``v`` (n,) rad/s, ``bound`` (n,) rad/s); ``v`` itself when
    ``bound`` is None."""
    v = np.asarray(v, dtype=float)
    return v if bound is None else np.minimum(np.maximum(v, -bound), bound)
