"""Offline gain design (numbers, not symbols).

Reduced-order observer [S000 (8), (12), (13), Remark 3] and its scheduled gains (16):

    c0(q)   = max_{|v| = 1} ||C(q, v)||_2                          (SPEC §0, [DERIVED])
    k0      = max_q [c0(q)(v_max + eta) - lambda_min(F)] / lambda_min(M(q))      (12)
    lambda1 = min_q lambda_min(M(q)) / 2,  lambda2 = max_q lambda_max(M(q)) / 2  (8)
    radius of E = eta sqrt(lambda1 / lambda2)                                    (13)
    Remark 3: k0 = [c0bar (v_max + eta) - lambda_min(F)] / (2 lambda1)
    k_r     = max_q [c0(q)(eta + r vbar) - lambda_min(F)] / lambda_min(M(q))     (16)

Maxima over configurations: sample the joint ranges (uniform random plus the
robot's range corners/centre), then refine the best samples locally (bounded
Nelder-Mead). c0(q) is the spectral norm of the 3-tensor C_ijk(q) = C(q, e_k)_ij,
computed by the higher-order power method from several starts.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np
from scipy.optimize import minimize


# ----------------------------------------------------------------------------- helpers
def c0_batch(slices, n, starts=None, extra_starts=4, iters=50, seed=0):
    """c0 for a batch: slices (S, n, n*n) = [C(q_s, e_1) ... C(q_s, e_n)].

    max_{|v|=1} ||sum_k v_k C_k||_2 by the higher-order power method (each sweep can only
    increase the value), from ``starts`` ((m, n) or (S, n) warm starts) or else from the n unit
    vectors plus ``extra_starts`` random ones. Returns (c0 (S,), maximiser v (S, n))."""
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
    """lambda_min(M), lambda_max(M) and c0 over sampled configurations, and local refinement."""

    def __init__(self, robot, samples=2000, seed=0):
        self.robot, self.samples = robot, samples
        n = robot.n
        q = ca.SX.sym("q", n)
        blocks = [robot.coriolis(q, ca.DM(np.eye(n)[:, k])) for k in range(n)]
        self._f = ca.Function("stats", [q], [robot.mass_matrix(q), ca.horzcat(*blocks)])
        pts = np.vstack([0.5 * (robot.q_lower + robot.q_upper),
                         robot.sample_configurations(samples, seed)])
        Ms, Cs = self._eval(pts)
        lam = np.linalg.eigvalsh(Ms)
        self.points, self.lmin, self.lmax = pts, lam[:, 0], lam[:, -1]
        self.c0s, self._v = c0_batch(Cs, n)
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
        """max_q fun(lmin, lmax, c0): best samples, then bounded Nelder-Mead from each."""
        r = self.robot
        vals = fun(self.lmin, self.lmax, self.c0s)
        order = np.argsort(vals)[::-1][:refine]
        best, best_q = vals[order[0]], self.points[order[0]]
        for i in order:
            self._warm = self._v[i]
            res = minimize(lambda q: -fun(*self.at(q)), self.points[i], method="Nelder-Mead",
                           bounds=list(zip(r.q_lower, r.q_upper)),
                           options={"xatol": 1e-8, "fatol": 1e-11, "maxiter": 100 * r.n})
            if -res.fun > best:
                best, best_q = -res.fun, res.x
        return float(best), np.asarray(best_q)


# ----------------------------------------------------------------------------- report
@dataclass
class ReducedOrderDesign:
    """Why k0 is what it is [S000 (8), (12), (13), Remark 3]."""
    robot: str
    eta: float
    v_max: float
    lambda_min_F: float
    k0: float                  # (12), the gain used
    q_k0: np.ndarray           # configuration attaining the max in (12)
    k0_remark3: float          # Remark 3, conservative
    c0bar: float               # max_q c0(q)
    lambda1: float             # min_q lambda_min(M)/2
    lambda2: float             # max_q lambda_max(M)/2
    radius: float              # eta sqrt(lambda1/lambda2), region (13)
    samples: int

    def as_dict(self):
        d = dict(self.__dict__)
        d["q_k0"] = [float(x) for x in self.q_k0]
        return d

    def __str__(self):
        q = np.array2string(np.asarray(self.q_k0), precision=4)
        return "\n".join([
            f"reduced-order gain design for {self.robot} (eta = {self.eta:g}, v_max = {self.v_max:g}):",
            f"  k0 = max_q [c0(q)(v_max+eta) - lambda_min(F)] / lambda_min(M(q)) = {self.k0:.6g}   (12)",
            f"       attained at q = {q}",
            f"  Remark 3: [c0bar (v_max+eta) - lambda_min(F)] / (2 lambda1) = {self.k0_remark3:.6g}",
            f"  c0bar = {self.c0bar:.6g},  lambda_min(F) = {self.lambda_min_F:.6g}",
            f"  lambda1 = {self.lambda1:.6g}, lambda2 = {self.lambda2:.6g}   (8)",
            f"  region of attraction contains |eps| < eta sqrt(lambda1/lambda2) = {self.radius:.4g}   (13)",
            f"  ({self.samples} sampled configurations, best 3 refined locally)",
        ])


def _gain_objective(lamF, speed):
    """[c0 (speed) - lambda_min(F)] / lambda_min(M), the quantity maximised in (12) and (16)."""
    return lambda lmin, lmax, c0: (c0 * speed - lamF) / lmin


@lru_cache(maxsize=32)
def _design_cached(robot, eta, v_max, samples, seed):
    stats = ConfigurationStats(robot, samples, seed)
    lamF = float(np.linalg.eigvalsh(0.5 * (robot.F + robot.F.T))[0])
    k0, q_k0 = stats.maximise(_gain_objective(lamF, v_max + eta))
    lmin, _ = stats.maximise(lambda lmin, lmax, c0: -lmin)
    lmax, _ = stats.maximise(lambda lmin, lmax, c0: lmax)
    c0bar, _ = stats.maximise(lambda lmin, lmax, c0: c0)
    lambda1, lambda2 = -lmin / 2, lmax / 2
    return ReducedOrderDesign(
        robot=robot.name, eta=eta, v_max=v_max, lambda_min_F=lamF, k0=k0, q_k0=np.asarray(q_k0),
        k0_remark3=(c0bar * (v_max + eta) - lamF) / (2 * lambda1), c0bar=c0bar,
        lambda1=lambda1, lambda2=lambda2, radius=eta * np.sqrt(lambda1 / lambda2), samples=samples)


def reduced_order_gain(robot, eta=1.0, v_max=2.0, samples=2000, seed=0):
    """Design k0 for the reduced-order observer [S000 (12)]; returns a ReducedOrderDesign."""
    if eta <= 0 or v_max <= 0:
        raise ValueError(f"eta and v_max must be positive, got eta={eta}, v_max={v_max}")
    return _design_cached(robot, float(eta), float(v_max), int(samples), int(seed))


def scheduled_gains(robot, eta=1.0, vbar=2.0, r_max=6, samples=2000, seed=0):
    """k_r for r = 1..r_max [S000 (16)]: max_q [c0(q)(eta + r vbar) - lambda_min(F)] / lambda_min(M(q))."""
    stats = ConfigurationStats(robot, samples, seed)
    lamF = float(np.linalg.eigvalsh(0.5 * (robot.F + robot.F.T))[0])
    return np.array([stats.maximise(_gain_objective(lamF, eta + r * vbar))[0]
                     for r in range(1, r_max + 1)])
