"""The one shape every estimator has: the compiled observers (codegen.pipeline.load), the numpy
reference (codegen.reference) and the baselines a user would write (codegen.evaluate.baselines).

    est.reset(y0, est0=None)      start from the first measurement (and an initial estimate)
    est.step(y, u)  -> (nest,)    the estimate at this sample; the state advances
    est.estimate(y, u)            what step(y, u) would return, the state unchanged
    est.run(Y, U)   -> (N, nest)  many samples at once
    est.state                     a copy of the internal state; settable

Sizes ``ny``, ``nu``, ``nest`` and ``nx`` are attributes. Comparisons, simulations and sweeps
take any ``Estimator``, so a new baseline or backend needs nothing else.
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable


@runtime_checkable
class Estimator(Protocol):
    """What ``isinstance(obj, Estimator)`` checks: the methods and attributes of the module
    docstring (their signatures are the documented ones)."""

    ny: int
    nu: int
    nest: int
    nx: int

    def reset(self, y0, est0=None):
        """Start from the first measurement ``y0`` (ny,) and an initial estimate ``est0`` (nest,)."""

    def step(self, y, u):
        """The estimate (nest,) at this sample from measurement ``y`` (ny,) and input ``u`` (nu,)."""

    def estimate(self, y, u):
        """What ``step(y, u)`` would return, without advancing the state."""

    def run(self, Y, U):
        """Estimates (N, nest) over the rows of ``Y`` (N, ny) and ``U`` (N, nu)."""

    @property
    def state(self):
        """A copy of the internal state (nx,)."""


VELOCITY_PREFIX = "qd_hat_"


def velocity_slots(est_names, joint_names=None):
    """Indices of the velocity estimates ``qd_hat_<joint>`` among ``est_names``: in the order of
    ``joint_names`` when given (each must be there, else ValueError naming the missing ones), else
    in their own order. An estimate holds more than the velocity for some families (the
    extended-state observer appends its torque-error estimate ``tau_d_hat_<joint>``), so a caller
    that wants q̇̂ selects these slots by name, never by position.

    Parameters
    ----------
    est_names : sequence of str
        The estimate's slot names (``spec.est_names``, ``meta["names"]["est"]``, ``obs.est_names``).
    joint_names : sequence of str, optional
        The joints, in the order wanted.

    Returns
    -------
    list of int
    """
    names = list(est_names)
    if joint_names is None:
        return [i for i, s in enumerate(names) if s.startswith(VELOCITY_PREFIX)]
    missing = [j for j in joint_names if VELOCITY_PREFIX + j not in names]
    if missing:
        raise ValueError(f"est_names: no velocity estimate for joint(s) {', '.join(missing)} "
                         f"(expected slots {VELOCITY_PREFIX}<joint>; got {', '.join(names)})")
    return [names.index(VELOCITY_PREFIX + j) for j in joint_names]


def velocity_estimate(est, est_names, joint_names=None):
    """The velocity columns of ``est`` ((N, nest) or (nest,)): ``est[..., velocity_slots(est_names,
    joint_names)]`` (arguments as in ``velocity_slots``)."""
    import numpy as np
    return np.asarray(est)[..., velocity_slots(est_names, joint_names)]


def full_estimate(est_names, qd_hat, joint_names=None):
    """An initial estimate (nest,) with the velocity slots set to ``qd_hat`` (n,) rad/s in the order
    of ``joint_names`` (or of the slots) and every other slot 0 (e.g. the extended-state
    observer's torque-error estimate), for ``reset(y0, est0)``; ``est_names`` as in
    ``velocity_slots``."""
    import numpy as np
    est0 = np.zeros(len(est_names))
    est0[velocity_slots(est_names, joint_names)] = np.asarray(qd_hat, dtype=float).reshape(-1)
    return est0
