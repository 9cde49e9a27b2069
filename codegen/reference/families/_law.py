"""Stateless control laws as reference families: the observer contract with a constant state.

A law's "estimate" is its output (a torque); its state is a dummy of ``nx`` slots (0, or 1 where
the generated C wants a non-empty state) that never changes: x' = 0, x(0) = 0.
"""
from __future__ import annotations

import numpy as np


def constant_state(nx):
    """(rhs, init) of a law with a constant zero state of ``nx`` slots.

    Parameters
    ----------
    nx : int
        Number of dummy state slots.

    Returns
    -------
    rhs : callable
        rhs(robot, x, y, u, p) -> zeros (nx,)
    init : callable
        init(robot, y0, est0, p) -> zeros (nx,)
    """
    def rhs(robot, x, y, u, p):
        """x' = 0 (nx,)."""
        return np.zeros(nx)

    def init(robot, y0, est0, p):
        """x(0) = 0 (nx,)."""
        return np.zeros(nx)

    return rhs, init


def parameters(family, p, count):
    """``p`` as a float vector of ``count`` entries, or ValueError naming the family.

    Parameters
    ----------
    family : str
    p : (count,) array_like
    count : int

    Returns
    -------
    (count,) float array
    """
    p = np.asarray(p, dtype=float).reshape(-1)
    if p.size != count:
        raise ValueError(f"{family}: expected {count} parameters, got {p.size}")
    return p
