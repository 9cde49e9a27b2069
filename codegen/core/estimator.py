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
