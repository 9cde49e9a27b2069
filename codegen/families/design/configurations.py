"""Sups and infs over configurations, shared by every gain design.

A quantity maximised over the joint ranges is first sampled (the centre of the ranges plus
uniform random configurations), then refined locally from the best samples by a batched
pattern search (every candidate of a sweep evaluated in one call). The Coriolis constant

    c0(q) = max_{|v| = 1} ||C(q, v)||_2 = max_{|v| = 1} ||C(q, v) v||_2          (docs/papers/seed000.md §0, [DERIVED])

(the second form because C(q, a) b = C(q, b) a makes the bilinear form symmetric, and the norm
of a symmetric bilinear form is the max of its quadratic form) is computed by gradient ascent of
||C(q, v) v||^2 on the unit sphere from several starts, all configurations at once.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...core.symbolic import christoffel_slices

# pattern-search step sizes (rad or m) and sweeps per size
STEPS = (0.2, 0.05, 0.0125, 3e-3, 1e-3, 2.5e-4, 6e-5, 1.5e-5)
SWEEPS = 6


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


def pattern_search(fun, robot, starts, values, steps=STEPS, sweeps=SWEEPS):
    """Local maxima of a batched ``fun`` from each row of ``starts``, inside the joint box.

    Each sweep evaluates the 2n coordinate neighbours of every current point at step h in one
    call and moves each point to its best neighbour when that is higher; h runs through
    ``steps`` (``sweeps`` sweeps at most per size).

    Parameters
    ----------
    fun : callable (K, n) -> (K,)
    robot : RobotModel, whose q_lower, q_upper bound the search
    starts : (K, n) configurations;  values : (K,) fun at those

    Returns
    -------
    (values (K,), points (K, n))."""
    Q, cur = np.array(starts, dtype=float), np.array(values, dtype=float)
    K, n = Q.shape
    D = np.vstack([np.eye(n), -np.eye(n)])
    lo, up = robot.q_lower, robot.q_upper
    for h in steps:
        for _ in range(sweeps):
            cand = np.clip(Q[:, None, :] + h * D[None], lo, up)            # (K, 2n, n)
            val = np.asarray(fun(cand.reshape(-1, n)), dtype=float).reshape(K, 2 * n)
            j = np.argmax(val, axis=1)
            best = val[np.arange(K), j]
            better = best > cur
            if not np.any(better):
                break
            Q[better], cur[better] = cand[better, j[better]], best[better]
    return cur, Q


def refine_max(fun, robot, points, vals, refine=3, starts=None):
    """max_q fun(q) over the joint box: the best of the sampled ``vals`` (= fun at ``points``),
    then a pattern search from each of the ``refine`` best points (and from ``starts``).

    Parameters
    ----------
    fun : callable (K, n) -> (K,), batched
    robot : RobotModel, whose q_lower, q_upper bound the search
    points : (S, n) sampled configurations;  vals : (S,) fun at those
    refine : int, number of local searches from samples
    starts : optional (m, n) further configurations to search from (e.g. a previous maximiser)

    Returns
    -------
    (max value, maximiser (n,))."""
    order = np.argsort(vals)[::-1][:max(refine, 1)]
    P, V = points[order], vals[order]
    if starts is not None and len(starts):
        P, V = np.vstack([P, starts]), np.concatenate([V, fun(np.asarray(starts))])
    cur, Q = pattern_search(fun, robot, P, V) if refine else (V, P)
    i = int(np.argmax(cur))
    return float(cur[i]), np.asarray(Q[i])


def c0_batch(slices, n, starts=None, extra_starts=2, iters=500, seed=0, tol=1e-13):
    """c0 = max_{|v|=1} ||C(q, v) v||_2 for a batch of configurations (docs/papers/seed000.md §0; equal to
    max_{|v|=1} ||sum_k v_k C_k||_2 for Christoffel slices, module docstring).

    Gradient ascent on the sphere, v <- C(v)^T C(v) v / ||.|| (the gradient of ||C(v) v||^2 is
    4 C(v)^T C(v) v), every (configuration, start) pair iterated at once until its value
    settles (relative ``tol``), from ``starts`` or else from the n unit vectors plus
    ``extra_starts`` random ones; the best start is kept.

    Parameters
    ----------
    slices : (S, n, n*n) array, [C(q_s, e_1) ... C(q_s, e_n)] for each configuration q_s
    n : int, number of joints
    starts : optional (m, n) starts, each used for every configuration
    extra_starts, iters, seed : random starts, most iterations, seed of the random starts

    Returns
    -------
    (c0 (S,), maximiser v (S, n))."""
    S = len(slices)
    if starts is None:
        starts = np.vstack([np.eye(n), np.random.default_rng(seed).normal(size=(extra_starts, n))])
    starts = np.atleast_2d(starts) / np.linalg.norm(np.atleast_2d(starts), axis=1, keepdims=True)
    m = len(starts)
    # slices[s, i, k*n + j] = C(q_s, e_k)[i, j]; T[s, i*n + j, k] so that C(q_s, v) = T[s] @ v
    T = np.asarray(slices, dtype=float).reshape(S, n, n, n).transpose(0, 1, 3, 2).reshape(S, n * n, n)
    row = np.repeat(np.arange(S), m)                   # (configuration, start) pairs
    v = np.tile(starts, (S, 1))

    def value(rows, v):
        C = (T[row[rows]] @ v[:, :, None]).reshape(len(v), n, n)
        c = (C @ v[:, :, None])[:, :, 0]
        return np.linalg.norm(c, axis=1), (C.transpose(0, 2, 1) @ c[:, :, None])[:, :, 0]

    active = np.arange(len(v))
    val, g = value(active, v)
    for _ in range(iters):
        ng = np.linalg.norm(g, axis=1, keepdims=True)
        v[active] = np.where(ng > 0, g / np.where(ng > 0, ng, 1), v[active])
        new, g = value(active, v[active])
        moving = np.abs(new - val[active]) > tol * np.maximum(new, 1)
        val[active] = new
        active, g = active[moving], g[moving]
        if not len(active):
            break
    best = np.argmax(val.reshape(S, m), axis=1)
    pick = np.arange(S) * m + best
    return val[pick], v[pick]


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
        self._M = ca.Function("M", [q], [robot.mass_matrix(q)])
        self._C = ca.Function("C", [q], [christoffel_slices(robot, q)])
        self.points = sample_points(robot, samples, seed)
        self.lmin, self.lmax, self.c0s, self._v = self.at(self.points)

    def _eval(self, f, pts, cols):
        """f at each row of pts, as (S, n, cols) (a mapped output is [f(q_1) f(q_2) ...])."""
        n, S = self.robot.n, len(pts)
        return np.asarray((f if S == 1 else f.map(S))(np.asarray(pts).T)).reshape(n, S, cols).transpose(1, 0, 2)

    def at(self, pts, starts=None, c0=True, tol=1e-13):
        """(lambda_min, lambda_max, c0, c0's maximiser v) at each row of pts, c0 from
        ``starts`` (default: unit vectors and random ones; None, None when ``c0`` is False) to
        relative tolerance ``tol``; pts (m, n) rad, results (m,) each and v (m, n)."""
        lam = np.linalg.eigvalsh(self._eval(self._M, pts, self.robot.n))
        if not c0:
            return lam[:, 0], lam[:, -1], None, None
        c0s, v = c0_batch(self._eval(self._C, pts, self.robot.n ** 2), self.robot.n, starts, tol=tol)
        return lam[:, 0], lam[:, -1], c0s, v

    def maximise(self, fun, refine=3, c0=True, starts=None):
        """max_q fun(lmin, lmax, c0) (vectorised): best samples (and ``starts``, configurations),
        then a pattern search from each, c0 (when ``c0``: fun uses it) started from the
        maximisers v of those samples and resolved to 1e-10 relative during the search; ``refine``
        best samples are refined.

        Returns (max value, maximiser (n,))."""
        vals = fun(self.lmin, self.lmax, self.c0s)
        v0 = self._v[np.argsort(vals)[::-1][:max(refine, 1)]]
        return refine_max(lambda Q: fun(*self.at(Q, v0, c0, tol=1e-10)[:3]), self.robot, self.points,
                          vals, refine, starts)

    def extremes(self, refine=3):
        """(min_q lambda_min(M(q)), max_q lambda_max(M(q)), max_q c0(q)), each refined from its
        ``refine`` best samples (``maximise``)."""
        return (-self.maximise(lambda lmin, lmax, c0: -lmin, refine, c0=False)[0],
                self.maximise(lambda lmin, lmax, c0: lmax, refine, c0=False)[0],
                self.maximise(lambda lmin, lmax, c0: c0, refine)[0])


def entrywise_sup(f, robot, points, refine, max_refine=64):
    """Entrywise sup over q of |f(q)|: max over ``points``, then (``refine``) a pattern search,
    inside the joint ranges, from the best point of each of the ``max_refine`` largest entries
    [ASSUMPTION: smaller entries keep their sampled max].

    Parameters
    ----------
    f : casadi.Function q (n,) -> one flat vector (E,)
    robot : RobotModel, whose q_lower, q_upper bound the search
    points : (S, n) sampled configurations
    refine : bool;  max_refine : int

    Returns
    -------
    (E,) array of sups."""
    n = robot.n
    V = np.abs(np.asarray(f.map(len(points))(points.T)))    # (E, S)
    best_idx = np.argmax(V, axis=1)
    best = V[np.arange(V.shape[0]), best_idx]
    if not refine:
        return best
    sel = np.argsort(best)[::-1][:max_refine]
    sel = sel[best[sel] > 0]
    if len(sel) == 0:
        return best
    entry = np.repeat(sel, 2 * n)             # the entry each candidate of a sweep is refined for
    fmap = f.map(len(entry))
    best[sel] = pattern_search(lambda Q: np.abs(np.asarray(fmap(Q.T)))[entry, np.arange(len(entry))],
                               robot, points[best_idx[sel]], best[sel])[0]
    return best
