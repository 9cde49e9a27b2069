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


# ============================================================================= I&I speed observer
# Seed 003 (Arbo, Grotli & Gravdahl), SPEC §4.1-§4.2: the constants of P1, P4 and the bounds
# Deltabar_x (Lemma 1) and Deltabar_y (Lemma 2), computed for any robot (never typed in).
#
#   k_m = min_q lambda_min(M(q)),  k_M = max_q lambda_max(M(q))                      [S003 P1]
#   k_c = max_q max_{|v|=1} ||C(q, v)||_2                                            [S003 P4]
#   ||Deltabar_x|| = k_c / k_m                                                      [S003 (21)]
#   H(q, x) = k1 H0(q) + sum_m x_m H^(m)(q),  H0 = M^{-1},  H^(m) = -M^{-1} C(q, e_m)  [DERIVED]
#   Deltabar_y,ji(s_x) = k1 a_ji + sum_m |s_x,m| b_jim                               [S003 Lemma 2, DERIVED]
#      a_ji  = || (sup_q |dH0_ji/dq_k|)_{k != i} ||_2
#      b_jim = || (sup_q |dH^(m)_ji/dq_k|)_{k != i} ||_2
# Column i of Delta_y depends on e_y only through the entries k != i (column i is evaluated at
# s_y with y_i in place i), and |dDelta_ji/de| <= k1 |dH0_ji/dq| + sum_m |x_m| |dH^(m)_ji/dq|
# entrywise, whose 2-norm over k is bounded by the triangle inequality: the seed's "sum of the
# sup-norms of the terms" rule, made computable for any robot.


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


def _abs_sups(f, robot, points, refine, max_refine=64,
              steps=(0.2, 0.05, 0.0125, 3e-3, 1e-3, 2.5e-4, 6e-5, 1.5e-5)):
    """Entrywise sup over q of |f(q)| (f: q -> one flat vector): max over ``points``, then
    (``refine``) a batch pattern search, inside the joint ranges, from the best point of each of
    the ``max_refine`` largest entries [ASSUMPTION: smaller entries keep their sampled max]."""
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


def _frobenius_bound(robot, hm_fun, points, refine):
    """max_q max_{|v|=1} ||sum_m v_m H^(m)(q)||_F (= sqrt of lambda_max of the Gram matrix of
    the H^(m) in the Frobenius inner product), sampled then refined by Nelder-Mead."""
    n = robot.n

    def val(pts):
        pts = np.atleast_2d(pts)
        A = np.asarray(hm_fun.map(len(pts))(pts.T)).reshape(n, len(pts), n, n)  # [i, s, m, j]
        G = np.einsum("ismj,islj->sml", A, A)
        return np.sqrt(np.maximum(np.linalg.eigvalsh(G)[:, -1], 0.0))

    vals = val(points)
    best = float(vals.max())
    if refine:
        for i in np.argsort(vals)[::-1][:3]:
            res = minimize(lambda q: -val(q)[0], points[i], method="Nelder-Mead",
                           bounds=list(zip(robot.q_lower, robot.q_upper)),
                           options={"xatol": 1e-8, "fatol": 1e-11, "maxiter": 100 * n})
            best = max(best, -float(res.fun))
    return best


def _lemma2(robot, split, points, refine):
    """(a, b, Frobenius bound of H^(m)) for H = k1 H0 + sum_m x_m H^(m)  [S003 Lemma 2, DERIVED]:
    a_ji = ||(sup|dH0_ji/dq_k|)_{k!=i}||, b_jim = ||(sup|dH^(m)_ji/dq_k|)_{k!=i}||."""
    n = robot.n
    dfun, hm_fun = _affine_derivatives(robot, split)
    sup = _abs_sups(dfun, robot, points, refine)
    s0 = sup[: n ** 3].reshape(n, n, n).transpose(2, 1, 0)      # [j, i, k]
    # d1 is (n^3 x n), row m n^2 + i n + j: vec(d1) index = k n^3 + m n^2 + i n + j
    s1 = sup[n ** 3:].reshape(n, n, n, n).transpose(3, 2, 1, 0)  # [j, i, m, k]
    mask = 1.0 - np.eye(n)                                       # k != i
    a = np.sqrt(np.einsum("jik,ik->ji", s0 ** 2, mask))
    b = np.sqrt(np.einsum("jimk,ik->jim", s1 ** 2, mask))
    return a, b, _frobenius_bound(robot, hm_fun, points, refine)


@lru_cache(maxsize=32)
def _ii_speed_design_cached(robot, samples, seed, refine):
    from .symbolic import ldl_solve
    n = robot.n
    stats = ConfigurationStats(robot, samples, seed)
    k_m = -stats.maximise(lambda lmin, lmax, c0: -lmin)[0]
    k_M = stats.maximise(lambda lmin, lmax, c0: lmax)[0]
    k_c = stats.maximise(lambda lmin, lmax, c0: c0)[0]

    def split(q):
        Mq = robot.mass_matrix(q)
        return (ldl_solve(Mq, ca.DM.eye(n)),
                [-ldl_solve(Mq, robot.coriolis(q, ca.DM(np.eye(n)[:, m]))) for m in range(n)])

    a, b, _ = _lemma2(robot, split, stats.points, refine)
    k_cF = _frobenius_bound(robot, _christoffel_slices(robot), stats.points, refine)
    return IISpeedDesign(robot=robot.name, k_m=float(k_m), k_M=float(k_M), k_c=float(k_c),
                         k_cF=float(k_cF), deltabar_x=float(max(k_c / k_m, k_cF / k_M)),
                         dy_k1=a, dy_sx=b, samples=samples, refined=bool(refine))


def _christoffel_slices(robot):
    """q -> [C(q, e_1) ... C(q, e_n)] (n x n^2)."""
    n = robot.n
    q = ca.SX.sym("q", n)
    return ca.Function("Cslices", [q], [ca.horzcat(*[robot.coriolis(q, ca.DM(np.eye(n)[:, m]))
                                                      for m in range(n)])])


def ii_speed_bounds(robot, samples=2000, seed=0, refine=True):
    """k_m, k_M, k_c and the Lemma-1/Lemma-2 bounds of the I&I speed observer [S003 (21), (27)].

    Sups over configurations: ``samples`` uniform samples of the joint ranges (plus the centre),
    then local refinement (Nelder-Mead for k_m, k_M, k_c, k_cF; a batch pattern search for the
    partial derivatives of H) unless ``refine`` is False. Returns an IISpeedDesign (cached)."""
    return _ii_speed_design_cached(robot, int(samples), int(seed), bool(refine))


# ============================================================================ seed 004 (elastic joints)
def companion_gains(poles):
    """[a_{r-1}, ..., a_0] of prod_k (s - p_k) = s^r + a_{r-1} s^{r-1} + ... + a_0: the gain K
    that gives the Brunovsky chain A - K e_1^T the eigenvalues ``poles``  [S004 §8.1; CODE-CP]."""
    c = np.real(np.poly(np.asarray(poles, dtype=float)))
    return c[1:].copy()


def ciccarella_germani_gains(variant, n, eigenvalues):
    """Per-channel gain vectors of the CG observer variants (SPEC §8.3, §8.4), flat.

    O1, O4: joint i gets eigenvalues[4i:4i+4] -> 4 companion coefficients.
    O2:     joint i: [-p_{4i}, companion(p_{4i+1}, p_{4i+2}, p_{4i+3})] (position error gain
            |p| on the first chain state, the 3-chain driven by the velocity error).
    O3:     output i (of [q2_1..q2_n, tau_1..tau_n]) gets eigenvalues[2i:2i+2] -> 2 coefficients.
    """
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
    """K1 solving A^T K1 + K1 A = Q (Thm 3.1 of seed 004, SPEC §7), by
    scipy.linalg.solve_continuous_lyapunov(A^T, Q) (which solves A^T X + X A = Q)."""
    from scipy.linalg import solve_continuous_lyapunov
    A, Qlyap = np.atleast_2d(A).astype(float), np.atleast_2d(Qlyap).astype(float)
    return solve_continuous_lyapunov(A.T, Qlyap)


def spong_fl_gains(n, poles):
    """K_c rows per joint acting on [e, e', e'', e''']: -[a0, a1, a2, a3] of prod (s - p),
    joint i gets poles[4i:4i+4]  [S004 (4.7); CODE-CP computegains.m], flat (4n,)."""
    p = np.asarray(poles, dtype=float).reshape(-1)
    if p.size != 4 * n:
        raise ValueError(f"need {4 * n} poles, got {p.size}")
    return np.concatenate([-companion_gains(p[4 * i:4 * i + 4])[::-1] for i in range(n)])


def spong_fast_gains(n, poles, stiffness):
    """Per joint [k_eta, k_etad] of zeta_i = k_eta eta_i + k_etad eta_i' so that
    eta'' = K zeta has the eigenvalues (p_a, p_b): k_eta = -p_a p_b / K_i,
    k_etad = (p_a + p_b) / K_i  [S004 (4.23), SPEC §10.4 DERIVED]; the poles are cycled
    over the joints two by two (2n needed)."""
    p = np.asarray(poles, dtype=float).reshape(-1)
    Kd = np.broadcast_to(np.asarray(stiffness, dtype=float), (n,))
    if p.size < 2 * n:
        raise ValueError(f"need {2 * n} fast poles, got {p.size}")
    return np.concatenate([[-p[2 * i] * p[2 * i + 1] / Kd[i], (p[2 * i] + p[2 * i + 1]) / Kd[i]]
                           for i in range(n)])


# ============================================================================= AOV observer (seed 003 comparison)
@dataclass
class IIAovDesign:
    """Bounds of the reconstructed Astolfi-Ortega-Venkatraman observer (SPEC §5) [DERIVED]:
    Hbar(q, p) = k1 T^{-1} + sum_m p_m Cbar(q, e_m) T^{-1}."""
    robot: str
    deltabar_p: float          # max_q max_{|a|=1} ||Cbar(q, a) T^{-1}||_F
    dq_k1: np.ndarray          # (n, n) coefficient of k1 in Deltabar_q,ji
    dq_p: np.ndarray           # (n, n, n) coefficient of |phat_m|
    samples: int
    refined: bool

    def as_dict(self):
        d = dict(self.__dict__)
        d["dq_k1"], d["dq_p"] = self.dq_k1.tolist(), self.dq_p.tolist()
        return d


@lru_cache(maxsize=32)
def _ii_aov_design_cached(robot, samples, seed, refine):
    from .observers.ii_aov import cholesky_velocity, skew_S   # symbolic T and S (SPEC §5)
    n = robot.n
    points = np.vstack([0.5 * (robot.q_lower + robot.q_upper), robot.sample_configurations(samples, seed)])

    def split(q):
        _, T, Tinv = cholesky_velocity(robot, q)
        S = [skew_S(robot, q, ca.DM(np.eye(n)[:, k])) for k in range(n)]
        # Cbar(q, e_m) column k = S(q, e_k) e_m
        Cbar = [ca.horzcat(*[S[k][:, m] for k in range(n)]) for m in range(n)]
        return Tinv, [ca.mtimes(Cbar[m], Tinv) for m in range(n)]

    a, b, dbar_p = _lemma2(robot, split, points, refine)
    return IIAovDesign(robot=robot.name, deltabar_p=float(dbar_p), dq_k1=a, dq_p=b,
                       samples=samples, refined=bool(refine))


def ii_aov_bounds(robot, samples=2000, seed=0, refine=True):
    """Deltabar_p and the Lemma-2 coefficients of Deltabar_q for the AOV observer (SPEC §5)."""
    return _ii_aov_design_cached(robot, int(samples), int(seed), bool(refine))
