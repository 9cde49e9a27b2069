"""CasADi helpers shared by observer families: quadrature and structured solves.

Self-contained sections; each one only uses casadi and numpy.
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np


# ============================================================================ quadrature
@lru_cache(maxsize=64)
def gauss_legendre(N):
    """Nodes t_k and weights w_k of the N-point Gauss-Legendre rule on [-1, 1].

    Exact for polynomials of degree <= 2N - 1. Returned as read-only float64 arrays."""
    if int(N) != N or N < 1:
        raise ValueError(f"N (quadrature nodes) must be a positive integer, got {N!r}")
    t, w = np.polynomial.legendre.leggauss(int(N))
    t.setflags(write=False)
    w.setflags(write=False)
    return t, w


def quadrature_points(b, N, a=0.0):
    """Nodes sigma_k and weights h_k of the N-point Gauss-Legendre rule on [a, b] (b may be SX):

        int_a^b f(sigma) d sigma  ~=  sum_k h_k f(sigma_k),
        sigma_k = (a + b)/2 + (b - a)/2 t_k,   h_k = (b - a)/2 w_k.
    """
    t, w = gauss_legendre(N)
    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    return [mid + half * float(tk) for tk in t], [half * float(wk) for wk in w]


def integrate(f, b, N, a=0.0):
    """Gauss-Legendre approximation of int_a^b f(sigma) d sigma with N nodes.

    f maps a scalar (SX) to an SX expression (any shape); b (and a) may be symbolic."""
    sig, h = quadrature_points(b, N, a)
    total = 0
    for s, hk in zip(sig, h):
        total = total + hk * f(s)
    return total


# ============================================================================ structured solves
def ldl_solve(M, B):
    """X = M^{-1} B for a symmetric positive-definite M by an unpivoted LDL^T factorisation.

    Written out entry by entry, so an SX M gives ~n^3/6 + n^2 (cols of B) operations and no
    square roots (leaner than a generic symbolic QR solve). Structural zeros of M are kept."""
    n = M.shape[0]
    if M.shape != (n, n) or B.shape[0] != n:
        raise ValueError(f"ldl_solve: M must be square and B have {n} rows, got {M.shape}, {B.shape}")
    L = [[None] * n for _ in range(n)]
    D = [None] * n
    for j in range(n):
        d = M[j, j]
        for k in range(j):
            d = d - L[j][k] * L[j][k] * D[k]
        D[j] = d
        for i in range(j + 1, n):
            s = M[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k] * D[k]
            L[i][j] = s / d
    cols = []
    for c in range(B.shape[1]):
        z = [B[i, c] for i in range(n)]
        for i in range(n):                      # L z = b
            for k in range(i):
                z[i] = z[i] - L[i][k] * z[k]
        z = [z[i] / D[i] for i in range(n)]     # D
        for i in range(n - 1, -1, -1):          # L^T x = z
            for k in range(i + 1, n):
                z[i] = z[i] - L[k][i] * z[k]
        cols.append(ca.vertcat(*z))
    return ca.horzcat(*cols)
