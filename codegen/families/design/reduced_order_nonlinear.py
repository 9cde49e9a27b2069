"""Nonlinear gain k(y) = k0 K1(y) of the reduced-order observer, by deformation reduction
[S000 §VI] (beyond the paper: the authors sketch it, nobody published a design).

With V = 1/2 eps^T M eps (7) and the error flow of (6) for a general k(y),

    V' = -eps^T (C(y, x2hat) + F) eps - k0/2 eps^T Q1(y) eps,   Q1 = M dK1/dy + (M dK1/dy)^T

so the analogue of (12) is                                                     [DERIVED]

    k0 = max_y [c0(y)(v_max + eta) - lambda_min(F)] / (lambda_min(Q1(y)) / 2)           (12')

(K1 = y gives Q1 = 2M and (12) back) with the same region (13): V is unchanged. Deformation
reduction makes Q1(y) as close to a constant as possible, i.e. min lambda_min(Q1) /
max lambda_max(Q1) close to 1, by a least-squares fit of Q1(y) to 2I over sampled
configurations (only the symmetric part of M dK1/dy matters), with K1 = C phi(y) in the basis

    phi(y) = [y_l; sin y_l; cos y_l; sin 2y_l; cos 2y_l (l = 1..n); y_l cos y_m; y_l sin y_m (l != m)]

(linear in the coefficients C (n x nb), so the fit is one linear least-squares problem), then
blended with the paper's K1 = y where that widens the ratio (it always keeps Q1 > 0 reachable).
The condition (12') is then checked on fresh configurations (``verify``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .configurations import ConfigurationStats, refine_max, sample_points
from .reduced_order import _lambda_min_F


def features(y):
    """phi(y) (nb,) of the basis above, casadi; nb = 3n + 2n(n-1)."""
    n = y.shape[0]
    pairs = [(l, m) for l in range(n) for m in range(n) if l != m]
    return ca.vertcat(y, ca.sin(y), ca.cos(y), ca.sin(2 * y), ca.cos(2 * y),
                      *[y[l] * ca.cos(y[m]) for l, m in pairs], *[y[l] * ca.sin(y[m]) for l, m in pairs])


def feature_count(n):
    """nb = 5n + 2n(n - 1), the number of features phi(y) for ``n`` joints."""
    return 5 * n + 2 * n * (n - 1)


@dataclass
class NonlinearGainDesign:
    """Why k0 and K1 are what they are [S000 §VI; (12'), (13)]."""
    robot: str
    eta: float
    v_max: float
    k0: float                  # (12'), the gain used
    C: np.ndarray              # K1(y) = C phi(y), (n, nb)
    q_k0: np.ndarray           # configuration attaining the max in (12')
    ratio_Q: float             # min lambda_min(Q1) / max lambda_max(Q1) on the fit samples
    ratio_M: float             # the same for K1 = y (Q1 = 2M): lambda_min(M) / lambda_max(M)
    blend: float               # weight s of the fit against the paper's K1 = y
    fit_samples: int
    checks: dict = field(default_factory=dict)

    def as_dict(self):
        """The fields as a JSON-ready dict (arrays as lists)."""
        d = dict(self.__dict__)
        d["C"] = np.asarray(self.C).tolist()
        d["q_k0"] = [float(x) for x in self.q_k0]
        return d


class _Gain:
    """M(q), dK1/dy(q) and c0(q) of a robot at configurations (numpy, through casadi)."""

    def __init__(self, robot, samples, seed):
        n = robot.n
        y = ca.SX.sym("y", n)
        self.n, self.nb = n, feature_count(n)
        self._f = ca.Function("mp", [y], [robot.mass_matrix(y), ca.jacobian(features(y), y)])
        self.stats = ConfigurationStats(robot, samples, seed)

    def at(self, Q):
        """M (S, n, n) and P = dphi/dy (S, nb, n) at the rows of Q."""
        Q = np.atleast_2d(Q)
        S, n, nb = len(Q), self.n, self.nb
        Mm, Pm = (self._f if S == 1 else self._f.map(S))(Q.T)
        return (np.asarray(Mm).reshape(n, S, n).transpose(1, 0, 2),
                np.asarray(Pm).reshape(nb, S, n).transpose(1, 0, 2))

    def q_eigs(self, C, Q):
        """lambda_min, lambda_max of Q1 = M D + (M D)^T, D = C P, at the rows of Q."""
        M, P = self.at(Q)
        MD = M @ np.einsum("ib,sbl->sil", C, P)
        lam = np.linalg.eigvalsh(MD + MD.transpose(0, 2, 1))
        return lam[:, 0], lam[:, -1]


def fit_K1(M, P):
    """Least-squares C minimising sum_s ||Q1_s / 2 - I||_F^2, Q1_s = M_s C P_s + (M_s C P_s)^T
    (deformation reduction: Q1 as constant as the basis allows).

    Parameters
    ----------
    M : (S, n, n) mass matrices;  P : (S, nb, n) dphi/dy at the same configurations

    Returns
    -------
    (n, nb) array C."""
    S, n, _ = M.shape
    nb = P.shape[1]
    A = np.einsum("ski,sbl->sklib", M, P)                                 # (M C P)_kl in C_ib
    A = (0.5 * (A + A.transpose(0, 2, 1, 3, 4))).reshape(S * n * n, n * nb)
    b = np.tile(np.eye(n).ravel(), S)
    return np.linalg.lstsq(A, b, rcond=None)[0].reshape(n, nb)


def _blend(g, C_fit, Q, steps=21):
    """C = (1 - s) C_lin + s C_fit with C_lin the paper's K1 = y / mean lambda(M) (Q1 = 2M / ..):
    the s in [0, 1] with the largest min lambda_min(Q1) / max lambda_max(Q1) on Q (s = 0, the
    paper's gain, is always positive definite)."""
    M, _ = g.at(Q)
    C_lin = np.zeros_like(C_fit)
    C_lin[:, :g.n] = np.eye(g.n) / np.mean(np.linalg.eigvalsh(M))
    best = (-np.inf, None, None)
    for s in np.linspace(0.0, 1.0, steps):
        C = (1 - s) * C_lin + s * C_fit
        lmin, lmax = g.q_eigs(C, Q)
        if lmin.min() / lmax.max() > best[0]:
            best = (lmin.min() / lmax.max(), C, s)
    return best


def nonlinear_gain(robot, eta=1.0, v_max=2.0, fit_samples=300, samples=2000, seed=0):
    """Design K1 (deformation reduction) and k0 (12') for ``robot``.

    Parameters
    ----------
    robot : RobotModel (n joints)
    eta : float > 0, error radius [rad/s];  v_max : float > 0, speed bound [rad/s]
    fit_samples : int, configurations of the least-squares fit of K1
    samples, seed : configurations (and seed) over which k0 is maximised, then refined

    Returns
    -------
    NonlinearGainDesign"""
    if eta <= 0 or v_max <= 0:
        raise ValueError(f"eta and v_max must be positive, got eta={eta}, v_max={v_max}")
    g = _Gain(robot, samples, seed)
    fit = sample_points(robot, fit_samples, seed + 1)
    M, P = g.at(fit)
    ratio, C, s = _blend(g, fit_K1(M, P), g.stats.points)
    k0, q_k0 = gain_for(g, C, eta, v_max)
    return NonlinearGainDesign(robot=robot.name, eta=eta, v_max=v_max, C=C, fit_samples=fit_samples,
                               ratio_Q=float(ratio), blend=float(s),
                               ratio_M=float(g.stats.lmin.min() / g.stats.lmax.max()), k0=k0, q_k0=q_k0)


def gain_for(g, C, eta, v_max):
    """(k0, maximiser) of (12') for K1 = C phi(y): sampled on g.stats' points, then refined
    (c0 from every start of the power method at each refined point, not a warm start).
    ``g``: the sampled _Gain of the robot; ``C``: (n, nb), K1 = C phi(y); ``eta``, ``v_max``: rad/s
    (docs/papers/seed000.md §0 (12))."""
    lamF = _lambda_min_F(g.stats.robot)

    def need(c0, lmin_q):
        return (c0 * (v_max + eta) - lamF) / (0.5 * lmin_q)

    def at(Q):                       # batched: (K, n) -> (K,), c0 from every start (no warm start)
        Q = np.atleast_2d(Q)
        return need(g.stats.at(Q)[2], g.q_eigs(C, Q)[0])

    vals = need(g.stats.c0s, g.q_eigs(C, g.stats.points)[0])
    return refine_max(at, g.stats.robot, g.stats.points, vals, refine=10)


def verify(robot, design, samples=5000, seed=7):
    """The convergence condition (12') on fresh configurations: the margin
    k0/2 lambda_min(Q1(y)) + lambda_min(F) - c0(y)(v_max + eta) (>= 0 everywhere: V' <= -0 on
    the region), lambda_min(Q1) > 0, the spread of Q1 and the noise gain max ||k0 dK1/dy||_2.

    Parameters
    ----------
    robot : RobotModel
    design : NonlinearGainDesign
        k0, C (n, nb), eta and v_max (rad/s) to check.
    samples : int
        Number of fresh configurations.
    seed : int
        Seed of those configurations (not the design's).

    Returns
    -------
    dict with "min_margin", "min_lambda_Q", "ratio_Q", "max_noise_gain", "samples"."""
    g = _Gain(robot, samples, seed)
    C = np.asarray(design.C)
    lmin, lmax = g.q_eigs(C, g.stats.points)
    margin = 0.5 * design.k0 * lmin + _lambda_min_F(robot) - g.stats.c0s * (design.v_max + design.eta)
    _, P = g.at(g.stats.points)
    D = np.einsum("ib,sbl->sil", C, P)
    return {"min_margin": float(margin.min()), "min_lambda_Q": float(lmin.min()),
            "ratio_Q": float(lmin.min() / lmax.max()),
            "max_noise_gain": float(design.k0 * np.linalg.norm(D, ord=2, axis=(1, 2)).max()),
            "samples": samples}
