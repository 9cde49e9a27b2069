"""Gains for the elastic-joint robots of seed 004: pole placement on Brunovsky chains
(companion coefficients), the Ciccarella-Germani observer variants, Tomei's Lyapunov gain and
the Spong controllers (docs/papers/seed004.md §7, §8, §10).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import solve_continuous_lyapunov


def companion_gains(poles):
    """[a_{r-1}, ..., a_0] of prod_k (s - p_k) = s^r + a_{r-1} s^{r-1} + ... + a_0: the gain K
    that gives the Brunovsky chain A - K e_1^T the eigenvalues ``poles``  [S004 §8.1; CODE-CP].

    Parameters
    ----------
    poles : (r,) real eigenvalues [1/s]

    Returns
    -------
    (r,) array of coefficients."""
    c = np.real(np.poly(np.asarray(poles, dtype=float)))
    return c[1:].copy()


def ciccarella_germani_gains(variant, n, eigenvalues):
    """Per-channel gain vectors of the CG observer variants (docs/papers/seed004.md §8.3, §8.4), flat.

    O1, O4: joint i gets eigenvalues[4i:4i+4] -> 4 companion coefficients.
    O2:     joint i: [-p_{4i}, companion(p_{4i+1}, p_{4i+2}, p_{4i+3})] (position error gain
            |p| on the first chain state, the 3-chain driven by the velocity error).
    O3:     output i (of [q2_1..q2_n, tau_1..tau_n]) gets eigenvalues[2i:2i+2] -> 2 coefficients.

    Parameters
    ----------
    variant : "O1" | "O2" | "O3" | "O4"
    n : int, number of joints
    eigenvalues : (4n,) negative observer eigenvalues [1/s]

    Returns
    -------
    (4n,) flat gain vector."""
    p = np.asarray(eigenvalues, dtype=float).reshape(-1)
    if p.size != 4 * n or np.any(p >= 0):
        raise ValueError(f"need {4 * n} negative eigenvalues, got {p}")
    if variant in ("O1", "O4"):
        return np.concatenate([companion_gains(p[4 * i:4 * i + 4]) for i in range(n)])
    if variant == "O2":
        return np.concatenate([np.r_[-p[4 * i], companion_gains(p[4 * i + 1:4 * i + 4])]
                               for i in range(n)])
    if variant == "O3":
        return np.concatenate([companion_gains(p[2 * i:2 * i + 2]) for i in range(2 * n)])
    raise ValueError(f"unknown CG variant {variant!r} (O1..O4)")


def tomei_K1(A, Qlyap):
    """K1 solving A^T K1 + K1 A = Q (Thm 3.1 of seed 004, docs/papers/seed004.md §7), by
    scipy.linalg.solve_continuous_lyapunov(A^T, Q) (which solves A^T X + X A = Q).

    Parameters
    ----------
    A : (m, m) Hurwitz matrix;  Qlyap : (m, m) right-hand side

    Returns
    -------
    (m, m) array K1."""
    A, Qlyap = np.atleast_2d(A).astype(float), np.atleast_2d(Qlyap).astype(float)
    return solve_continuous_lyapunov(A.T, Qlyap)


def spong_fl_gains(n, poles):
    """K_c rows per joint acting on [e, e', e'', e''']: -[a0, a1, a2, a3] of prod (s - p),
    joint i gets poles[4i:4i+4]  [S004 (4.7); CODE-CP computegains.m].

    Parameters
    ----------
    n : int, number of joints;  poles : (4n,) closed-loop poles [1/s]

    Returns
    -------
    (4n,) flat gains."""
    p = np.asarray(poles, dtype=float).reshape(-1)
    if p.size != 4 * n:
        raise ValueError(f"need {4 * n} poles, got {p.size}")
    return np.concatenate([-companion_gains(p[4 * i:4 * i + 4])[::-1] for i in range(n)])


def spong_fast_gains(n, poles, stiffness):
    """Per joint [k_eta, k_etad] of zeta_i = k_eta eta_i + k_etad eta_i' so that
    eta'' = K zeta has the eigenvalues (p_a, p_b): k_eta = -p_a p_b / K_i,
    k_etad = (p_a + p_b) / K_i  [S004 (4.23), docs/papers/seed004.md §10.4 DERIVED]; the poles are cycled
    over the joints two by two (2n needed).

    Parameters
    ----------
    n : int, number of joints
    poles : (>= 2n,) fast poles [1/s]
    stiffness : scalar or (n,) joint stiffnesses K_i [N m/rad]

    Returns
    -------
    (2n,) flat gains [k_eta_1, k_etad_1, ...]."""
    p = np.asarray(poles, dtype=float).reshape(-1)
    Kd = np.broadcast_to(np.asarray(stiffness, dtype=float), (n,))
    if p.size < 2 * n:
        raise ValueError(f"need {2 * n} fast poles, got {p.size}")
    return np.concatenate([[-p[2 * i] * p[2 * i + 1] / Kd[i], (p[2 * i] + p[2 * i + 1]) / Kd[i]]
                           for i in range(n)])
