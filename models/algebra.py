"""Scalar algebra that folds python-float zeros and ones before CasADi sees them.

The spatial algorithms (``models.spatial`` and the algorithm modules) mix CasADi SX
scalars with constant python floats taken from a robot description. Every product or sum
goes through :func:`add`, :func:`sub`, :func:`mul` and :func:`dot`, which drop exact zeros
and fold factors +-1 into signs, so the expression graph holds only the operations the
robot really needs. 3-vectors are tuples and 3x3 matrices nested lists/tuples of such
scalars; :func:`split` and :func:`column` convert to and from SX columns.
"""
from __future__ import annotations

import casadi as ca

__all__ = ["is_zero", "add", "sub", "mul", "dot", "cross", "vadd", "vsub", "cmv", "cmtv",
           "sym3", "symmap", "zero3", "split", "column"]


def is_zero(x):
    """True when the scalar ``x`` is exactly zero: the float 0.0 or a structurally zero SX."""
    if isinstance(x, float):
        return x == 0.0
    return x.is_zero()


def add(a, b):
    """a + b, skipping an exact zero."""
    if is_zero(a):
        return b
    if is_zero(b):
        return a
    return a + b


def sub(a, b):
    """a - b, skipping an exact zero."""
    if is_zero(b):
        return a
    if is_zero(a):
        return -b
    return a - b


def mul(a, b):
    """a b: exact zeros give 0.0, float factors +-1 give a sign."""
    if is_zero(a) or is_zero(b):
        return 0.0
    if isinstance(a, float):
        if a == 1.0:
            return b
        if a == -1.0:
            return -b
    if isinstance(b, float):
        if b == 1.0:
            return a
        if b == -1.0:
            return -a
    return a * b


def dot(a, b):
    """sum_k a_k b_k of two equal-length sequences ``a``, ``b`` of scalars, skipping zeros and
    folding unit coefficients into +/-."""
    acc = 0.0
    for x, y in zip(a, b):
        if is_zero(x) or is_zero(y):
            continue
        if isinstance(x, float) and x == -1.0:
            acc = sub(acc, y)
        elif isinstance(y, float) and y == -1.0:
            acc = sub(acc, x)
        else:
            acc = add(acc, mul(x, y))
    return acc


def cross(a, b):
    """a x b of two 3-vectors."""
    return (sub(mul(a[1], b[2]), mul(a[2], b[1])),
            sub(mul(a[2], b[0]), mul(a[0], b[2])),
            sub(mul(a[0], b[1]), mul(a[1], b[0])))


def vadd(a, b):
    """a + b entrywise."""
    return tuple(add(x, y) for x, y in zip(a, b))


def vsub(a, b):
    """a - b entrywise."""
    return tuple(sub(x, y) for x, y in zip(a, b))


def cmv(E, u):
    """E u for a constant matrix E (rows of floats)."""
    return tuple(dot(row, u) for row in E)


def cmtv(E, u):
    """E^T u for a constant matrix E."""
    return tuple(dot((E[0][j], E[1][j], E[2][j]), u) for j in range(3))


def sym3(m00, m01, m02, m11, m12, m22):
    """Symmetric 3x3 as nested lists sharing the mirrored entries.

    The upper triangle is given row by row: ``m00``, ``m01``, ``m02`` (row 0), ``m11``,
    ``m12`` (row 1) and ``m22``; the lower triangle mirrors it."""
    return [[m00, m01, m02], [m01, m11, m12], [m02, m12, m22]]


def symmap(S, T, op):
    """The symmetric 3x3 op(S, T), entry by entry on the upper triangle."""
    return sym3(op(S[0][0], T[0][0]), op(S[0][1], T[0][1]), op(S[0][2], T[0][2]),
                op(S[1][1], T[1][1]), op(S[1][2], T[1][2]), op(S[2][2], T[2][2]))


def zero3():
    """The zero 3-vector (0.0, 0.0, 0.0)."""
    return (0.0, 0.0, 0.0)


def split(x, n, what):
    """The n entries of an argument as scalars.

    Parameters
    ----------
    x : casadi.SX of shape (n, 1) or (1, n), list or tuple of n scalars, or None
        None stands for the zero vector (exact: its entries are the float 0.0).
    n : int
    what : str
        Argument name for the error message.

    Returns
    -------
    list of n SX scalars or floats
    """
    if isinstance(x, (list, tuple)):
        if len(x) != n:
            raise ValueError(f"{what}: expected {n} entries, got {len(x)}")
        return [e if isinstance(e, ca.SX) else float(e) for e in x]
    if x is None:
        return [0.0] * n
    if x.shape != (n, 1) and x.shape != (1, n):
        raise ValueError(f"{what}: expected shape ({n}, 1), got {x.shape}")
    return [x[k] for k in range(n)]


def column(entries):
    """The scalars ``entries`` stacked into an (len(entries), 1) SX."""
    return ca.vertcat(*[ca.SX(e) if isinstance(e, float) else e for e in entries])
