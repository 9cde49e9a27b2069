"""Sups and infs over configurations, shared by every gain design.

A quantity maximised over the joint ranges is first sampled (the centre of the ranges plus
uniform random configurations), then refined locally from the best samples: bounded
Nelder-Mead for a scalar, a batch pattern search for many entries at once. The Coriolis
constant

    c0(q) = max_{|v| = 1} ||C(q, v)||_2                                       (SPEC §0, [DERIVED])

is the spectral norm of the 3-tensor C_ijk(q) = C(q, e_k)_ij, computed by the higher-order
power method from several starts.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.optimize import minimize

from ..symbolic import christoffel_slices


def sample_points(robot, samples, seed):
    """The centre of the joint ranges, then ``samples`` uniform random configurations.

    Parameters
    ----------
    robot : RobotModel (n joints, with q_lower, q_upper and sample_configurations)
    samples : int, number of random configurations
    seed : int, seed of the random draw

    Returns
    -------
    (samples + 1, n) array of configurations [rad or m]."""
    return np.vstack([0.5 * (robot.q_lower + robot.q_upper), robot.sample_configurations(samples, seed)])


def refine_max(fun, robot, points, vals, refine=3, before=None):
    """max_q fun(q) over the joint box: the best of the sampled ``vals`` (= fun at ``points``),
    then bounded Nelder-Mead from each of the ``refine`` best points.

    Parameters
    ----------
    fun : callable (n,) -> float
    robot : RobotModel, whose q_lower, q_upper bound the search
    points : (S, n) sampled configurations;  vals : (S,) fun at those
    refine : int, number of local searches
    before : optional callable(i) run before the search that starts at points[i]

    Returns
    -------
    (max value, maximiser (n,))."""
    order = np.argsort(vals)[::-1]
    best, best_q = vals[order[0]], points[order[0]]
    for i in order[:refine]:
        if before is not None:
            before(i)
        res = minimize(lambda q: -fun(q), points[i], method="Nelder-Mead",
                       bounds=list(zip(robot.q_lower, robot.q_upper)),
                       options={"xatol": 1e-8, "fatol": 1e-11, "maxiter": 100 * robot.n})
        if -res.fun > best:
            best, best_q = -res.fun, res.x
    return float(best), np.asarray(best_q)


def c0_batch(slices, n, starts=None, extra_starts=4, iters=50, seed=0):
    """c0 = max_{|v|=1} ||sum_k v_k C_k||_2 for a batch of configurations (SPEC §0).

    Higher-order power method (each sweep can only increase the value), from ``starts`` or
    else from the n unit vectors plus ``extra_starts`` random ones.

    Parameters
    ----------
    slices : (S, n, n*n) array, [C(q_s, e_1) ... C(q_s, e_n)] for each configuration q_s
    n : int, number of joints
    starts : optional (m, n) or (S, n) warm starts
    extra_starts, iters, seed : random starts, sweeps per start, seed of the random starts

    Returns
    -------
    (c0 (S,), maximiser v (S, n))."""
    Ck = np.asarray(slices).reshape(-1, n, n, n).transpose(0, 1, 3, 2)
    # slices[s, i, k*n + j] = C(q_s, e_k)[i, j]; after the transpose Ck[s, i, j, k]
    S = Ck.shape[0]
    if starts is None:
        starts = np.vstack([np.eye(n), np.random.default_rng(seed).normal(size=(extra_starts, n))])
    best, best_v = np.full(S, -1.0), np.zeros((S, n))
    for v0 in starts:
        v = np.broadcast_to(v0 / np.linalg.norm(v0), (S, n)).copy()
        last = np.zeros((S, 1))
        for _ in range(iters):
            U, _, Vt = np.linalg.svd(np.einsum("sijk,sk->sij", Ck, v))
            w = np.einsum("si,sijk,sj->sk", U[:, :, 0], Ck, Vt[:, 0, :])
            nw = np.linalg.norm(w, axis=1, keepdims=True)
            v = np.where(nw > 0, w / np.where(nw > 0, nw, 1), v)
            if np.all(np.abs(nw - last) <= 1e-13 * np.maximum(nw, 1)):
                break
            last = nw
        val = np.linalg.norm(np.einsum("sijk,sk->sij", Ck, v), ord=2, axis=(1, 2))
        better = val > best
        best, best_v[better] = np.where(better, val, best), v[better]
    return best, best_v


class ConfigurationStats:
    """lambda_min(M(q)), lambda_max(M(q)) and c0(q) over sampled configurations, and their
    local refinement.

    Parameters
    ----------
    robot : RobotModel (n joints)
    samples : int, number of random configurations (the centre of the ranges is added)
    seed : int, seed of the random draw
    """

    def __init__(self, robot, samples=2000, seed=0):
        self.robot, self.samples = robot, samples
        q = ca.SX.sym("q", robot.n)
        self._f = ca.Function("stats", [q], [robot.mass_matrix(q), christoffel_slices(robot, q)])
        pts = sample_points(robot, samples, seed)
        Ms, Cs = self._eval(pts)
        lam = np.linalg.eigvalsh(Ms)
        self.points, self.lmin, self.lmax = pts, lam[:, 0], lam[:, -1]
        self.c0s, self._v = c0_batch(Cs, robot.n)
        self._warm = self._v[0]

    def _eval(self, pts):
        """M and [C(q, e_1) ... C(q, e_n)] at each row of pts: (S, n, n), (S, n, n*n)."""
        n, S = self.robot.n, len(pts)
        f = self._f if S == 1 else self._f.map(S)
        Mm, Cm = f(pts.T)
        # a mapped output is [out(q_1) out(q_2) ...] side by side
        Ms = np.asarray(Mm).reshape(n, S, n).transpose(1, 0, 2)
        Cs = np.asarray(Cm).reshape(n, S, n * n).transpose(1, 0, 2)
        return Ms, Cs

    def at(self, q):
        """(lambda_min, lambda_max, c0) at one configuration; c0's power method is warm-started
        from the previous maximiser (local refinement moves q a little at a time)."""
        Ms, Cs = self._eval(np.atleast_2d(q))
        lam = np.linalg.eigvalsh(Ms[0])
        c0, v = c0_batch(Cs, self.robot.n, starts=[self._warm])
        self._warm = v[0]
        return lam[0], lam[-1], c0[0]

    def maximise(self, fun, refine=3):
        """max_q fun(lmin, lmax, c0): best samples, then bounded Nelder-Mead from each.

        Returns (max value, maximiser (n,))."""
        def warm(i):
            self._warm = self._v[i]
        return refine_max(lambda q: fun(*self.at(q)), self.robot, self.points,
                          fun(self.lmin, self.lmax, self.c0s), refine, before=warm)

    def extremes(self):
        """(min_q lambda_min(M(q)), max_q lambda_max(M(q)), max_q c0(q)), each refined."""
        return (-self.maximise(lambda lmin, lmax, c0: -lmin)[0],
                self.maximise(lambda lmin, lmax, c0: lmax)[0],
                self.maximise(lambda lmin, lmax, c0: c0)[0])


def entrywise_sup(f, robot, points, refine, max_refine=64,
                  steps=(0.2, 0.05, 0.0125, 3e-3, 1e-3, 2.5e-4, 6e-5, 1.5e-5)):
    """Entrywise sup over q of |f(q)|: max over ``points``, then (``refine``) a batch pattern
    search, inside the joint ranges, from the best point of each of the ``max_refine`` largest
    entries [ASSUMPTION: smaller entries keep their sampled max].

    Parameters
    ----------
    f : casadi.Function q (n,) -> one flat vector (E,)
    robot : RobotModel, whose q_lower, q_upper bound the search
    points : (S, n) sampled configurations
    refine : bool;  max_refine : int;  steps : pattern-search step sizes [rad or m]

    Returns
    -------
    (E,) array of sups."""
    n = robot.n
    V = np.abs(np.asarray(f.map(len(points))(points.T)))    # (E, S)
    best_idx = np.argmax(V, axis=1)
    best = V[np.arange(V.shape[0]), best_idx]
    if not refine:
        return best
    lo, up = robot.q_lower, robot.q_upper
    sel = np.argsort(best)[::-1][:max_refine]
    sel = sel[best[sel] > 0]
    if len(sel) == 0:
        return best
    Q = points[best_idx[sel]].copy()
    cur = best[sel].copy()
    fE = f.map(len(sel))
    for h in steps:
        for _ in range(4):
            improved = False
            for k in range(n):
                for sgn in (1.0, -1.0):
                    cand = Q.copy()
                    cand[:, k] = np.clip(cand[:, k] + sgn * h, lo[k], up[k])
                    val = np.abs(np.asarray(fE(cand.T)))[sel, np.arange(len(sel))]
                    better = val > cur
                    if np.any(better):
                        improved = True
                        cur = np.where(better, val, cur)
                        Q[better] = cand[better]
            if not improved:
                break
    best[sel] = cur
    return best
