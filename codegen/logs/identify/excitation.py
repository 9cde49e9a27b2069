"""The excitation trajectory to log for identification: a Fourier series per joint (Swevers et
al. 1997) within the position, velocity and acceleration limits, at rest at t = 0 and T, whose
coefficients minimise the condition number of the stacked base regressor (SLSQP, exact gradient)."""
from __future__ import annotations

import math

import numpy as np

from .fit import _progress
from .regressor import _Arm, _tri


class Excitation:
    """A periodic Fourier-series trajectory per joint (Swevers et al. 1997),

        q_j(t) = q0_j + sum_l a_jl/(w l) sin(w l t) - b_jl/(w l) cos(w l t),   w = 2 pi f0,
        qd_j   = sum_l a_jl cos(w l t) + b_jl sin(w l t),
        qdd_j  = sum_l w l (b_jl cos(w l t) - a_jl sin(w l t)),

    at rest at t = 0 (sum_l a_jl = 0, sum_l l b_jl = 0) and so at every whole period.

    Attributes
    ----------
    joint_names : list of str
    f0 : float
        Base frequency (Hz).
    a, b : (n, L) arrays
        Coefficients (rad/s).
    q0 : (n,) array
    T : float
        Duration (s), a whole number of periods 1/f0.
    condition : float
        Condition number of the stacked base regressor along it (as in the identification report).
    """

    def __init__(self, joint_names, f0, a, b, q0, T, condition=math.nan):
        self.joint_names, self.f0, self.T, self.condition = list(joint_names), float(f0), float(T), condition
        self.a, self.b, self.q0 = np.asarray(a, float), np.asarray(b, float), np.asarray(q0, float)

    def at(self, t):
        """(q, qd, qdd), each (N, n), at times ``t`` (N,) s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        w = 2 * math.pi * self.f0
        wl = w * np.arange(1, self.a.shape[1] + 1)
        S, C = np.sin(np.outer(t, wl)), np.cos(np.outer(t, wl))
        q = self.q0 + S @ (self.a / wl).T - C @ (self.b / wl).T
        qd = C @ self.a.T + S @ self.b.T
        qdd = C @ (self.b * wl).T - S @ (self.a * wl).T
        return q, qd, qdd

    def sample(self, dt=1e-3):
        """(t, q, qd, qdd) on [0, T] every ``dt`` s."""
        t = dt * np.arange(int(round(self.T / dt)) + 1)
        return (t, *self.at(t))

    def write_csv(self, path, dt=1e-3):
        """The CSV a user plays on the robot: t, q_<joint>..., qd_<joint>..., qdd_<joint>...
        every ``dt`` s (to ``path``, atomically). Returns the path."""
        from codegen.core.columns import write_columns
        t, q, qd, qdd = self.sample(dt)
        cols = {"t": t}
        for g, a in (("q", q), ("qd", qd), ("qdd", qdd)):
            cols.update({f"{g}_{j}": a[:, k] for k, j in enumerate(self.joint_names)})
        return write_columns(path, cols)


class _Design:
    """The excitation design problem in y = (a (n, L), b (n, L), q0 (n)): minimise
    f = log cond W = log sigma_1(W) - log sigma_r(W), W = diag(1/tau_s) Y(q, qd, qdd) S_b stacked
    over a period's ``points`` instants, subject to linear constraints on a fine grid of the period
    (position within [lower, upper], |qd| <= vmax, |qdd| <= amax) and at rest at t = 0
    (sum_l a_l = 0, sum_l l b_l = 0).

    Gradient: d sigma_i = u_i^T dW v_i = sum_k w_ik^T d tau_k(x_i) with w_ik = u_ik / tau_s and
    x_i = S_b v_i, whose derivatives in q, qd, qdd are pinocchio's RNEA derivatives on a model
    with the (linear) parameters x_i (shifted by a consistent x0 and subtracted again, so that no
    body's mass is near 0) plus the friction's; then back through the series (linear in y)."""

    def __init__(self, arm, f0, L, lower, upper, vmax, amax, points):
        self.arm, self.L, self.n = arm, L, arm.n
        self.lower, self.upper, self.vmax, self.amax = lower, upper, vmax, amax
        self.wl = 2 * math.pi * f0 * np.arange(1, L + 1)
        self.fine = self.grid(np.linspace(0.0, 1.0 / f0, 40 * L + 1)[:-1])
        self.coarse = self.grid(np.linspace(0.0, 1.0 / f0, points + 1)[:-1])
        self.models = [arm.model.copy() for _ in range(3)]
        self.datas = [m.createData() for m in self.models]

    def grid(self, t):
        """(sin, cos) of the harmonics at times ``t``."""
        return np.sin(np.outer(t, self.wl)), np.cos(np.outer(t, self.wl))

    def split(self, y):
        """(a, b, q0) of the variables y."""
        n, L = self.n, self.L
        return y[:n * L].reshape(n, L), y[n * L:2 * n * L].reshape(n, L), y[2 * n * L:]

    def states(self, y, grid=None):
        """(q, qd, qdd) of y on ``grid`` (default the coarse one)."""
        a, b, q0 = self.split(y)
        S, C = grid or self.coarse
        wl = self.wl
        return (q0 + S @ (a / wl).T - C @ (b / wl).T, C @ a.T + S @ b.T,
                C @ (b * wl).T - S @ (a * wl).T)

    def constraints(self):
        """scipy LinearConstraints: limits on the fine grid, at rest at t = 0."""
        from scipy.optimize import LinearConstraint
        from scipy.sparse import lil_matrix
        n, L, wl = self.n, self.L, self.wl
        S, C = self.fine
        F, nv = len(S), 2 * n * L + n
        out = []
        for ra, rb, rq, lo, hi in ((S / wl, -C / wl, 1.0, self.lower, self.upper),
                                   (C, S, 0.0, -self.vmax, self.vmax),
                                   (-S * wl, C * wl, 0.0, -self.amax, self.amax)):
            A = np.zeros((n * F, nv))
            for j in range(n):
                r = slice(j * F, (j + 1) * F)
                A[r, j * L:(j + 1) * L] = ra
                A[r, n * L + j * L:n * L + (j + 1) * L] = rb
                A[r, 2 * n * L + j] = rq
            out.append(LinearConstraint(A, np.repeat(lo, F), np.repeat(hi, F)))
        E = lil_matrix((2 * n, nv))
        for j in range(n):
            E[j, j * L:(j + 1) * L] = 1.0
            E[n + j, n * L + j * L:n * L + (j + 1) * L] = np.arange(1, L + 1)
        out.append(LinearConstraint(E.toarray(), 0.0, 0.0))
        return out

    def start(self, c):
        """A feasible y from raw coefficients ``c`` (n, 2L): projected to rest at t = 0, each
        joint scaled to the tightest of its limits (times 0.98) and centred in its range."""
        n, L = self.n, self.L
        ell = np.arange(1, L + 1)
        a = c[:, :L] - c[:, :L].mean(axis=1, keepdims=True)
        b = c[:, L:] - np.outer(c[:, L:] @ ell / (ell @ ell), ell)
        y = np.concatenate([a.ravel(), b.ravel(), np.zeros(n)])
        return self.fit(y, 0.98)

    def fit(self, y, factor=1.0):
        """y with each joint's series scaled so that its motion on a grid 10x finer than the
        constraints' stays within ``factor`` x its limits, centred in its range."""
        a, b, _ = self.split(y)
        dense = self.grid(np.linspace(0.0, 2 * math.pi / self.wl[0], 400 * self.L, endpoint=False))
        q, v, acc = self.states(np.concatenate([a.ravel(), b.ravel(), np.zeros(self.n)]), dense)
        k = factor * np.minimum.reduce([(self.upper - self.lower) / np.maximum(np.ptp(q, axis=0), 1e-12),
                                        self.vmax / np.maximum(np.abs(v).max(axis=0), 1e-12),
                                        self.amax / np.maximum(np.abs(acc).max(axis=0), 1e-12)])
        q0 = 0.5 * (self.lower + self.upper) - 0.5 * k * (q.max(axis=0) + q.min(axis=0))
        return np.concatenate([(a * k[:, None]).ravel(), (b * k[:, None]).ravel(), q0])

    def inside(self, y):
        """y with each joint that exceeds a limit on a grid 10x finer than the constraints' scaled
        down (about its mid-range) and shifted just enough to be within them; the others as
        they are."""
        a, b, q0 = (v.copy() for v in self.split(y))
        dense = self.grid(np.linspace(0.0, 2 * math.pi / self.wl[0], 400 * self.L, endpoint=False))
        q, v, acc = self.states(np.concatenate([a.ravel(), b.ravel(), np.zeros(self.n)]), dense)
        k = np.minimum.reduce([np.ones(self.n),
                               (self.upper - self.lower) / np.maximum(np.ptp(q, axis=0), 1e-12),
                               self.vmax / np.maximum(np.abs(v).max(axis=0), 1e-12),
                               self.amax / np.maximum(np.abs(acc).max(axis=0), 1e-12)])
        mid = 0.5 * (q.max(axis=0) + q.min(axis=0))
        q0 = q0 + (1 - k) * mid                              # the mid-range kept
        top, bottom = q0 + k * q.max(axis=0), q0 + k * q.min(axis=0)
        q0 = q0 - np.maximum(top - self.upper, 0.0) + np.maximum(self.lower - bottom, 0.0)
        return np.concatenate([(a * k[:, None]).ravel(), (b * k[:, None]).ravel(), q0])

    def matrix(self, q, v, acc):
        """The stacked, scaled base regressor W at those states."""
        arm = self.arm
        Y = arm.regressor(q, v, acc) / arm.torque_scale[None, :, None] * arm.scale
        return Y.reshape(-1, arm.p)[:, arm.indep]

    @staticmethod
    def _extremes(W):
        """(sigma_1, sigma_r, v_1, v_r) of W from the eigenvalues of W^T W (ascending)."""
        lam, V = np.linalg.eigh(W.T @ W)
        return math.sqrt(max(lam[-1], 0.0)), math.sqrt(max(lam[0], 0.0)), V[:, -1], V[:, 0]

    def value(self, y):
        """log cond W of the variables ``y``."""
        s1, sr, _, _ = self._extremes(self.matrix(*self.states(y)))
        return math.log(s1 / sr) if sr > 0 else 1e3

    def value_and_grad(self, y):
        """(log cond W, its gradient in ``y``)."""
        pin, arm, n, wl = self.arm.pin, self.arm, self.n, self.wl
        q, v, acc = self.states(y)
        W = self.matrix(q, v, acc)
        s1, sr, v1, vr = self._extremes(W)
        if not sr > 1e-12 * s1:
            return 1e3, np.zeros(len(y))
        K = len(q)
        gq, gv, ga = np.zeros((K, n)), np.zeros((K, n)), np.zeros((K, n))
        xs = []
        for vec, sig, sign in ((v1, s1, 1.0 / s1), (vr, sr, -1.0 / sr)):
            x = np.zeros(arm.p)
            x[arm.indep] = arm.scale[arm.indep] * vec
            xs.append((x, sign, (W @ vec / sig).reshape(K, n) / arm.torque_scale))   # u = W v / sigma
        # a consistent x0 that keeps every body's mass of x + x0 away from 0
        masses = arm.pi_urdf[0:10 * n:10]
        x0 = (2.0 + max(np.abs(x[0:10 * n:10]).max() for x, _, _ in xs) / masses.min()) * arm.pi_urdf
        for m, xi in zip(self.models, [x0] + [x0 + x[:10 * n] for x, _, _ in xs]):
            for i in range(1, n + 1):
                m.inertias[i] = pin.Inertia.FromDynamicParameters(xi[10 * (i - 1):10 * i])
        Q = arm.pin_configurations(q)
        for k in range(K):
            d0 = pin.computeRNEADerivatives(self.models[0], self.datas[0], Q[k], v[k], acc[k])
            for j, (_, sign, w) in enumerate(xs, start=1):
                d1 = pin.computeRNEADerivatives(self.models[j], self.datas[j], Q[k], v[k], acc[k])
                wk = sign * w[k]
                Ma = np.triu(d1[2] - d0[2])                # pinocchio fills M's upper triangle
                gq[k] += wk @ (d1[0] - d0[0])
                gv[k] += wk @ (d1[1] - d0[1])
                ga[k] += wk @ (Ma + np.triu(Ma, 1).T)
        th = np.tanh(v / arm.width)
        for x, sign, w in xs:                               # friction: d/dqd
            fv, fc = x[10 * n:11 * n], x[11 * n:12 * n]
            gv += sign * w * (fv + fc * (1 - th ** 2) / arm.width)
        S, C = self.coarse
        g_a = (S.T @ gq).T / wl + (C.T @ gv).T - (S.T @ ga).T * wl
        g_b = -(C.T @ gq).T / wl + (S.T @ gv).T + (C.T @ ga).T * wl
        return math.log(s1 / sr), np.concatenate([g_a.ravel(), g_b.ravel(), gq.sum(axis=0)])


def excitation(robot, T=10.0, *, base_frequency=None, harmonics=5, margin=0.05, speed=0.8,
               qdd_max=None, coulomb_width=None, points=None, starts=2, maxiter=30, seed=0,
               progress=False):
    """An excitation trajectory for :func:`identify`: a Fourier series per joint within the
    limits, its coefficients chosen for a low condition number of the stacked base regressor.

    From ``starts`` random coefficient sets, each joint scaled to its tightest limit and centred
    in its range (feasible), SLSQP minimises log cond W, W the stacked base regressor at
    ``points`` instants of a period (columns in parameter scales, rows in joint torque scales, as
    in the identification report), with its exact gradient (:class:`_Design`), subject to the
    limits at 40 L instants per period (linear in the coefficients) and rest at t = 0: positions
    within the range less ``margin`` at both ends, |qd| <= ``speed`` x the velocity limit,
    |qdd| <= ``qdd_max``. A final check on a 10x finer grid scales a joint back to its limits
    should it exceed one between the grid's instants.

    Parameters
    ----------
    robot : models.RobotModel
        A URDF robot (as for :func:`identify`).
    T : float
        Duration (s), a whole number of periods so the trajectory ends at rest.
    base_frequency : float, optional
        f0 (Hz); default the smallest f0 >= 0.1 Hz with T f0 whole.
    harmonics : int
        L >= 2, the number of harmonics (top frequency L f0).
    margin : float
        Fraction of each joint's range kept free at both ends.
    speed : float
        Fraction of each joint's velocity limit used (limit 1 rad/s where the URDF gives none).
    qdd_max : float or (n,) array, optional
        Acceleration limit (rad/s^2); default 2 (1/s) x the velocity used.
    coulomb_width : float, optional
        w of the Coulomb column (as in :func:`identify`).
    points : int, optional
        Instants per period in the objective (default max(60, 3 x base parameters / n)).
    starts : int
        Random starting coefficient sets.
    maxiter : int
        SLSQP iterations per start (0: the scaled random start itself).
    seed : int
        Seeds the starting coefficients.
    progress : bool
        A tqdm bar on stderr over the optimiser's iterations.

    Returns
    -------
    Excitation
    """
    from scipy.optimize import minimize
    arm = _Arm(robot, coulomb_width)
    n = arm.n
    T = float(T)
    if not (math.isfinite(T) and T > 0):
        raise ValueError(f"T: expected a positive duration (s), got {T!r}")
    if base_frequency is None:
        f0 = math.ceil(0.1 * T - 1e-9) / T
    else:
        f0 = float(base_frequency)
        if not (f0 > 0 and abs(T * f0 - round(T * f0)) < 1e-9 and round(T * f0) >= 1):
            raise ValueError(f"T: {T:g} s is not a whole number of periods of base_frequency {f0:g} Hz "
                             "(the trajectory would not end at rest)")
    L = int(harmonics)
    if L < 2:
        raise ValueError(f"harmonics: expected an integer >= 2 (one harmonic cannot start and end at "
                         f"rest), got {harmonics!r}")
    if not 0 <= margin < 0.5:
        raise ValueError(f"margin: expected a fraction in [0, 0.5), got {margin!r}")
    if not 0 < speed <= 1:
        raise ValueError(f"speed: expected a fraction in (0, 1], got {speed!r}")
    vmax = speed * arm.v_limit
    amax = np.broadcast_to(np.asarray(qdd_max, float), (n,)) if qdd_max is not None else 2.0 * vmax
    if not np.all(np.isfinite(amax) & (amax > 0)):
        raise ValueError(f"qdd_max: expected positive accelerations (rad/s^2), got {qdd_max!r}")
    lo, hi = arm.q_lower, arm.q_upper
    points = int(points or max(60, math.ceil(3 * len(arm.indep) / n)))
    design = _Design(arm, f0, L, lo + margin * (hi - lo), hi - margin * (hi - lo), vmax, amax, points)
    constraints = design.constraints()
    rng = np.random.default_rng(seed)
    bar = _progress(progress, f"excitation {arm.name}", total=int(starts) * int(maxiter))
    best = None
    ell = np.arange(1, L + 1)
    for _ in range(int(starts)):
        y0 = design.start(rng.normal(size=(n, 2 * L)) / np.r_[ell, ell])
        res = minimize(design.value_and_grad, y0, jac=True, method="SLSQP", constraints=constraints,
                       options={"maxiter": int(maxiter)}, callback=lambda *_: bar.update(1)) \
            if maxiter > 0 else None
        y, f = (res.x, res.fun) if res is not None and np.all(np.isfinite(res.x)) else (y0, design.value(y0))
        if best is None or f < best[1]:
            best = (y, f)
        bar.set_postfix_str(f"cond {math.exp(best[1]):.4g}")
    bar.close()
    y = best[0]
    # the constraints hold on the fine grid; between its points the motion may exceed them by
    # round-off or a sliver: scaled back within them on a grid 10x finer
    y = design.inside(y)
    a, b, q0 = design.split(y)
    dense = design.grid(np.linspace(0.0, 1.0 / f0, 400, endpoint=False))
    cond = float(np.linalg.cond(_tri(design.matrix(*design.states(y, dense)))))
    return Excitation(arm.joint_names, f0, a, b, q0, T, condition=float(cond))
