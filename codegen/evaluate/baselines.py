"""What a user would write instead of an observer: velocity from sampled positions (numpy).

Same shape as an observer (``codegen.pipeline.load.CompiledObserver``): ``reset(y0)``,
``step(y, u) -> qd_hat``, ``estimate(y, u)``, ``run(Y, U) -> QD_HAT``, ``state``, and the sizes
``ny = nu = nest = n``. The torque u is accepted and ignored: none of these uses a model.

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

    def run(self, Y, U=None):
        """Many samples (rows of Y, (N, n)); U is ignored. Returns QD_HAT (N, n)."""
        Y = as_matrix("Y", Y, self.n)
        return self._run(Y)

    def _run(self, Y):
        out = np.empty_like(Y)
        for k in range(len(Y)):
            out[k] = self._step(Y[k])
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
    """qd_hat_k = (y_k - y_k-1) / dt: the velocity at t_k - dt/2 (a lag of half a sample).

    State: the previous sample y_k-1."""

    name = "backward"

    def _reset(self, y0, est0):
        self._x[:] = y0

    def _step(self, y):
        est = (y - self._x) / self.dt
        self._x[:] = y
        return est

    def _run(self, Y):
        out = np.empty_like(Y)
        out[0] = (Y[0] - self._x) / self.dt
        out[1:] = np.diff(Y, axis=0) / self.dt
        self._x[:] = Y[-1]
        return out


class Butterworth(Baseline):
    """Backward difference filtered by a causal Butterworth low-pass, per joint.

    The filter is ``scipy.signal.butter(order, cutoff, fs=1/dt, output="sos")`` run as
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
        from scipy import signal
        prev, zi = self._split()
        D = np.empty_like(Y)
        D[0] = (Y[0] - prev) / self.dt
        D[1:] = np.diff(Y, axis=0) / self.dt
        out, zi[:] = signal.sosfilt(self._sos, D, axis=0, zi=zi)
        prev[:] = Y[-1]
        return out

    def _step(self, y):
        return self._run(y[None, :])[0]


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
    model, so they share one covariance P; the estimate is the filtered qd after y_k.

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
    t_k is z_1 before the update with y_k, so it uses samples up to y_k-1.

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
        # Taylor matrix T[i, j] = dt^(j-i) / (j-i)! for j >= i
        self._T = np.array([[dt ** (j - i) / math.factorial(j - i) if j >= i else 0.0
                             for j in range(m + 1)] for i in range(m + 1)])
        super().__init__(n, dt)

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

    def _step(self, y):
        Z = self._x.reshape(self.order + 1, self.n)
        est = Z[1].copy()
        e = Z[0] - y
        corr = -self._gain[:, None] * np.abs(e) ** self._power[:, None] * np.sign(e)
        Z[:] = self._T @ Z + self.dt * corr
        return est


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
