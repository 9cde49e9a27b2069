"""Hyper-dual arrays: exact first and second directional derivatives in plain numpy.

A hyper-dual number a + b e1 + c e2 + d e1 e2 (e1^2 = e2^2 = 0) carried through an analytic F
evaluated at x + e1 u + e2 w gives, with no truncation error,

    F(x) (part a),  DF[u] (part b),  DF[w] (part c),  D^2F[u, w] (part d).

This is what the Ciccarella-Germani Q(x) and Spong's F(x) need (docs/papers/seed004.md §8.3, §9) on the
Newton-Euler DH recursion of reference/dh.py. The functions below (sin, cos, tanh, stack, cross,
dot, solve) take floats and hyper-duals alike, so that one recursion serves both.
"""
from __future__ import annotations

import numpy as np


class HyperDual:
    """Array of hyper-dual numbers.

    Parameters
    ----------
    a, b, c, d : array_like, same shape
        Value, e1 part, e2 part and e1 e2 part; b, c, d default to zeros.
    """

    __array_priority__ = 100

    def __init__(self, a, b=None, c=None, d=None):
        # parts are float arrays; the type test skips np.asarray on the hot path (speed only)
        self.a = a if type(a) is np.ndarray and a.dtype == np.float64 else np.asarray(a, dtype=float)
        z = None
        if b is None or c is None or d is None:
            z = np.zeros(self.a.shape)
        self.b = z if b is None else b if type(b) is np.ndarray else np.asarray(b, dtype=float)
        self.c = z if c is None else c if type(c) is np.ndarray else np.asarray(c, dtype=float)
        self.d = z if d is None else d if type(d) is np.ndarray else np.asarray(d, dtype=float)

    @staticmethod
    def lift(v):
        """``v`` as a hyper-dual (a float array gets zero derivative parts)."""
        return v if isinstance(v, HyperDual) else HyperDual(v)

    def parts(self):
        """(a, b, c, d)."""
        return self.a, self.b, self.c, self.d

    shape = property(lambda self: self.a.shape)
    T = property(lambda self: HyperDual(*(p.T for p in self.parts())))

    def __getitem__(self, k):
        return HyperDual(*(p[k] for p in self.parts()))

    def __neg__(self):
        return HyperDual(*(-p for p in self.parts()))

    def __add__(self, o):
        o = HyperDual.lift(o)
        return HyperDual(*(p + q for p, q in zip(self.parts(), o.parts())))

    __radd__ = __add__

    def __sub__(self, o):
        return self + (-HyperDual.lift(o))

    @staticmethod
    def _product(x, y, op):
        """Leibniz rule of a bilinear ``op`` (elementwise or matrix product)."""
        return HyperDual(op(x.a, y.a), op(x.a, y.b) + op(x.b, y.a), op(x.a, y.c) + op(x.c, y.a),
                         op(x.a, y.d) + op(x.b, y.c) + op(x.c, y.b) + op(x.d, y.a))

    def __mul__(self, o):
        return HyperDual._product(self, HyperDual.lift(o), np.multiply)

    __rmul__ = __mul__

    def __matmul__(self, o):
        return HyperDual._product(self, HyperDual.lift(o), np.matmul)

    def __rmatmul__(self, o):
        return HyperDual._product(HyperDual.lift(o), self, np.matmul)


def _unary(x, f, df, d2f):
    """f(x) by the chain rule: b, c scale by f'; d = f' d + f'' b c."""
    if not isinstance(x, HyperDual):
        return f(x)
    f1, f2 = df(x.a), d2f(x.a)
    return HyperDual(f(x.a), f1 * x.b, f1 * x.c, f1 * x.d + f2 * x.b * x.c)


def sin(x):
    """sin of ``x``, a float, array or hyper-dual."""
    return _unary(x, np.sin, np.cos, lambda a: -np.sin(a))


def cos(x):
    """cos of ``x``, a float, array or hyper-dual."""
    return _unary(x, np.cos, lambda a: -np.sin(a), lambda a: -np.cos(a))


def tanh(x):
    """tanh of ``x``, a float, array or hyper-dual: tanh' = 1 - t^2, tanh'' = -2 t (1 - t^2)."""
    return _unary(x, np.tanh, lambda a: 1.0 - np.tanh(a) ** 2,
                  lambda a: -2.0 * np.tanh(a) * (1.0 - np.tanh(a) ** 2))


def stack(items, axis=0):
    """np.stack of ``items`` along ``axis`` for a mix of floats and hyper-duals (a hyper-dual if any
    item is one)."""
    if not any(isinstance(i, HyperDual) for i in items):
        return np.stack([np.asarray(i, dtype=float) for i in items], axis=axis)
    items = [HyperDual.lift(i) for i in items]
    return HyperDual(*(np.stack([getattr(i, k) for i in items], axis=axis) for k in "abcd"))


_NEXT, _PREV = [1, 2, 0], [2, 0, 1]


def _cross3(x, y):
    """x x y of float arrays whose first axis has length 3 (the components)."""
    return x[_NEXT] * y[_PREV] - x[_PREV] * y[_NEXT]


def cross(u, v):
    """u x v for 3-vectors (floats or hyper-duals): bilinear, so the parts follow the Leibniz
    rule of ``HyperDual._product`` on the float cross product."""
    if isinstance(u, HyperDual) or isinstance(v, HyperDual):
        return HyperDual._product(HyperDual.lift(u), HyperDual.lift(v), _cross3)
    return _cross3(np.asarray(u, dtype=float), np.asarray(v, dtype=float))


def dot(u, v):
    """u . v for 3-vectors (floats or hyper-duals)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def solve(A, y):
    """A^{-1} y for floats or hyper-duals: the parts by differentiating A x = y twice,

        A xb = yb - Ab xa,  A xc = yc - Ac xa,  A xd = yd - Ab xc - Ac xb - Ad xa.

    Parameters
    ----------
    A : (n, n) array or HyperDual
    y : (n,) or (n, k) array or HyperDual

    Returns
    -------
    ndarray or HyperDual, the shape of y
    """
    if not isinstance(A, HyperDual) and not isinstance(y, HyperDual):
        return np.linalg.solve(A, y)
    A, y = HyperDual.lift(A), HyperDual.lift(y)
    xa = np.linalg.solve(A.a, y.a)
    xb = np.linalg.solve(A.a, y.b - A.b @ xa)
    xc = np.linalg.solve(A.a, y.c - A.c @ xa)
    xd = np.linalg.solve(A.a, y.d - A.b @ xc - A.c @ xb - A.d @ xa)
    return HyperDual(xa, xb, xc, xd)


def seeded(x, u=None, w=None):
    """The hyper-dual point x + e1 u + e2 w (u, w default to zero).

    Parameters
    ----------
    x, u, w : (m,) array_like

    Returns
    -------
    HyperDual
    """
    z = np.zeros_like(np.asarray(x, dtype=float))
    return HyperDual(x, z if u is None else u, z if w is None else w)
