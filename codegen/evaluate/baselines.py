"""What a user would write instead of an observer: velocity from sampled positions (numpy).

Same shape as an observer (``codegen.pipeline.load.CompiledObserver``): ``reset(y0)``,
``step(y, u) -> qd_hat``, ``estimate(y, u)``, ``run(Y, U) -> QD_HAT``, ``state``, and the sizes
``ny = nu = nest = n``. The torque u is accepted and ignored: none of these uses a model.

A real log's stamps jitter and drop samples: ``run(Y, U, t=t)`` takes the sample times and uses
each sample's own step h_k = t_k - t_k-1 where a user would (the differences divide by h_k, the
Kalman filter and Levant's differentiator advance by h_k); the Butterworth filter stays designed
at the nominal ``dt`` (the median step: what a user designs it at). Stamps uniform at ``dt`` to
1e-9 take the constant-step path, bit for bit what ``run(Y)`` gives.

| name           | what                                                                 | tuned over |
|----------------|----------------------------------------------------------------------|------------|
| ``backward``   | backward difference (y_k - y_k-1) / dt                               | --         |
| ``butterworth``| backward difference, then a causal Butterworth low-pass              | cutoff     |
| ``kalman``     | constant-acceleration Kalman filter per joint                        | q          |
| ``levant``     | Levant's robust exact differentiator, homogeneous discretisation     | L          |

``GRIDS`` holds the parameter grid each one is tuned over by ``codegen.evaluate.compare``.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.arrays import as_matrix, as_vector, positive


class Baseline:
    """Common shape of the baselines: a flat state ``_x`` and a per-sample update ``_step``.

    Parameters
    ----------
    n : int
        Number of joints (channels), >= 1.
    dt : float
        Sample time (s), > 0.
    """

    name = "baseline"
    tuned = None          # the parameter codegen.evaluate.compare tunes over GRIDS[name]

    def __init__(self, n, dt):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"n must be a positive integer (joints), got {n!r}")
        self.n = self.ny = self.nu = self.nest = int(n)
        self.dt = positive("dt", dt)
        self._x = np.zeros(self.nx)
        self.reset(np.zeros(self.n))

    @property
    def nx(self):
        return self.n

    @property
    def params(self):
        """The options this baseline was built with, name -> value."""
        return {}

    def reset(self, y0, est0=None):
        """Start from the first measurement y0 (rad) and an initial velocity est0 (default 0)."""
        y0 = as_vector("y0", y0, self.n)
        est0 = np.zeros(self.n) if est0 is None else as_vector("est0", est0, self.n)
        self._t_last = None                 # the last stamp seen by run(..., t=...)
        self._reset(y0, est0)

    def step(self, y, u=None):
        """Velocity estimate (rad/s) at this sample from the position y (rad); u is ignored."""
        return self._step(as_vector("y", y, self.n)).copy()

    def estimate(self, y, u=None):
        """What ``step(y, u)`` would return, without advancing the state."""
        saved = self._x.copy()
        est = self.step(y, u)
        self._x[:] = saved
        return est

    def run(self, Y, U=None, t=None):
        """Many samples (rows of Y, (N, n)); U is ignored. Returns QD_HAT (N, n).

        ``t`` (N,), optional: the samples' time stamps (s), strictly increasing; each sample then
        advances by its own step h_k = t_k - t_k-1 (the first by t_0 minus the last stamp of a
        previous ``run`` with stamps since ``reset``, else by ``dt``). None: every step is ``dt``.
        """
        Y = as_matrix("Y", Y, self.n)
        H = self._steps(t, len(Y))
        if H is None:
            return self._run(Y)
        out = self._run_steps(Y, H)
        self._t_last = float(t[-1])
        return out

    def _steps(self, t, N):
        """The steps h_k (N,) of the stamps ``t``, or None for no stamps or stamps uniform at dt."""
        if t is None:
            self._t_last = None
            return None
        t = as_vector("t", t, N)
        H = np.diff(t, prepend=t[0] - self.dt if self._t_last is None else self._t_last)
        if np.any(H <= 0):
            k = int(np.argmax(H <= 0))
            prev = f"t[{k - 1}] = {t[k - 1]:.9g}" if k else f"the previous run's last stamp {self._t_last:.9g}"
            raise ValueError(f"t: time stamps must increase; t[{k}] = {t[k]:.9g} <= {prev}")
        if np.all(np.abs(H - self.dt) <= 1e-9 * self.dt):
            self._t_last = float(t[-1])
            return None
        return H

    def _run(self, Y):
        out = np.empty_like(Y)
        for k in range(len(Y)):
            out[k] = self._step(Y[k])
        return out

    def _run_steps(self, Y, H):
        """As _run with the step H[k] (s) before sample k."""
        out = np.empty_like(Y)
        for k in range(len(Y)):
            out[k] = self._step(Y[k], H[k])
        return out

    @property
    def state(self):
        """A copy of the state (nx,)."""
        return self._x.copy()

    @state.setter
    def state(self, x):
        """Set the state to ``x`` (nx,) (ValueError on a wrong size or a non-finite entry)."""
        self._x[:] = as_vector("x", x, self.nx)

    def __repr__(self):
        opts = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        return f"<{type(self).__name__} n={self.n} dt={self.dt:g}{', ' + opts if opts else ''}>"


class BackwardDifference(Baseline):
    """qd_hat_k = (y_k - y_k-1) / h_k, h_k = dt or t_k - t_k-1 (stamped ``run``): the velocity
    at t_k - h_k/2 (a lag of half a sample).

    State: the previous sample y_k-1."""

    name = "backward"

    def _reset(self, y0, est0):
        self._x[:] = y0

    def _step(self, y, h=None):
        est = (y - self._x) / (self.dt if h is None else h)
        self._x[:] = y
        return est

    def _run(self, Y):
        return self._run_steps(Y, self.dt)

    def _run_steps(self, Y, H):
        """(y_k - y_k-1) / h_k for all rows at once; H: (N,) steps or the scalar dt."""
        H = np.asarray(H, dtype=float)
        H = H[:, None] if H.ndim else H
        out = np.empty_like(Y)
        out[0] = (Y[0] - self._x) / (H[0] if H.ndim else H)
        out[1:] = np.diff(Y, axis=0) / (H[1:] if H.ndim else H)
        self._x[:] = Y[-1]
        return out


class Butterworth(Baseline):
    """Backward difference filtered by a causal Butterworth low-pass, per joint.

    The difference divides by each sample's own step (stamped ``run``); the filter is designed
    at the nominal rate, ``scipy.signal.butter(order, cutoff, fs=1/dt, output="sos")``, run as
    second-order sections (direct form II transposed, ``scipy.signal.sosfilt``) whose state
    is kept across steps. Its group delay at low frequency is about sqrt(2)/(2 pi cutoff) s
    for order 2 (4.5 ms at 50 Hz), plus the half sample of the difference.

    Parameters
    ----------
    n, dt
        See :class:`Baseline`.
    cutoff : float
        -3 dB frequency (Hz), below the Nyquist frequency 1/(2 dt).
    order : int
        Filter order (>= 1).
    """

    name = "butterworth"
    tuned = "cutoff"

    def __init__(self, n, dt, cutoff=50.0, order=2):
        from scipy import signal
        dt = positive("dt", dt)
        self.cutoff = positive("cutoff", cutoff)
        if self.cutoff >= 0.5 / dt:
            raise ValueError(f"cutoff must be below the Nyquist frequency {0.5 / dt:g} Hz "
                             f"(dt = {dt:g} s), got {cutoff!r}")
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
            raise ValueError(f"order must be a positive integer, got {order!r}")
        self.order = int(order)
        self._sos = signal.butter(self.order, self.cutoff, fs=1.0 / dt, output="sos")
        self._zi1 = signal.sosfilt_zi(self._sos)               # steady state for a unit input
        super().__init__(n, dt)

    @property
    def nx(self):
        return self.n * (1 + 2 * len(self._sos))             # previous y, then the filter state

    @property
    def params(self):
        return {"cutoff": self.cutoff, "order": self.order}

    def _split(self):
        return self._x[: self.n], self._x[self.n:].reshape(len(self._sos), 2, self.n)

    def _reset(self, y0, est0):
        prev, zi = self._split()
        prev[:] = y0
        zi[:] = self._zi1[:, :, None] * est0                  # settled at the initial velocity

    def _run(self, Y):
        return self._run_steps(Y, self.dt)

    def _run_steps(self, Y, H):
        """Differences (y_k - y_k-1) / h_k (H: (N,) steps or the scalar dt), then the filter."""
        from scipy import signal
        prev, zi = self._split()
        H = np.asarray(H, dtype=float)
        H = H[:, None] if H.ndim else H
        D = np.empty_like(Y)
        D[0] = (Y[0] - prev) / (H[0] if H.ndim else H)
        D[1:] = np.diff(Y, axis=0) / (H[1:] if H.ndim else H)
        out, zi[:] = signal.sosfilt(self._sos, D, axis=0, zi=zi)
        prev[:] = Y[-1]
        return out

    def _step(self, y, h=None):
        return self._run_steps(y[None, :], np.array([self.dt if h is None else h]))[0]


def white_jerk_covariance(dt, q):
    """Process noise of the constant-acceleration model driven by white jerk of spectral
    density q (rad^2/s^5) over one sample dt (Bar-Shalom, Li, Kirubarajan 2001, §6.2.3)."""
    return q * np.array([[dt ** 5 / 20, dt ** 4 / 8, dt ** 3 / 6],
                         [dt ** 4 / 8, dt ** 3 / 3, dt ** 2 / 2],
                         [dt ** 3 / 6, dt ** 2 / 2, dt]])


class Kalman(Baseline):
    """Constant-acceleration Kalman filter per joint: state (q, qd, qdd) per joint,

        x_k = A x_k-1 + w,  A = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]],  w ~ N(0, Q(q))
        y_k = q_k + v,      v ~ N(0, r)

    with Q the white-jerk covariance (``white_jerk_covariance``). Every joint has the same
    model, so they share one covariance P; the estimate is the filtered qd after y_k. A stamped
    ``run`` uses A(h_k) and Q(h_k) with each sample's own step h_k = t_k - t_k-1.

    Parameters
    ----------
    n, dt
        See :class:`Baseline`.
    q : float
        Spectral density of the jerk (rad^2/s^5): larger follows faster, filters less.
    r : float
        Variance of the measurement noise (rad^2); about sigma^2 + Delta^2/12 for Gaussian
        noise sigma and quantisation step Delta.
    v0, a0 : float
        Standard deviations of the initial velocity (rad/s) and acceleration (rad/s^2).
    """

    name = "kalman"
    tuned = "q"

    def __init__(self, n, dt, q=1e3, r=1e-8, v0=10.0, a0=100.0):
        self.q, self.r = positive("q", q), positive("r", r)
        self.v0, self.a0 = positive("v0", v0), positive("a0", a0)
        dt = positive("dt", dt)
        self._A = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        self._Q = white_jerk_covariance(dt, self.q)
        super().__init__(n, dt)

    @property
    def nx(self):
        return 3 * self.n + 9                                 # (q, qd, qdd) per joint, then P

    @property
    def params(self):
        return {"q": self.q, "r": self.r}

    def _split(self):
        return self._x[: 3 * self.n].reshape(3, self.n), self._x[3 * self.n:].reshape(3, 3)

    def _reset(self, y0, est0):
        X, P = self._split()
        X[0], X[1], X[2] = y0, est0, 0.0
        P[:] = np.diag([self.r, self.v0 ** 2, self.a0 ** 2])

    def _gain(self):
        """Advance the shared covariance P over one sample; returns the Kalman gain K (3,)."""
        _, P = self._split()
        A = self._A
        P[:] = A @ P @ A.T + self._Q                          # predict
        K = P[:, 0] / (P[0, 0] + self.r)                      # update with H = [1, 0, 0]
        P[:] = P - np.outer(K, P[0])
        return K

    def _step(self, y, K=None):
        X, _ = self._split()
        K = self._gain() if K is None else K
        X[:] = self._A @ X
        X += np.outer(K, y - X[0])
        return X[1]

    def _run_steps(self, Y, H):
        """The filter with the transition A(h_k) and the process noise Q(h_k) of each step:
        P (symmetric, 6 entries) in scalars, the state (3, n) vectorised over the joints."""
        X, P = self._split()
        q, r = self.q, self.r
        p00, p01, p02, p11, p12, p22 = P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]
        x0, x1, x2 = X[0].copy(), X[1].copy(), X[2].copy()
        out = np.empty_like(Y)
        for k in range(len(Y)):
            h = float(H[k])
            h2 = h * h
            # predict: P <- A P A' + Q(h), A = [[1, h, h^2/2], [0, 1, h], [0, 0, 1]]
            a01, a02, a12 = h, 0.5 * h2, h
            m00 = p00 + a01 * p01 + a02 * p02
            m01 = p01 + a01 * p11 + a02 * p12
            m02 = p02 + a01 * p12 + a02 * p22
            m11 = p11 + a12 * p12
            m12 = p12 + a12 * p22
            n00 = m00 + m01 * a01 + m02 * a02
            n01 = m01 + m02 * a12
            n02 = m02
            n11 = m11 + m12 * a12
            n12 = m12
            n22 = p22
            n00 += q * h2 * h2 * h / 20
            n01 += q * h2 * h2 / 8
            n02 += q * h2 * h / 6
            n11 += q * h2 * h / 3
            n12 += q * h2 / 2
            n22 += q * h
            # update with H = [1, 0, 0]
            s = n00 + r
            k0, k1, k2 = n00 / s, n01 / s, n02 / s
            p00, p01, p02 = n00 - k0 * n00, n01 - k0 * n01, n02 - k0 * n02
            p11, p12, p22 = n11 - k1 * n01, n12 - k1 * n02, n22 - k2 * n02
            # the state, every joint at once
            x0 = x0 + h * x1 + 0.5 * h2 * x2
            x1 = x1 + h * x2
            e = Y[k] - x0
            x0, x1, x2 = x0 + k0 * e, x1 + k1 * e, x2 + k2 * e
            out[k] = x1
        X[0], X[1], X[2] = x0, x1, x2
        P[:] = [[p00, p01, p02], [p01, p11, p12], [p02, p12, p22]]
        return out

    def _run(self, Y):
        """As _step per row; once the gain has settled (P does not depend on the data) it is
        reused instead of advancing P."""
        out = np.empty_like(Y)
        K_prev, settled = None, False
        for k in range(len(Y)):
            if not settled:
                K = self._gain()
                settled = K_prev is not None and np.allclose(K, K_prev, rtol=1e-15, atol=0.0)
                K_prev = K
            out[k] = self._step(Y[k], K)
        return out


# Levant's non-recursive coefficients lambda_0 .. lambda_n for n = 1, 2, 3 [Levant 2003, §6]
LEVANT_LAMBDAS = {1: (1.1, 1.5), 2: (1.1, 2.12, 2.0), 3: (1.1, 3.06, 4.16, 3.0)}


class Levant(Baseline):
    """Levant's robust exact differentiator of order m (default 2) in the homogeneous
    discrete form of Livne & Levant (2014), per joint. With e = z_0 - y_k:

        z_i <- z_i + dt (-lambda_{m-i} L^{(i+1)/(m+1)} |e|^{(m-i)/(m+1)} sign e)
                   + sum_{j=i+1..m} dt^{j-i}/(j-i)! z_j          i = 0 .. m

    (A. Levant, "Higher-order sliding modes, differentiation and output-feedback control",
    Int. J. Control 76, 2003, non-recursive form; M. Livne, A. Levant, "Proper discretization
    of homogeneous differentiators", Automatica 50, 2014: the Taylor terms keep the accuracy
    of the continuous differentiator, |z_1 - qd| = O(L dt^m) without noise). The estimate at
    t_k is z_1 before the update with y_k, so it uses samples up to y_k-1. A stamped ``run``
    advances each update by the sample's own step h_k = t_k+1 - t_k in place of dt (the next
    stamp, the last update by the previous step).

    Parameters
    ----------
    n, dt
        See :class:`Baseline`.
    L : float
        Bound on |d^(m+1) q / dt^(m+1)| (rad/s^(m+1)): larger converges faster, filters less.
    order : {1, 2, 3}
        Differentiator order m (1 is the super-twisting differentiator).
    """

    name = "levant"
    tuned = "L"

    def __init__(self, n, dt, L=100.0, order=2):
        self.L = positive("L", L)
        if order not in LEVANT_LAMBDAS:
            raise ValueError(f"order must be one of {sorted(LEVANT_LAMBDAS)}, got {order!r}")
        self.order = int(order)
        m = self.order
        lam = LEVANT_LAMBDAS[m]
        self._gain = np.array([lam[m - i] * self.L ** ((i + 1) / (m + 1)) for i in range(m + 1)])
        self._power = np.array([(m - i) / (m + 1) for i in range(m + 1)])
        dt = positive("dt", dt)
        # Taylor matrix T[i, j] = dt^(j-i) / (j-i)! for j >= i (the uniform path; _taylor: stamps)
        self._T = np.array([[dt ** (j - i) / math.factorial(j - i) if j >= i else 0.0
                             for j in range(m + 1)] for i in range(m + 1)])
        D = np.subtract.outer(np.arange(m + 1), np.arange(m + 1)).T                  # j - i
        self._upper, self._powers = D >= 0, np.maximum(D, 0)
        self._factorials = np.vectorize(math.factorial)(self._powers).astype(float)
        super().__init__(n, dt)

    def _taylor(self, h):
        """Taylor matrix T[i, j] = h^(j-i) / (j-i)! for j >= i, else 0 (h in s)."""
        return np.where(self._upper, h ** self._powers / self._factorials, 0.0)

    @property
    def nx(self):
        return (self.order + 1) * self.n

    @property
    def params(self):
        return {"L": self.L, "order": self.order}

    def _reset(self, y0, est0):
        Z = self._x.reshape(self.order + 1, self.n)
        Z[:] = 0.0
        Z[0], Z[1] = y0, est0

    def _step(self, y, h=None):
        Z = self._x.reshape(self.order + 1, self.n)
        est = Z[1].copy()
        e = Z[0] - y
        corr = -self._gain[:, None] * np.abs(e) ** self._power[:, None] * np.sign(e)
        T, h = (self._T, self.dt) if h is None else (self._taylor(h), h)
        Z[:] = T @ Z + h * corr
        return est

    def _run_steps(self, Y, H):
        """Each update advances to the next sample: by h_k+1 (the last one by h_N-1)."""
        ahead = np.append(H[1:], H[-1])
        return super()._run_steps(Y, ahead)


BASELINES = {cls.name: cls for cls in (BackwardDifference, Butterworth, Kalman, Levant)}

# the grids codegen.evaluate.compare tunes each baseline's own parameter over (log-spaced)
GRIDS = {
    "butterworth": [2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 50.0, 70.0, 100.0, 150.0, 200.0,
                    300.0, 400.0],
    "kalman": [float(v) for v in np.logspace(-3, 12, 31)],
    "levant": [float(v) for v in np.logspace(-1, 5, 19)],
}


def make(name, n, dt, **options):
    """A baseline by name (see ``BASELINES``) for n joints sampled every dt seconds.

    Parameters
    ----------
    name : str
        One of ``BASELINES``.
    n : int
        Joints.
    dt : float
        Sample time (s).
    **options
        The baseline's own options (cutoff, order, q, r, L, ...).

    Returns
    -------
    Baseline
    """
    if name not in BASELINES:
        raise KeyError(f"unknown baseline {name!r}; known: {', '.join(BASELINES)}")
    return BASELINES[name](n, dt, **options)
