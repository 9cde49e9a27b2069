"""Offline constants and bounds of the I&I speed observers of seed 003 (Arbo, Grotli & Gravdahl),
docs/papers/seed003.md §4.1-§4.2 and §5, computed for any robot (never typed in).

I&I speed observer:

    k_m = min_q lambda_min(M(q)),  k_M = max_q lambda_max(M(q))                      [S003 P1]
    k_c = max_q max_{|v|=1} ||C(q, v)||_2                                            [S003 P4]
    ||Deltabar_x|| = k_c / k_m                                                      [S003 (21)]
    H(q, x) = k1 H0(q) + sum_m x_m H^(m)(q),  H0 = M^{-1},  H^(m) = -M^{-1} C(q, e_m)  [DERIVED]
    Deltabar_y,ji(s_x) = k1 a_ji + sum_m |s_x,m| b_jim                               [S003 Lemma 2, DERIVED]
       a_ji  = || (sup_q |dH0_ji/dq_k|)_{k != i} ||_2
       b_jim = || (sup_q |dH^(m)_ji/dq_k|)_{k != i} ||_2

Column i of Delta_y depends on e_y only through the entries k != i (column i is evaluated at
s_y with y_i in place i), and |dDelta_ji/de| <= k1 |dH0_ji/dq| + sum_m |x_m| |dH^(m)_ji/dq|
entrywise, whose 2-norm over k is bounded by the triangle inequality: the seed's "sum of the
sup-norms of the terms" rule, made computable for any robot.

AOV observer (the seed's comparison, docs/papers/seed003.md §5) [DERIVED]: the same Lemma-2 coefficients for the
affine split Hbar(q, p) = k1 T^{-1} + sum_m p_m Cbar(q, e_m) T^{-1}, and
Deltabar_p = max_q max_{|a|=1} ||Cbar(q, a) T^{-1}||_F.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ...core.symbolic import (christoffel_column_matrix, christoffel_slices, cholesky_velocity, ldl_solve,
                        skew_S)
from .configurations import ConfigurationStats, entrywise_sup, refine_max, sample_points


@dataclass
class IISpeedDesign:
    """Offline constants of the I&I speed observer [S003 P1, P4, Lemma 1, Lemma 2]."""
    robot: str
    k_m: float                 # min_q lambda_min(M)
    k_M: float                 # max_q lambda_max(M)
    k_c: float                 # max_q max_{|v|=1} ||C(q, v)||_2
    k_cF: float                # max_q max_{|v|=1} ||C(q, v)||_F
    deltabar_x: float          # max(k_c/k_m, k_cF/k_M): Lemma 1, valid with Frobenius norms in (38)
    dy_k1: np.ndarray          # (n, n) a_ji: coefficient of k1 in Deltabar_y,ji
    dy_sx: np.ndarray          # (n, n, n) b_jim: coefficient of |s_x,m| in Deltabar_y,ji
    samples: int
    refined: bool

    def deltabar_y(self, k1, s_x):
        """Deltabar_y (n x n) at gain k1 and filtered speed s_x (Lemma 2 matrix)."""
        return k1 * self.dy_k1 + np.einsum("jim,m->ji", self.dy_sx, np.abs(np.asarray(s_x, float)))

    def as_dict(self):
        """The fields as a JSON-ready dict (arrays as lists)."""
        d = dict(self.__dict__)
        d["dy_k1"], d["dy_sx"] = self.dy_k1.tolist(), self.dy_sx.tolist()
        return d

    def __str__(self):
        return "\n".join([
            f"I&I speed observer bounds for {self.robot} ({self.samples} samples"
            f"{', refined' if self.refined else ''}):",
            f"  k_m = {self.k_m:.6g}, k_M = {self.k_M:.6g}   [S003 P1]",
            f"  k_c = {self.k_c:.6g} (spectral), k_cF = {self.k_cF:.6g} (Frobenius)   [S003 P4]",
            f"  ||Deltabar_x|| = {self.deltabar_x:.6g}   [S003 (21)]",
            f"  ||Deltabar_y||_F <= k1 {np.linalg.norm(self.dy_k1):.4g} + sum_m |s_x,m| (...)   [S003 Lemma 2]",
        ])


@dataclass
class IIAovDesign:
    """Bounds of the reconstructed Astolfi-Ortega-Venkatraman observer (docs/papers/seed003.md §5) [DERIVED]:
    Hbar(q, p) = k1 T^{-1} + sum_m p_m Cbar(q, e_m) T^{-1}."""
    robot: str
    deltabar_p: float          # max_q max_{|a|=1} ||Cbar(q, a) T^{-1}||_F
    dq_k1: np.ndarray          # (n, n) coefficient of k1 in Deltabar_q,ji
    dq_p: np.ndarray           # (n, n, n) coefficient of |phat_m|
    samples: int
    refined: bool

    def as_dict(self):
        """The fields as a JSON-ready dict (arrays as lists)."""
        d = dict(self.__dict__)
        d["dq_k1"], d["dq_p"] = self.dq_k1.tolist(), self.dq_p.tolist()
        return d


def _affine_derivatives(robot, split):
    """CasADi Function q -> [vec(dH0/dq); vec(dH^(1)/dq); ...] for an affine target Jacobian
    H(q, x) = k1 H0(q) + sum_m x_m H^(m)(q); ``split(q) -> (H0, [H^(1), ..., H^(n)])`` (SX).
    vec is column-major: Jacobian of vec(H0) (n^2 x n) then of vec([H^(1)..H^(n)]) (n^3 x n)."""
    n = robot.n
    q = ca.SX.sym("q", n)
    H0, Hm = split(q)
    d0 = ca.jacobian(ca.vec(H0), q)
    d1 = ca.jacobian(ca.vertcat(*[ca.vec(h) for h in Hm]), q)
    return ca.Function("dH", [q], [ca.vertcat(ca.vec(d0), ca.vec(d1))]), \
        ca.Function("Hm", [q], [ca.horzcat(*Hm)])


def _frobenius_bound(robot, hm_fun, points, refine):
    """max_q max_{|v|=1} ||sum_m v_m H^(m)(q)||_F (= sqrt of lambda_max of the Gram matrix of
    the H^(m) in the Frobenius inner product), sampled then refined by a pattern search."""
    n = robot.n

    def val(pts):
        pts = np.atleast_2d(pts)
        A = np.asarray(hm_fun.map(len(pts))(pts.T)).reshape(n, len(pts), n, n)  # [i, s, m, j]
        G = np.einsum("ismj,islj->sml", A, A)
        return np.sqrt(np.maximum(np.linalg.eigvalsh(G)[:, -1], 0.0))

    return refine_max(val, robot, points, val(points), 3 if refine else 0)[0]


def _lemma2(robot, split, points, refine):
    """(a, b, Frobenius bound of H^(m)) for H = k1 H0 + sum_m x_m H^(m)  [S003 Lemma 2, DERIVED]:
    a_ji = ||(sup|dH0_ji/dq_k|)_{k!=i}||, b_jim = ||(sup|dH^(m)_ji/dq_k|)_{k!=i}||."""
    n = robot.n
    dfun, hm_fun = _affine_derivatives(robot, split)
    sup = entrywise_sup(dfun, robot, points, refine)
    s0 = sup[: n ** 3].reshape(n, n, n).transpose(2, 1, 0)      # [j, i, k]
    # d1 is (n^3 x n), row m n^2 + i n + j: vec(d1) index = k n^3 + m n^2 + i n + j
    s1 = sup[n ** 3:].reshape(n, n, n, n).transpose(3, 2, 1, 0)  # [j, i, m, k]
    mask = 1.0 - np.eye(n)                                       # k != i
    a = np.sqrt(np.einsum("jik,ik->ji", s0 ** 2, mask))
    b = np.sqrt(np.einsum("jimk,ik->jim", s1 ** 2, mask))
    return a, b, _frobenius_bound(robot, hm_fun, points, refine)


@lru_cache(maxsize=32)
def _ii_speed_design_cached(robot, samples, seed, refine):
    n = robot.n
    stats = ConfigurationStats(robot, samples, seed)
    k_m, k_M, k_c = stats.extremes()

    def split(q):
        Mq = robot.mass_matrix(q)
        return (ldl_solve(Mq, ca.DM.eye(n)),
                [-ldl_solve(Mq, christoffel_column_matrix(robot, q, m)) for m in range(n)])

    a, b, _ = _lemma2(robot, split, stats.points, refine)
    q = ca.SX.sym("q", n)
    slices = ca.Function("Cslices", [q], [christoffel_slices(robot, q)])
    k_cF = _frobenius_bound(robot, slices, stats.points, refine)
    return IISpeedDesign(robot=robot.name, k_m=float(k_m), k_M=float(k_M), k_c=float(k_c),
                         k_cF=float(k_cF), deltabar_x=float(max(k_c / k_m, k_cF / k_M)),
                         dy_k1=a, dy_sx=b, samples=samples, refined=bool(refine))


def ii_speed_bounds(robot, samples=2000, seed=0, refine=True):
    """k_m, k_M, k_c and the Lemma-1/Lemma-2 bounds of the I&I speed observer [S003 (21), (27)].

    Sups over configurations: ``samples`` uniform samples of the joint ranges (plus the centre),
    then local refinement (pattern searches for k_m, k_M, k_c, k_cF and for the
    partial derivatives of H) unless ``refine`` is False.

    Parameters
    ----------
    robot : RobotModel (n joints)
    samples : int;  seed : int;  refine : bool

    Returns
    -------
    IISpeedDesign (cached per robot and arguments)."""
    return _ii_speed_design_cached(robot, int(samples), int(seed), bool(refine))


@lru_cache(maxsize=32)
def _ii_aov_design_cached(robot, samples, seed, refine):
    n = robot.n

    def split(q):
        _, T, Tinv = cholesky_velocity(robot, q)
        S = [skew_S(robot, q, ca.DM(np.eye(n)[:, k])) for k in range(n)]
        # Cbar(q, e_m) column k = S(q, e_k) e_m
        Cbar = [ca.horzcat(*[S[k][:, m] for k in range(n)]) for m in range(n)]
        return Tinv, [ca.mtimes(Cbar[m], Tinv) for m in range(n)]

    a, b, dbar_p = _lemma2(robot, split, sample_points(robot, samples, seed), refine)
    return IIAovDesign(robot=robot.name, deltabar_p=float(dbar_p), dq_k1=a, dq_p=b,
                       samples=samples, refined=bool(refine))


def ii_aov_bounds(robot, samples=2000, seed=0, refine=True):
    """Deltabar_p and the Lemma-2 coefficients of Deltabar_q for the AOV observer (docs/papers/seed003.md §5).

    Parameters
    ----------
    robot : RobotModel (n joints)
    samples : int;  seed : int;  refine : bool (as in ``ii_speed_bounds``)

    Returns
    -------
    IIAovDesign (cached per robot and arguments)."""
    return _ii_aov_design_cached(robot, int(samples), int(seed), bool(refine))
