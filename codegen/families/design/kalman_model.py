"""Gains of the kalman_model observer: a steady-state Kalman-Bucy filter per joint on a
constant-jerk (white-snap) motion model, with the model's acceleration as a second measurement
(numbers only; the observer is codegen.families.observers.kalman_model).

Per joint, x = [q, v, a, j] with q'''' white (PSD q_s), the encoder y = q + white noise (per
sample std sigma_q, PSD sigma_q^2 dt) and, optionally, the model's acceleration
a_m = M^-1 (tau_m - h) = a + M^-1 eps (eps the torque sensor's noise, diag Sigma, per sample).
Time in units of 1/omega, omega^8 = q_s / (sigma_q^2 dt), makes the problem universal [DERIVED]:

    normalised chain:  q-measurement PSD 1, snap PSD 1, a-measurement PSD lam_hat
    lam_hat = lam / (sigma_q^2 omega^4),  lam the per-sample variance of a_m  (rad^2/s^4)
    gains:  K_q,b = omega^b g_q,b(lam_hat),   K_a,b = omega^(b-2) g_a,b(lam_hat),   b = 1..4

g the normalised Kalman-Bucy gains (continuous algebraic Riccati equation). Without the
a-measurement (lam_hat -> inf) g_q = (2.6131, 3.4142, 2.6131, 1), the Butterworth polynomial
s^4 + 2.6131 s^3 + 3.4142 s^2 + 2.6131 s + 1: the error poles are omega e^(i pi (2k + 5)/8).

The joints' a-measurements are correlated (C = M^-1 Sigma M^-1). With the same omega and sigma_q
on every joint, the stacked filter decouples exactly in the eigenvectors of C (orthogonal: the
encoder noise and the motion model stay isotropic), one chain per eigenvalue lam_i [DERIVED]; the
gain matrices are therefore the matrix functions g(C_hat), C_hat = C / (sigma_q^2 omega^4). The
observer evaluates them without an eigendecomposition from the partial fractions fitted here,

    g(lam_hat) ~ g(inf) + sum_k c_k p_k / (lam_hat + p_k)   ->   g(inf) I + sum_k c_k p_k (C_hat + p_k I)^-1

fitted to g(lam_hat + lam_floor) (relative error reported): below lam_floor the model's
acceleration is trusted no further, because a very precise acceleration makes the velocity error
forget its initial value slowly (the error's slowest pole tends to 0 with lam_hat); lam_floor is
the smallest lam_hat at which an initial velocity error still decays as fast as without the model.

The bandwidths (``design_kalman_model``), each the smallest omega at which an initial velocity
error v_max falls below 1e-2 rad/s within a time (``omega_floor``: the least noise that still
converges in that time):

    omega0 = omega_floor(v_max, t_conv)     start-up (the estimate starts at 0 while the arm may
                                             move at up to v_max): t_conv = 0.2 s gives 81 rad/s
    omega  = omega_floor(v_max, t_settle)   from t_switch = 1.5 t_conv on: t_settle = 0.5 s gives
                                             32 rad/s

t_conv and t_settle are requirements (how fast an error must go), the default when no log is
given; the best steady omega depends on the log's noise and motion (tuned on the log's own
samples, without truth, by ``codegen.logs.tune``: 66-224 rad/s on the log-grid's cells, docs/guide/
reading-a-log.md), so no measured optimum is built in. The switch waits 1.5 t_conv [ASSUMPTION, measured]: at
t_conv the start-up filter's estimates of a and j still carry its larger noise, and switching
then put the ur5's error back above 1e-2 until 0.27 s; at 1.5 t_conv it stays below 7e-3.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import solve_continuous_are, solve_continuous_lyapunov
from scipy.optimize import least_squares

from .noise import TOL, sensor_sigma

ORDER = 4                      # states per joint: q, v, a, j
# partial fractions of the gain functions and the largest starting pole (lam_hat; above it the gains
# are the kinematic ones + O(1/lam_hat)): four poles moved to fit give a relative error of 3.8e-4
# over lam_hat in {0} U [floor/1000, 1e4] (ten log-spaced ones up to 1e2 gave 3.7e-4, six up to 10 7.4e-3;
# the step's cost is mostly per pole)
POLES = 4
FIT_HIGH = 10.0
_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
_A = np.diag(np.ones(ORDER - 1), 1)


def normalised_gains(lam_hat=None):
    """The normalised Kalman-Bucy gains (module docstring): (4,) q-gains without the
    a-measurement (``lam_hat`` None or inf), else (4, 2) [q-gains, a-gains] with the
    a-measurement of normalised PSD ``lam_hat`` > 0; the stabilising solution P of
    A P + P A^T + e4 e4^T - P H^T R^-1 H P = 0, gains P H^T R^-1 (``riccati_gains``)."""
    if lam_hat is None or math.isinf(lam_hat):
        return _kinematic_gains().copy()
    if not lam_hat > 0:
        raise ValueError(f"lam_hat must be > 0, got {lam_hat!r}")
    return riccati_gains(np.array([float(lam_hat)]))[0]


@lru_cache(maxsize=1)
def _kinematic_gains():
    Q = np.zeros((ORDER, ORDER))
    Q[-1, -1] = 1.0
    H, R = _H[:1], np.eye(1)
    P = solve_continuous_are(_A.T, H.T, Q, R)
    return (P @ H.T)[:, 0]


def riccati_gains(lam_hats):
    """(L, 4, 2) normalised gains [q-gains, a-gains] (``normalised_gains``) at each of the
    ``lam_hats`` (L,) > 0 at once: P from the stable invariant subspace [U1; U2] of the
    Hamiltonian [[A^T, -H^T R^-1 H], [-e4 e4^T, -A]] (P = U2 U1^-1, one batched eigendecomposition
    of 8 x 8 matrices), then one Newton (Kleinman) step, the Lyapunov equation
    A_c P + P A_c^T + e4 e4^T + P0 S P0 = 0 (A_c = A - P0 S, S = H^T R^-1 H) solved as a 16 x 16
    system. Equal to scipy's solve_continuous_are to its own accuracy (1e-10 relative on the
    fit's range, where both leave residuals of 1e-12 relative), 30x quicker for the fit's 501."""
    lam = np.asarray(lam_hats, dtype=float).reshape(-1)
    L, I = len(lam), np.eye(ORDER)
    Rinv = np.stack([np.ones(L), 1.0 / lam], axis=1)                      # (L, 2)
    S = np.einsum("ki,lk,kj->lij", _H, Rinv, _H)                           # H^T R^-1 H
    Q = np.zeros((ORDER, ORDER))
    Q[-1, -1] = 1.0
    Z = np.zeros((L, 2 * ORDER, 2 * ORDER))
    Z[:, :ORDER, :ORDER] = _A.T
    Z[:, :ORDER, ORDER:] = -S
    Z[:, ORDER:, :ORDER] = -Q
    Z[:, ORDER:, ORDER:] = -_A
    w, V = np.linalg.eig(Z)
    U = np.take_along_axis(V, np.argsort(w.real, axis=1)[:, None, :ORDER], axis=2)
    # P = U2 U1^-1, i.e. U1^T P^T = U2^T
    P = np.linalg.solve(U[:, :ORDER].transpose(0, 2, 1), U[:, ORDER:].transpose(0, 2, 1)).real
    P = 0.5 * (P + P.transpose(0, 2, 1))
    Ac = _A[None] - P @ S
    # row-major vec: vec(Ac X) = (Ac (x) I) vec X, vec(X Ac^T) = (I (x) Ac) vec X
    K = (np.einsum("lij,ab->liajb", Ac, I) + np.einsum("ij,lab->liajb", I, Ac)).reshape(L, ORDER ** 2, ORDER ** 2)
    P = np.linalg.solve(K, -(Q[None] + P @ S @ P).reshape(L, ORDER ** 2, 1)).reshape(L, ORDER, ORDER)
    P = 0.5 * (P + P.transpose(0, 2, 1))
    return (P @ _H.T) * Rinv[:, None, :]


def closed_loop(L):
    """A - L H of normalised gains L ((4,) q-gains or (4, 2))."""
    L = np.asarray(L, float).reshape(ORDER, -1)
    return _A - L @ _H[:L.shape[1]]


def velocity_variance(L, lam_hat=None):
    """Stationary variance of v of the normalised filter with gains ``L`` under unit q-noise
    and (with (4, 2) gains) a-noise of PSD ``lam_hat`` (it may differ from the design's):
    the v entry of P of A_cl P + P A_cl^T + L R L^T = 0."""
    L = np.asarray(L, float).reshape(ORDER, -1)
    R = np.eye(1) if L.shape[1] == 1 else np.diag([1.0, float(lam_hat)])
    P = solve_continuous_lyapunov(closed_loop(L), -L @ R @ L.T)
    return float(P[1, 1])


def convergence_time(L, v_max, tol=TOL):
    """Normalised time (units of 1/omega) after which the velocity error of the filter with
    gains ``L`` started from a velocity error v_max (rad/s) stays below tol (rad/s): the last
    time |v(t)| > tol / v_max on a grid of step 0.005 over [0, 400], v(t) = e2^T exp(A_cl t) e2
    by the eigendecomposition of A_cl (distinct eigenvalues: a stable Kalman-Bucy closed loop);
    the grid stops at twice the time after which the envelope sum_i |w_i| e^(max Re lam t) of
    v(t) = sum_i w_i e^(lam_i t) is below tol / v_max (nothing later can be above it)."""
    lam, V = np.linalg.eig(closed_loop(L))
    w = V[1, :] * np.linalg.solve(V, np.array([0.0, 1.0, 0.0, 0.0]))
    # |v(t)| <= sum |w_i| e^(max Re lam t): the grid need not go past where that is below tol / v_max
    # (twice as far, for rounding: the points left out are below it either way)
    horizon = 400.0
    if np.max(lam.real) < 0 and np.sum(np.abs(w)) * v_max > tol:
        horizon = min(horizon, 2.0 * math.log(np.sum(np.abs(w)) * v_max / tol) / -np.max(lam.real) + 1.0)
    t = np.arange(0.0, 400.0, 0.005)
    t = t[t <= horizon]
    v = np.abs((np.exp(np.outer(t, lam)) @ w).real)
    above = np.nonzero(v > tol / v_max)[0]
    return float(t[above[-1]]) if len(above) else 0.0


@lru_cache(maxsize=16)
def _lambda_floor(v_max):
    t_kin = convergence_time(normalised_gains(), v_max)
    lo, hi = math.log(1e-4), math.log(1.0)
    if convergence_time(normalised_gains(1.0), v_max) > t_kin:
        return 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if convergence_time(normalised_gains(math.exp(mid)), v_max) > t_kin else (lo, mid)
    return math.exp(hi)


def lambda_floor(v_max):
    """The smallest lam_hat (in [1e-4, 1]) whose filter brings an initial velocity error v_max
    (rad/s) below 1e-2 rad/s no later than the kinematic filter (bisection in log lam_hat: the
    convergence time falls as lam_hat grows on that interval)."""
    return _lambda_floor(float(v_max))


@lru_cache(maxsize=16)
def _fit(floor, poles, high):
    lam = np.concatenate([[0.0], np.logspace(math.log10(floor) - 3, math.log10(high) + 3, 500)])
    G = riccati_gains(lam + floor)                                      # (L, 4, 2)
    gk = normalised_gains()
    # the eight gain functions (q-gains less their kinematic limit, then a-gains) and their weights
    target = np.stack([G[:, b, j] - (gk[b] if j == 0 else 0.0) for j in range(2) for b in range(ORDER)])
    weight = np.stack([np.abs(G[:, b, j]) + 1e-3 * np.max(np.abs(G[:, b, j])) for j in range(2)
                       for b in range(ORDER)])

    def coefficients(p):
        B = p[None, :] / (lam[:, None] + p[None, :])
        c = np.stack([np.linalg.lstsq(B / w[:, None], t / w, rcond=None)[0] for t, w in zip(target, weight)])
        return c, ((c @ B.T - target) / weight).ravel()
    start = np.logspace(math.log10(floor), math.log10(high), poles)
    # variable projection: the poles (in log) by Gauss-Newton, the coefficients by least squares
    moved = np.sort(np.exp(least_squares(lambda x: coefficients(np.exp(x))[1], np.log(start)).x))
    # poles that merge (within 5 %) are ill-conditioned: then, or when it fits no better, the start
    fits = [(p, *coefficients(p)) for p in (start, moved) if p is start or np.min(p[1:] / p[:-1]) >= 1.05]
    best, c, r = min(fits, key=lambda f: np.max(np.abs(f[2])))
    return best, c.reshape(2, ORDER, poles), float(np.max(np.abs(r)))


def fitted_gains(lam_hat, fit):
    """The fitted normalised gains (4, 2) at ``lam_hat`` >= 0 from ``fit`` = (poles (K,),
    coefficients (2, 4, K), ...): q-gains g_q(inf) + sum_k c_qk p_k / (lam_hat + p_k),
    a-gains sum_k c_ak p_k / (lam_hat + p_k)."""
    p, c = fit[0], fit[1]
    B = p / (lam_hat + p)
    return np.stack([normalised_gains() + c[0] @ B, c[1] @ B], axis=1)


def fit_gains(floor, poles=POLES, high=FIT_HIGH):
    """Partial fractions of the gain functions (module docstring) fitted to g(lam_hat + floor)
    on lam_hat in {0} U [floor/1000, 1000 high] (500 log-spaced points, least squares in
    relative error): the poles from log-spaced on [floor, high], moved by Gauss-Newton on their
    logarithms with the coefficients solved at each (variable projection; kept log-spaced if
    that fits no better or two poles come within 5 %).

    Parameters
    ----------
    floor : float
        lam_floor (``lambda_floor``), > 0.
    poles : int
        Number of partial fractions K.
    high : float
        The largest starting pole.

    Returns
    -------
    (poles (K,), coefficients (2, 4, K): [q-gains, a-gains], max relative error of the fit)
    """
    if not (floor > 0 and high > floor):
        raise ValueError(f"floor must be in (0, high), got floor={floor!r}, high={high!r}")
    if not (isinstance(poles, int) and poles >= 2):
        raise ValueError(f"poles must be an integer >= 2, got {poles!r}")
    return _fit(float(floor), poles, float(high))


def omega_floor(v_max, t_conv):
    """The kinematic filter's smallest omega (1/s) bringing a velocity error v_max (rad/s)
    below 1e-2 rad/s within t_conv (s): the response scales with omega t, so omega =
    convergence_time(g(inf), v_max) / t_conv."""
    if not (t_conv > 0 and v_max > 0):
        raise ValueError(f"t_conv and v_max must be positive, got t_conv={t_conv!r}, v_max={v_max!r}")
    return convergence_time(normalised_gains(), v_max) / t_conv


def check_torque_uncertainty(torque_uncertainty, n):
    """``torque_uncertainty`` as an (n,) array of stds (N m, > 0; a scalar is used for every joint);
    ValueError naming it otherwise."""
    s = np.atleast_1d(np.asarray(torque_uncertainty, dtype=float)).reshape(-1)
    if s.size == 1:
        s = np.full(n, float(s[0]))
    if s.size != n or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ValueError(f"torque_uncertainty must be {n} finite stds > 0 (N m), one per joint, got {torque_uncertainty!r}")
    return s


def check_per_joint(name, value, n, positive=False):
    """``value`` (None: zeros) as an (n,) array of finite numbers (>= 0 when ``positive``);
    ValueError naming ``name`` otherwise."""
    v = np.zeros(n) if value is None else np.atleast_1d(np.asarray(value, dtype=float)).reshape(-1)
    if v.size == 1 and n > 1:
        v = np.full(n, float(v[0]))
    if v.size != n or not np.all(np.isfinite(v)) or (positive and np.any(v < 0)):
        raise ValueError(f"{name} must be {n} finite numbers{' >= 0' if positive else ''} (N m), "
                         f"one per joint, got {value!r}")
    return v


@dataclass
class KalmanModelDesign:
    """Why the kalman_model observer's gains are what they are (module docstring).

    Attributes: omega (1/s, the steady bandwidth), omega0 (1/s, the start-up one, until
    t_switch, s), omega_floor (the steady rule's), sigma
    (encoder std, rad), dt (design sample time, s), v_max, t_conv, t_settle, lam_floor, fit poles and
    coefficients and their relative error, width (the velocity std below which the Coulomb
    friction's sign is uncertain, rad/s), predicted RMS error norms (rad/s, noise only:
    kinematic, and with the model at sampled configurations when torque noise is stated) and
    the normalised convergence time.
    """
    robot: str
    omega: float
    omega0: float
    t_switch: float
    omega_floor: float
    choice: str
    sigma: float
    dt: float
    v_max: float
    t_conv: float
    t_settle: float
    lam_floor: float
    poles: list
    coefficients: list
    fit_error: float
    width: float
    predicted_error: dict
    predicted_joint_std: float
    torque_uncertainty: list | None

    def as_dict(self):
        """The fields as a JSON-ready dict."""
        return dict(self.__dict__)


def predicted_model_error(robot, omega, sigma, dt, torque_uncertainty, fit, samples=64, seed=0):
    """RMS over ``samples`` configurations of the predicted error norm (rad/s, noise only, every
    joint moving so no friction ambiguity) of the observer with the model: per eigenvalue lam_i
    of C = M^-1 diag(torque_uncertainty^2) M^-1, the stationary velocity variance of the chain with the
    fitted gains at lam_hat_i and a-noise lam_hat_i, summed (the eigenvectors are orthonormal)
    and scaled by sigma^2 dt omega^3.

    Parameters
    ----------
    robot : RobotModel
    omega, sigma, dt : float
        Bandwidth (1/s), encoder std (rad), sample time (s).
    torque_uncertainty : (n,) array
        Torque noise std per joint (N m).
    fit : tuple
        ``fit_gains``'s result.
    samples, seed : int
        Configurations drawn in the joint ranges.
    """
    scale = sigma ** 2 * omega ** 4
    total = []
    for q in robot.sample_configurations(samples, seed):
        M = np.asarray(robot.M(q), dtype=float)
        Mi = np.linalg.inv(M)
        lam = np.linalg.eigvalsh(Mi @ np.diag(np.asarray(torque_uncertainty) ** 2) @ Mi)
        total.append(sum(velocity_variance(fitted_gains(max(x, 0.0) / scale, fit), max(x, 0.0) / scale)
                         for x in lam))
    return math.sqrt(sigma ** 2 * dt * omega ** 3 * float(np.mean(total)))


def design_kalman_model(robot, dt, noise=None, quantization=None, torque_uncertainty=None, v_max=2.0,
                        t_conv=0.2, t_settle=0.5, omega=None, poles=POLES):
    """The default gains of the kalman_model observer (module docstring).

    Parameters
    ----------
    robot : RobotModel
    dt : float
        Sample time the noise predictions are made for (s); the gains do not depend on it.
    noise, quantization : float or None
        Encoder noise std and quantisation step (rad); both None: a 2^16 counts/rev encoder.
    torque_uncertainty : (n,) array or None
        Std of the torque sensor's noise per joint (N m), as an identification reports it (the
        residual std); None: the kinematic variant (no model).
    v_max : float
        Speed bound (rad/s): the initial velocity error of the convergence rule.
    t_conv : float
        Time (s) to fall below 1e-2 rad/s from v_max: the start-up bandwidth omega0.
    t_settle : float
        The same time for the steady bandwidth omega (after t_switch = 1.5 t_conv).
    omega : float, optional
        A given steady bandwidth (1/s) instead of the rule.
    poles : int
        Partial fractions of the gain functions.

    Returns
    -------
    KalmanModelDesign
    """
    sigma = sensor_sigma(noise, quantization)
    if sigma <= 0:
        raise ValueError("noise and quantization: the encoder must have some noise or quantisation "
                         "(the Kalman gains divide by it)")
    for name, v in (("v_max", v_max), ("t_conv", t_conv), ("t_settle", t_settle), ("dt", dt)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive number, got {v!r}")
    w_floor = omega_floor(v_max, t_settle)
    omega0 = omega_floor(v_max, t_conv)
    if omega is None:
        omega, choice = w_floor, "convergence rule: the smallest omega converging within t_settle"
    else:
        if not (isinstance(omega, (int, float)) and math.isfinite(omega) and omega > 0):
            raise ValueError(f"omega must be a positive number (1/s), got {omega!r}")
        choice = "given"
    gk = normalised_gains()
    joint_std = math.sqrt(sigma ** 2 * dt * omega ** 3 * velocity_variance(gk))
    predicted = {"kinematic": joint_std * math.sqrt(robot.n)}
    floor = lambda_floor(v_max)
    fit = fit_gains(floor, poles)
    tn = None
    if torque_uncertainty is not None:
        tn = check_torque_uncertainty(torque_uncertainty, robot.n)
        predicted["model"] = predicted_model_error(robot, omega, sigma, dt, tn, fit)
    return KalmanModelDesign(
        robot=robot.name, omega=float(omega), omega0=float(max(omega0, omega)), t_switch=1.5 * float(t_conv),
        omega_floor=float(w_floor), choice=choice, sigma=sigma,
        dt=float(dt), v_max=float(v_max), t_conv=float(t_conv), t_settle=float(t_settle), lam_floor=float(floor),
        poles=[float(x) for x in fit[0]], coefficients=np.asarray(fit[1]).tolist(), fit_error=float(fit[2]),
        width=float(joint_std), predicted_error=predicted, predicted_joint_std=float(joint_std),
        torque_uncertainty=None if tn is None else tn.tolist())
