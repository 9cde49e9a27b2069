"""Sups and infs over configurations, shared by every gain design.

A quantity maximised over the joint ranges is first sampled (the centre of the ranges plus
uniform random configurations), then refined locally from the best samples by a batched
pattern search (every candidate of a sweep evaluated in one call). The Coriolis constant

    c0(q) = max_{|v| = 1} ||C(q, v)||_2 = max_{|v| = 1} ||C(q, v) v||_2          (docs/papers/seed000.md §0, [DERIVED])

(the second form because C(q, a) b = C(q, b) a makes the bilinear form symmetric, and the norm
of a symmetric bilinear form is the max of its quadratic form) is computed by gradient ascent of
||C(q, v) v||^2 on the unit sphere from several starts, all configurations at once. The ascent
needs only the products C(q, v) v and C(q, v)^T C(q, v) v: up to TENSOR_MAX joints from the
Christoffel tensor (n^3 entries per configuration), beyond from O(n) recursions
(codegen.families.design.rigid_batch for robots with a kinematic tree). M(q) and those products
are evaluated numerically below MEMORY_BYTES (configurations in chunks, the pairs of one ascent
iteration in blocks), and a design's sups stop with DesignBudgetError (naming --design k0=) after
DESIGN_BUDGET_S CPU seconds.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from ...core.symbolic import christoffel_slices
from .rigid_batch import TreeBatch

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


def pattern_search(fun, robot, starts, values, steps=STEPS, sweeps=SWEEPS, moved=None):
    """Local maxima of a batched ``fun`` from each row of ``starts``, inside the joint box.

    Each sweep evaluates the 2n coordinate neighbours of every current point at step h in one
    call and moves each point to its best neighbour when that is higher; h runs through
    ``steps`` (``sweeps`` sweeps at most per size).

    Parameters
    ----------
    fun : callable (K, n) -> (K,)
    robot : RobotModel, whose q_lower, q_upper bound the search
    starts : (K, n) configurations;  values : (K,) fun at those
    moved : optional callable (better (K,) bools, j (K,) ints): told which points moved, each to
        its neighbour j of the last call of ``fun`` (fun's rows are the K points' 2n neighbours)

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
            if moved is not None:
                moved(better, j)
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


# CPU seconds a design's sups over configurations may take (every catalog robot: < 2 s; a generic
# 50-joint chain: ~20 s); beyond, DesignBudgetError
DESIGN_BUDGET_S = 300.0


class DesignBudgetError(ValueError):
    """A design that cannot finish in its CPU budget (DESIGN_BUDGET_S)."""


class _Budget:
    """Raise DesignBudgetError naming ``robot`` once ``seconds`` of process CPU time have passed
    since construction (checked by ``check``, called between batches)."""

    def __init__(self, robot, seconds):
        self.robot, self.seconds, self.t0 = robot, seconds, time.process_time()

    def check(self):
        if time.process_time() - self.t0 > self.seconds:
            raise DesignBudgetError(
                f"the gain design for {self.robot.name} ({self.robot.n} joints) did not finish in its budget "
                f"of {self.seconds:g} s CPU (DESIGN_BUDGET_S): give the gain instead, e.g. --design k0=VALUE "
                f"(1/s) for the reduced-order families")


# memory bound of one batch of the c0 ascent and of the mass matrices (bytes): configurations
# are processed in chunks whose temporaries stay below it
MEMORY_BYTES = 64 * 2 ** 20


# the largest n whose c0 ascent iterates on the Christoffel tensor (n^3 entries per configuration,
# 2 n^3 per product), from all n unit vectors: every catalog arm (<= 7 joints), whose gains are
# those of the former tensor design up to round-off. Beyond, the ascent iterates on the O(n)
# Coriolis products with LARGE_UNIT_STARTS unit starts (those of largest ||C(q, e_k) e_k||) plus
# the 2 random ones, pruned every PRUNE_EVERY iterations to those within PRUNE_RATIO of their
# configuration's best, to relative LARGE_TOL; ``maximise`` refines LARGE_REFINE samples, c0 at
# each neighbour warm-started from its point's maximiser [ASSUMPTION: a local ascent either way;
# tested against the full start set in tests/families/test_rigid_batch.py]
TENSOR_MAX = 7
# pairs per call of the tree's products: n times the pairs below PAIR_ELEMENTS keeps each (3, n,
# pairs) temporary in cache (measured: 26 us per pair at n = 50 against 60 us at 1000 pairs)
PAIR_ELEMENTS = 6000
LARGE_UNIT_STARTS, PRUNE_EVERY, PRUNE_RATIO, LARGE_TOL, LARGE_REFINE = 3, 8, 0.98, 1e-10, 2


def c0_ascent(products, S, n, starts=None, extra_starts=2, iters=500, seed=0, tol=1e-13,
              pair_bytes=None, unit_starts=None, prune=False, budget=None, block=None):
    """c0(q_s) = max_{|v|=1} ||C(q_s, v) v||_2 for S configurations (docs/papers/seed000.md §0), from
    the products of the Coriolis matrix only (no Christoffel tensor).

    Gradient ascent on the sphere, v <- C(v)^T C(v) v / ||.|| (the gradient of ||C(v) v||^2 is
    4 C(v)^T C(v) v), every (configuration, start) pair iterated at once until its value
    settles (relative ``tol``), from ``starts`` or else from unit vectors plus ``extra_starts``
    random ones; the best start is kept. The unit vectors: all n, or the ``unit_starts`` with
    the largest ||C(q_s, e_k) e_k|| at each configuration (one product each), so that a
    configuration costs O(n) products, not O(n^2). Pairs are independent: ``products`` is
    called on at most ``block`` pairs at a time (default: those whose ``pair_bytes`` stay below
    MEMORY_BYTES).

    Parameters
    ----------
    products : callable (rows (P,), v (P, n)) -> (C(q_rows, v) v, C(q_rows, v)^T C(q_rows, v) v),
        each (P, n), rows indexing the S configurations
    S, n : int, number of configurations and of joints
    starts : optional (m, n) starts, each used for every configuration, or (S, m, n) per configuration
    extra_starts, iters, seed : random starts, most iterations, seed of the random starts
    pair_bytes : int, memory of one pair's products (default 1600 n)
    unit_starts : optional int, the most unit vectors started from (default all n)
    prune : bool, drop the starts below PRUNE_RATIO of their configuration's best every
        PRUNE_EVERY iterations (a start that far behind is taken not to overtake)
    budget : optional _Budget, checked every iteration
    block : optional int, most pairs per call of ``products`` (at most the memory bound's)

    Returns
    -------
    (c0 (S,), maximiser v (S, n))."""
    unit = starts is None and unit_starts is not None and n > unit_starts
    if starts is None:
        starts = np.vstack([np.eye(n), np.random.default_rng(seed).normal(size=(extra_starts, n))])
    starts = np.asarray(starts, dtype=float)
    starts = np.atleast_2d(starts) / np.linalg.norm(np.atleast_2d(starts), axis=-1, keepdims=True)
    V = starts if starts.ndim == 3 else np.broadcast_to(starts, (S,) + starts.shape)
    size = max(1, int(MEMORY_BYTES // (pair_bytes or 1600 * n)))
    products = _in_blocks(products, min(size, block or size))
    if unit:            # the unit_starts unit vectors of largest ||C(q, e_k) e_k||
        norms = np.empty((S, n))
        for lo in range(0, S, max(1, size // n)):
            configs = np.arange(lo, min(S, lo + max(1, size // n)))
            c, _ = products(np.repeat(configs, n), np.tile(np.eye(n), (len(configs), 1)))
            norms[configs] = np.linalg.norm(c, axis=1).reshape(len(configs), n)
        top = np.sort(np.argsort(-norms, axis=1, kind="stable")[:, :unit_starts], axis=1)
        V = np.concatenate([np.eye(n)[top], V[:, n:]], axis=1)
    return _ascent(products, np.arange(S), V, iters, tol, prune, budget)


def _in_blocks(products, size):
    """``products`` called on at most ``size`` pairs at a time, the results concatenated."""
    def blocked(rows, v):
        if len(rows) <= size:
            return products(rows, v)
        parts = [products(rows[i:i + size], v[i:i + size]) for i in range(0, len(rows), size)]
        return np.concatenate([c for c, _ in parts]), np.concatenate([h for _, h in parts])
    return blocked


def _ascent(products, configs, starts, iters, tol, prune=False, budget=None):
    """``c0_ascent`` on the configurations ``configs`` from ``starts`` (len(configs), m, n), all
    pairs at once."""
    S, m, n = starts.shape
    row = np.repeat(configs, m)                        # (configuration, start) pairs
    v = np.array(starts, dtype=float).reshape(S * m, n)

    def value(rows, v):
        c, h = products(row[rows], v)
        return np.linalg.norm(c, axis=1), h

    active = np.arange(len(v))
    val, g = value(active, v)
    for it in range(iters):
        if budget is not None:
            budget.check()
        if prune and m > 1 and it and it % PRUNE_EVERY == 0:
            best = np.repeat(np.max(val.reshape(S, m), axis=1), m)
            keep = val[active] >= PRUNE_RATIO * best[active]
            active, g = active[keep], g[keep]
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


def tensor_products(T):
    """The ``c0_ascent`` products of a Christoffel tensor T (S, n, n, n), T[s, i, j, k] = C(q_s, e_k)_ij:
    C(q, v) = sum_k T[:, :, k] v_k, then C v and C^T C v (2 n^3 per product: small n). The pairs
    of one configuration share one product T_s [v_1 .. v_m] (no copy of T_s per pair)."""
    S, n = T.shape[:2]
    T = np.asarray(T, dtype=float).reshape(S, n * n, n)

    def matrices(rows, v):
        """C(q_rows[k], v[k]) (P, n, n)."""
        if len(rows) < 2 or np.all(rows[1:] > rows[:-1]):         # one pair per configuration
            return (T[rows] @ np.asarray(v, dtype=float)[:, :, None]).reshape(len(rows), n, n)
        order = np.argsort(rows, kind="stable")
        u, first, inv = np.unique(rows[order], return_index=True, return_inverse=True)
        slot = np.empty(len(rows), dtype=int)
        slot[order] = np.arange(len(rows)) - first[inv]                  # the pair's column in its group
        group = np.empty(len(rows), dtype=int)
        group[order] = inv
        V = np.zeros((len(u), n, slot.max() + 1))
        V[group, :, slot] = v
        return (T[u] @ V)[group, :, slot].reshape(len(v), n, n)

    def products(rows, v):
        C = matrices(np.asarray(rows), v)
        c = np.einsum("pij,pj->pi", C, v)
        return c, np.einsum("pij,pi->pj", C, c)
    return products


def c0_batch(slices, n, starts=None, extra_starts=2, iters=500, seed=0, tol=1e-13):
    """``c0_ascent`` with the products of Christoffel slices (max_{|v|=1} ||sum_k v_k C_k||_2,
    module docstring).

    Parameters
    ----------
    slices : (S, n, n*n) array, [C(q_s, e_1) ... C(q_s, e_n)] for each configuration q_s
    n : int, number of joints
    starts, extra_starts, iters, seed, tol : as ``c0_ascent``

    Returns
    -------
    (c0 (S,), maximiser v (S, n))."""
    S = len(slices)
    # slices[s, i, k*n + j] = C(q_s, e_k)[i, j]
    T = np.asarray(slices, dtype=float).reshape(S, n, n, n).transpose(0, 1, 3, 2)
    return c0_ascent(tensor_products(T), S, n, starts, extra_starts, iters, seed, tol,
                     pair_bytes=16 * n ** 3)


class _SymbolicModel:
    """M(q), the Christoffel tensor and the Coriolis products of a robot through its CasADi
    functions (robots without a kinematic tree: closed-form and DH models, small n)."""

    def __init__(self, robot):
        n = robot.n
        q, v = ca.SX.sym("q", n), ca.SX.sym("v", n)
        C = robot.coriolis(q, v)
        c = ca.mtimes(C, v)
        self.n, self._M = n, robot.M
        self._P = ca.Function("Cprod", [q, v], [c, ca.mtimes(C.T, c)])
        self._T = ca.Function("Cslices", [q], [christoffel_slices(robot, q)]) if n <= TENSOR_MAX else None
        self.pair_bytes, self.config_bytes, self.kin_bytes, self.pair_block = 64 * n * n, 64 * n ** 3, 8 * n, None

    def batch(self, Q):
        self.Q = np.atleast_2d(Q)
        return self

    def _map(self, f, *args):
        P = args[0].shape[1]
        return f if P == 1 else f.map(P)

    def mass_matrix(self, rows=slice(None)):
        Q = self.Q[rows]
        S, n = len(Q), self.n
        return np.asarray(self._map(self._M, Q.T)(Q.T)).reshape(n, S, n).transpose(1, 0, 2)

    def christoffel(self, rows=slice(None)):
        Q = self.Q[rows]
        S, n = len(Q), self.n
        sl = np.asarray(self._map(self._T, Q.T)(Q.T)).reshape(n, S, n, n)   # [i, s, k, j]
        return sl.transpose(1, 0, 3, 2)

    def coriolis_products(self, rows, v):
        P = len(rows)
        c, h = self._map(self._P, v.T)(self.Q[rows].T, v.T)
        return np.asarray(c).reshape(self.n, P).T, np.asarray(h).reshape(self.n, P).T


class _TreeModel:
    """M(q), the Christoffel tensor and the Coriolis products of a robot with a kinematic tree
    (URDF robots), numerically (codegen.families.design.rigid_batch)."""

    def __init__(self, robot):
        self.tree, n = robot.tree, robot.n
        self.pair_bytes, self.kin_bytes = 1600 * n, 8 * 40 * n
        self.config_bytes = 8 * (60 * n + 40 * n * n + (16 * n ** 3 if n <= TENSOR_MAX else 0))
        self.pair_block = max(1, PAIR_ELEMENTS // n)

    def batch(self, Q):
        return TreeBatch(self.tree, Q)


def dynamics_model(robot):
    """The numeric M and Coriolis products of ``robot``: from its kinematic tree when it has one
    (``robot.tree``), else from its symbolic functions."""
    return _TreeModel(robot) if getattr(robot, "tree", None) is not None else _SymbolicModel(robot)


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
        self._budget = _Budget(robot, DESIGN_BUDGET_S)
        self._model = dynamics_model(robot)
        self.points = sample_points(robot, samples, seed)
        self.lmin, self.lmax, self.c0s, self._v = self.at(self.points)

    def at(self, pts, starts=None, c0=True, tol=1e-13, eig=True):
        """(lambda_min, lambda_max, c0, c0's maximiser v) at each row of pts, c0 from
        ``starts`` (default: unit vectors and random ones; None, None when ``c0`` is False) to
        relative tolerance ``tol``, lambda(M) unless ``eig`` is False (then None, None); pts (m, n)
        rad, results (m,) each and v (m, n). Memory below MEMORY_BYTES: configurations in chunks
        (their kinematics, the ascent's state, up to TENSOR_MAX joints their tensor), M(q) and the
        tensor's temporaries in sub-chunks, the ascent's pairs in blocks (``c0_ascent``), all
        pairs of a chunk iterated together."""
        pts = np.atleast_2d(np.asarray(pts, dtype=float))
        model, n = self._model, self.robot.n
        tensor = n <= TENSOR_MAX
        m = n + 2 if starts is None else np.shape(starts)[-2] if np.ndim(starts) > 1 else 1
        chunk = int(MEMORY_BYTES // (model.kin_bytes + 32 * m * n + (8 * n ** 3 if c0 and tensor else 0)))
        sub = max(1, int(MEMORY_BYTES // model.config_bytes))
        out = [np.empty(len(pts)) for _ in range(3)] + [np.empty((len(pts), n))]
        for lo in range(0, len(pts), max(1, chunk)):
            hi = min(len(pts), lo + max(1, chunk))
            self._budget.check()
            batch = model.batch(pts[lo:hi])
            for a in range(0, hi - lo, sub) if eig else ():
                lam = np.linalg.eigvalsh(batch.mass_matrix(slice(a, min(hi - lo, a + sub))))
                out[0][lo + a:lo + a + len(lam)], out[1][lo + a:lo + a + len(lam)] = lam[:, 0], lam[:, -1]
            part = starts[lo:hi] if starts is not None and np.ndim(starts) == 3 else starts
            if c0 and tensor:
                T = np.concatenate([batch.christoffel(slice(a, min(hi - lo, a + sub))) for a in range(0, hi - lo, sub)])
                out[2][lo:hi], out[3][lo:hi] = c0_ascent(
                    tensor_products(T), hi - lo, n, part, tol=tol,
                    pair_bytes=16 * n ** 3, budget=self._budget)
            elif c0:
                out[2][lo:hi], out[3][lo:hi] = c0_ascent(
                    batch.coriolis_products, hi - lo, n, part, tol=max(tol, LARGE_TOL),
                    pair_bytes=model.pair_bytes, unit_starts=LARGE_UNIT_STARTS, prune=True,
                    budget=self._budget, block=model.pair_block)
        lam = (out[0], out[1]) if eig else (None, None)
        return lam + ((out[2], out[3]) if c0 else (None, None))

    def maximise(self, fun, refine=3, c0=True, starts=None, eig=True):
        """max_q fun(lmin, lmax, c0) (vectorised): best samples (and ``starts``, configurations),
        then a pattern search from each, lambda(M) (when ``eig``: fun uses lmin or lmax, else they
        are None) and c0 (when ``c0``: fun uses it) at each neighbour, c0 started
        from the maximiser v at the point it neighbours (warm, one start; the maximisers of
        several samples at every neighbour gave the same gains to 1e-11 relative on ur5 and
        panda) and resolved to 1e-10 relative; ``refine`` best samples are refined (beyond
        TENSOR_MAX joints LARGE_REFINE at most).

        Returns (max value, maximiser (n,))."""
        vals = fun(self.lmin, self.lmax, self.c0s)
        if self.robot.n > TENSOR_MAX:
            refine = min(refine, LARGE_REFINE)
        order = np.argsort(vals)[::-1][:max(refine, 1)]
        P, V, W = self.points[order], vals[order], self._v[order]
        if starts is not None and len(starts):
            starts = np.atleast_2d(starts)
            lmin, lmax, c0s, v = self.at(starts, W[:1], c0, tol=1e-10, eig=eig)
            P, V = np.vstack([P, starts]), np.concatenate([V, fun(lmin, lmax, c0s)])
            W = np.vstack([W, v if c0 else np.repeat(W[:1], len(starts), axis=0)])
        last = {}

        def f(Q):
            parent = np.arange(len(Q)) // (len(Q) // len(W))
            lmin, lmax, c0s, v = self.at(Q, W[parent][:, None, :], c0, tol=1e-10, eig=eig)
            last["v"] = v
            return fun(lmin, lmax, c0s)

        def moved(better, j):
            if c0:
                W[better] = last["v"].reshape(len(W), -1, self.robot.n)[better, j[better]]
        cur, Q = pattern_search(f, self.robot, P, V, moved=moved) if refine else (V, P)
        i = int(np.argmax(cur))
        return float(cur[i]), np.asarray(Q[i])

    def extremes(self, refine=3):
        """(min_q lambda_min(M(q)), max_q lambda_max(M(q)), max_q c0(q)), each refined from its
        ``refine`` best samples (``maximise``)."""
        return (-self.maximise(lambda lmin, lmax, c0: -lmin, refine, c0=False)[0],
                self.maximise(lambda lmin, lmax, c0: lmax, refine, c0=False)[0],
                self.maximise(lambda lmin, lmax, c0: c0, refine, eig=False)[0])


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
