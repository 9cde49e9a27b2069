"""Noise-aware gains: the gain minimising the predicted estimation error (numbers only).

Sensor: Gaussian noise sigma and/or a quantisation step q (uniform error, std q/sqrt(12)),
per joint, white at the sample rate: sigma_e^2 = sigma^2 + q^2 / 12. Default when the user
gives nothing: a 2^16 counts/rev encoder, q = 2 pi / 65536 = 9.59e-5 rad [ASSUMPTION].
Model: masses and inertias off by a relative ``uncertainty`` d, so the model's acceleration is
off by e = d (qdd + M^-1 (C qd + g)) ~ d M(q)^-1 g(q) for slow motions [DERIVED]; and a torque
error dtau (an offset, unmodelled friction, a payload: ``torque_uncertainty`` t_j N m per joint,
e.g. an identification's torque residual), e = M(q)^-1 dtau. Taken as independent errors of
size t_j, the RMS norm over configurations is rms_q ||M^-1 diag(t)||_F = sqrt(sum_j t_j^2
mean_q |M^-1 e_j|^2), added in quadrature to the relative term: e_rms^2 = (d rms|M^-1 g|)^2 +
sum_j t_j^2 mean_q |M^-1 e_j|^2. The extended-state observer removes a constant e and sees its
rate, d/dt M^-1 dtau = -M^-1 Mdot M^-1 dtau, Mdot = sum_k dM/dq_k qd_k, with RMS
sqrt(sum_j t_j^2 (v^2/n) mean_q sum_k |M^-1 dM/dq_k M^-1 e_j|^2) over speeds of norm v in
random directions (v = v_max/2, as for the relative term).

Reduced-order observer (linearised error dynamics eps' = -k0 eps + e, estimate x2hat = z + k0 y):
under the default discretisation (expmid1, expmid or ETD-RK4, first-order hold) the scalar observer is exactly

    w_k+1 = E w_k + (1 - E) (y_k+1 - y_k) / dt,   E = exp(-k0 dt)        [DERIVED]

(an exponential smoother of the backward difference), so per joint

    noise std  s(k0) = sigma_e (1 - E) / dt sqrt(2 / (1 + E))   (~ k0 sigma_e for k0 dt << 1)
    bias             = |e| / k0

and the noise also enters through the model: the acceleration FD(y, ...) moves with y by
~ -M^-1 dg/dq n (gravity stiffness; slow motions), white noise of PSD sigma_e^2 G^2 dt with
G = rms_q ||M^-1 dg/dq||_F, which the error dynamics filter by 1/(s + k0):

    E(k0)^2 = n s(k0)^2 + sigma_e^2 G^2 dt / (2 k0) + e_rms^2 / k0^2   (norm, RMS; e_rms above)

and the error from an initial eps0 decays like eps0 exp(-k0 t): below ``tol`` within ``t_conv``
needs k0 >= ln(eps0 / tol) / t_conv (the convergence floor), eps0 = v_max: the estimate starts at 0
while the robot may move at up to v_max [ASSUMPTION].

Nicosia-Tomei (kd, kp) (docs/papers/seed000.md §2), per mode mu of M^-1: eps1'' + kd eps1' + kp mu eps1 = e, the
estimate x2hat = kp mu s / (s^2 + kd s + kp mu) y [DERIVED], so

    noise variance  sigma_e^2 dt (kp mu)^2 / (2 kd)   (white noise of PSD sigma_e^2 dt)
    bias            kd / kp |M e| = kd / kp sqrt((d |g|)^2 + |dtau|^2)
    slowest rate    kd/2 - sqrt(max(0, kd^2/4 - kp mu_min)),  mu_min = 1 / max lambda_max(M)
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import minimize, minimize_scalar

ENCODER_COUNTS = 2 ** 16
DEFAULT_QUANTIZATION = 2 * math.pi / ENCODER_COUNTS    # rad, [ASSUMPTION] a 16-bit encoder
TOL = 1e-2                                            # rad/s, convergence threshold


def sensor_sigma(noise=None, quantization=None):
    """Per-joint std of the measurement error (rad): sqrt(sigma^2 + q^2/12).

    Parameters
    ----------
    noise : float or None
        Gaussian std sigma (rad).
    quantization : float or None
        Quantisation step q (rad). Both None: the default encoder (``DEFAULT_QUANTIZATION``).

    Returns
    -------
    float
    """
    for name, v in (("noise", noise), ("quantization", quantization)):
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite number >= 0 (rad), got {v!r}")
    if noise is None and quantization is None:
        quantization = DEFAULT_QUANTIZATION
    return math.sqrt((noise or 0.0) ** 2 + (quantization or 0.0) ** 2 / 12)


def check_uncertainty(uncertainty):
    """``uncertainty`` as a float; ValueError naming it unless a relative model error in [0, 1)."""
    if not (isinstance(uncertainty, (int, float)) and math.isfinite(uncertainty) and 0 <= uncertainty < 1):
        raise ValueError(f"uncertainty must be a relative error in [0, 1), got {uncertainty!r}")
    return float(uncertainty)


def check_torque_uncertainty(torque_uncertainty, n, joint_names=None):
    """Per-joint torque uncertainty (n,) in N m from ``torque_uncertainty``: a number (every
    joint), ``n`` numbers, or a dict joint name -> number (e.g. an identification report's
    held-out torque residual, ``report["residual_rms"]["after"]``), each finite and >= 0;
    ValueError naming it otherwise.

    Parameters
    ----------
    torque_uncertainty : float, sequence of float or dict
        N m.
    n : int
        Number of joints.
    joint_names : sequence of str, optional
        The joints, in order (needed for a dict: every joint once, no other key).

    Returns
    -------
    (n,) float array
    """
    if isinstance(torque_uncertainty, dict):
        names = list(joint_names or [])
        missing = [j for j in names if j not in torque_uncertainty]
        extra = [k for k in torque_uncertainty if k not in names]
        if not names or missing or extra:
            raise ValueError(f"torque_uncertainty: a dict needs every joint ({', '.join(names)}) and no "
                             f"other key; missing {missing}, unknown {extra}")
        torque_uncertainty = [torque_uncertainty[j] for j in names]
    try:
        t = np.asarray(torque_uncertainty, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        t = np.array([np.nan])
    if t.size == 1:
        t = np.full(n, float(t[0]))
    if t.size != n or not np.all(np.isfinite(t) & (t >= 0)):
        raise ValueError(f"torque_uncertainty must be a torque >= 0 (N m) or {n} of them (one per joint), "
                         f"got {torque_uncertainty!r}")
    return t


def torque_error_rms(torque_uncertainty, column_ms):
    """RMS norm of a vector M^-1 dtau (or of its rate) when dtau has independent per-joint errors
    of size ``torque_uncertainty`` (n,) N m: sqrt(sum_j dtau_j^2 column_ms_j), ``column_ms`` (n,)
    the mean square norm of column j of the matrix applied to dtau (``torque_statistics``)."""
    t = np.asarray(torque_uncertainty, dtype=float)
    return float(math.sqrt(float(np.sum(t ** 2 * np.asarray(column_ms, dtype=float)))))


def convergence_floor(eps0, t_conv, tol=TOL):
    """Rate (1/s) that brings an error eps0 below tol within t_conv: ln(eps0/tol) / t_conv."""
    if not (t_conv > 0 and eps0 > 0):
        raise ValueError(f"t_conv and the initial error must be positive, got t_conv={t_conv}, eps0={eps0}")
    return max(math.log(eps0 / tol), 0.0) / t_conv


def smoother_noise(k0, dt, sigma):
    """Std (rad/s) of w = the exponential smoother of the backward difference (module docstring) at
    gain ``k0`` (1/s), sample time ``dt`` (s) and sensor std ``sigma`` (rad)."""
    E = math.exp(-k0 * dt)
    return sigma * (1 - E) / dt * math.sqrt(2 / (1 + E))


def reduced_order_error(k0, dt, n, sigma, e_rms, G=0.0):
    """Predicted RMS of the error norm (rad/s), module docstring:
    sqrt(n s(k0)^2 + sigma^2 G^2 dt / (2 k0) + (e_rms / k0)^2)."""
    return math.sqrt(n * smoother_noise(k0, dt, sigma) ** 2 + sigma ** 2 * G ** 2 * dt / (2 * k0)
                     + (e_rms / k0) ** 2)


@dataclass
class NoiseAwareDesign:
    """The reduced-order gain minimising the predicted error, with the values it is chosen among.

    k0 is the default; ``choice`` and ``why`` say which value it is and why."""
    robot: str
    k0: float
    choice: str                # "noise-aware optimum" | "convergence floor" | "guarantee (12)"
    why: str
    k0_noise: float            # argmin of the predicted error (unconstrained), inf without noise
    k0_floor: float            # ln(v_max / tol) / t_conv
    k0_guarantee: float        # (12)
    k0_remark3: float
    predicted_error: dict      # name -> predicted RMS error norm at that gain (rad/s)
    sigma: float               # per-joint measurement std used (rad)
    noise: float | None
    quantization: float | None
    uncertainty: float
    e_rms: float               # rms_q |M^-1 g| * uncertainty (rad/s^2)
    G: float                   # rms_q ||M^-1 dg/dq||_F (1/s^2)
    dt: float
    t_conv: float
    eta: float
    v_max: float
    guarantee: dict            # the (12) design report
    torque_uncertainty: list = None    # per joint, N m (None: not stated)
    e_rms_torque: float = 0.0  # rms_q ||M^-1 diag(torque_uncertainty)||_F (rad/s^2), inside e_rms

    def as_dict(self):
        """The fields as a JSON-ready dict (arrays as lists)."""
        return dict(self.__dict__)

    def __str__(self):
        pe = self.predicted_error
        return "\n".join([
            f"reduced-order gain for {self.robot}: k0 = {self.k0:.6g} ({self.choice}): {self.why}",
            f"  sensor std {self.sigma:.3g} rad (noise {self.noise}, quantization {self.quantization}),"
            f" model uncertainty {self.uncertainty:g}, dt {self.dt:g} s",
            f"  model acceleration error {self.e_rms:.3g} rad/s^2 (of which torque uncertainty "
            f"{self.e_rms_torque:.3g}: {self.torque_uncertainty or 0} N m)",
            f"  noise-aware optimum {self.k0_noise:.6g}, convergence floor {self.k0_floor:.6g}"
            f" (below 1e-2 within {self.t_conv:g} s from {self.v_max:g} rad/s),",
            f"  guarantee (12) {self.k0_guarantee:.6g}, Remark 3 {self.k0_remark3:.6g}",
            "  predicted RMS error: " + ", ".join(f"{k} {v:.3g}" for k, v in pe.items()) + " rad/s",
        ])


def reduced_order_noise_gain(n, dt, sigma, e_rms, G, floor, guarantee):
    """Choose k0 (see NoiseAwareDesign): the predicted-error minimiser, raised to the convergence
    floor; without noise the guarantee gain (12) (a higher gain only lowers the bias), raised to
    the floor. (The families then keep it inside the stable region, codegen.discrete.stability.)

    Parameters
    ----------
    n : int
        Number of joints.
    dt : float
        Sample time, s.
    sigma : float
        Sensor std sigma_e, rad.
    e_rms : float
        RMS model acceleration error d rms_q |M^-1 g|, rad/s^2.
    G : float
        Gravity stiffness rms_q ||M^-1 dg/dq||_F, 1/s^2.
    floor : float
        Convergence floor on k0, 1/s.
    guarantee : float
        Gain of the guarantee (12), 1/s.

    Returns
    -------
    (k0, choice, why, k0_noise, predicted errors dict)."""
    def err(k):
        return reduced_order_error(k, dt, n, sigma, e_rms, G)
    if sigma > 0 and (e_rms > 0 or G > 0):
        # the k0 dt << 1 optima of each pair of terms bracket the minimiser
        guesses = [(e_rms ** 2 / (n * sigma ** 2)) ** 0.25, (G ** 2 * dt / (4 * n)) ** (1 / 3)]
        lo, hi = min(g for g in guesses if g > 0), max(guesses)
        res = minimize_scalar(lambda lk: err(math.exp(lk)), method="bounded",
                              bounds=(math.log(lo) - 2, math.log(hi) + 2))
        k_noise = math.exp(res.x)
    elif sigma > 0:
        k_noise = 0.0          # the error only grows with k0: the floor decides
    else:
        k_noise = math.inf     # no noise: the error only falls with k0
    if sigma == 0:
        k0, choice = max(guarantee, floor), "guarantee (12)" if guarantee >= floor else "convergence floor"
        why = "no sensor noise: a higher gain only lowers the model-error bias; (12) certifies the region (13)"
    elif k_noise >= floor:
        k0, choice = k_noise, "noise-aware optimum"
        why = ("minimises the predicted error (measurement noise ~ k0 sigma against noise through the model "
               "~ sigma G sqrt(dt / 2 k0) and model-error bias ~ |e|/k0)")
    else:
        k0, choice = floor, "convergence floor"
        why = (f"the noise-aware optimum {k_noise:.4g} is below the gain that converges to 1e-2 rad/s in time; "
               "lower gains would only be slower")
    predicted = {"default": err(k0), "guarantee (12)": err(guarantee), "floor": err(floor)}
    return k0, choice, why, k_noise, predicted


def nicosia_tomei_noise_gains(dt, sigma, g_rms, uncertainty, trace_minv2, mu_min, rate, torque_rms=0.0):
    """(kd, kp) minimising the predicted error of Nicosia-Tomei (module docstring) subject to
    the slowest error mode decaying at ``rate`` or faster.

    Parameters
    ----------
    dt : float, sample time (s);  sigma : measurement std (rad)
    g_rms : rms_q |g(q)| (N m);  uncertainty : relative model error
    trace_minv2 : mean_q trace(M(q)^-2) (1/(kg m^2)^2);  mu_min : 1 / max_q lambda_max(M(q))
    rate : required slowest decay rate (1/s)
    torque_rms : RMS norm of a torque error dtau (N m, e.g. sqrt(sum_j torque_uncertainty_j^2)):
        the bias is kd / kp |dtau| (kp x1tilde enters as a torque), added in quadrature to the
        relative model error's kd / kp uncertainty |g|

    Returns
    -------
    (kd, kp, predicted RMS error norm)."""
    tau_err = math.hypot(uncertainty * g_rms, torque_rms)      # RMS norm of the torque error (N m)

    def error(kd, kp):
        return math.sqrt(sigma ** 2 * dt * kp ** 2 * trace_minv2 / (2 * kd) + (kd / kp * tau_err) ** 2)

    def slowest(kd, kp):
        return kd / 2 - math.sqrt(max(0.0, kd ** 2 / 4 - kp * mu_min))

    kd0 = 2 * rate                       # critically damped slowest mode: the least noise at no model error
    kp0 = rate ** 2 / mu_min
    if tau_err == 0:
        return kd0, kp0, error(kd0, kp0)

    def cost(v):
        kd, kp = math.exp(v[0]), math.exp(v[1])
        short = max(0.0, rate - slowest(kd, kp)) / rate
        return math.log(error(kd, kp)) + 1e3 * short ** 2
    res = minimize(cost, [math.log(kd0), math.log(kp0)], method="Nelder-Mead",
                   options={"xatol": 1e-6, "fatol": 1e-10, "maxiter": 2000})
    kd, kp = math.exp(res.x[0]), math.exp(res.x[1])
    if slowest(kd, kp) < rate * (1 - 1e-3):
        kd, kp = kd0, kp0
    return kd, kp, error(kd, kp)


def gravity_statistics(chunks):
    """Statistics of the model over sampled configurations (for the predictions above).

    Parameters
    ----------
    chunks : iterable of (Ms (S, n, n), gs (S, n), dgs (S, n, n)), M(q), g(q) and dg/dq at the
        configurations, in chunks

    Returns
    -------
    dict: minv_g_rms (rms |M^-1 g|, rad/s^2), minv_dg_rms (rms ||M^-1 dg/dq||_F, 1/s^2), g_rms
    (rms |g|, N m), trace_minv2 (mean tr(M^-2)), mu_min (1 / max lambda_max(M)), mu_max
    (1 / min lambda_min(M))."""
    terms = []
    for Ms, gs, dgs in chunks:      # per configuration: |M^-1 g|^2, ||M^-1 dg||_F^2, |g|^2, tr M^-2, lambda
        lam = np.linalg.eigvalsh(Ms)
        terms.append(np.column_stack([np.sum(np.linalg.solve(Ms, gs[:, :, None])[:, :, 0] ** 2, axis=1),
                                      np.sum(np.linalg.solve(Ms, dgs) ** 2, axis=(1, 2)), np.sum(gs ** 2, axis=1),
                                      np.sum(lam ** -2.0, axis=1), lam[:, 0], lam[:, -1]]))
    t = np.concatenate(terms)
    return {"minv_g_rms": float(np.sqrt(np.mean(t[:, 0]))), "minv_dg_rms": float(np.sqrt(np.mean(t[:, 1]))),
            "g_rms": float(np.sqrt(np.mean(t[:, 2]))), "trace_minv2": float(np.mean(t[:, 3])),
            "mu_min": float(1 / t[:, 5].max()), "mu_max": float(1 / t[:, 4].min())}


def bias_balance_gain(n, dt, sigma, e_rms):
    """The gain k (1/s) at which the predicted model-error bias e_rms / k equals the predicted
    measurement noise sqrt(n) s(k) of the reduced-order observer (``smoother_noise``): below it
    the bias is the larger term, and lowering the gain costs more bias than it saves noise.
    0 without model error, inf without sensor noise (the bias is then the only error).

    Parameters
    ----------
    n : int
        Number of joints.
    dt : float
        Sample time, s.
    sigma : float
        Sensor std, rad.
    e_rms : float
        RMS norm of the model's acceleration error, rad/s^2 (relative and torque uncertainty).

    Returns
    -------
    float
    """
    from scipy.optimize import brentq
    if e_rms <= 0:
        return 0.0
    if sigma <= 0:
        return math.inf

    def f(lk):
        k = math.exp(lk)
        return math.log(e_rms / k) - math.log(math.sqrt(n) * smoother_noise(k, dt, sigma))
    lo, hi = math.log(1e-9), math.log(1e12)
    if f(hi) > 0:         # the noise saturates at sigma sqrt(2) / dt: the bias is larger at every gain
        return math.inf
    return math.exp(brentq(f, lo, hi, xtol=1e-12))


def switched_gains(nd, n, t_settle=2.0):
    """The time-switched gain of the reduced_order_switched family from a noise-aware design.

    The gain nd.k0 (>= the convergence floor) runs until the initial error has decayed to the
    predicted error at that gain, then the gain switches (bumplessly) to the noise-aware optimum
    nd.k0_noise, kept at or above the gain that still brings an error of v_max below 1e-2 rad/s
    within ``t_settle`` (so a model error or a disturbance the design did not foresee still
    settles in seconds), at or above the gain k0_bias where the predicted bias (model and torque
    uncertainty, nd.e_rms / k) equals the predicted measurement noise sqrt(n) s(k) (the final
    gain never sits where its bias is larger than the noise it saves; the optimum of E already
    satisfies it, the bound makes the rule explicit) and at or below nd.k0 [DERIVED]:

        k0_final = min(k0, max(k0_noise, ln(v_max / tol) / t_settle, k0_bias))
        t_switch = max(t_conv, ln(v_max / E(k0)) / k0),   E the predicted RMS error

    Parameters
    ----------
    nd : NoiseAwareDesign
        The design of the initial gain (its sensor, uncertainty, dt, v_max, t_conv).
    n : int
        Number of joints.
    t_settle : float
        Time (s) the final gain takes to bring an error of v_max below 1e-2 rad/s.

    Returns
    -------
    dict
        k0, k0_final (1/s), t_switch (s), k0_settle and k0_bias (the floors of k0_final, 1/s),
        t_settle, the predicted RMS error and the predicted bias nd.e_rms / k at k0 and at
        k0_final (rad/s); k0_final = k0 (no switch) without sensor noise or when the optimum is
        the convergence-floor gain or above.
    """
    if not (isinstance(t_settle, (int, float)) and math.isfinite(t_settle) and t_settle > 0):
        raise ValueError(f"t_settle must be a positive time (s), got {t_settle!r}")
    k_settle = convergence_floor(nd.v_max, t_settle)
    k_bias = bias_balance_gain(n, nd.dt, nd.sigma, nd.e_rms)
    k0 = nd.k0
    k_final = min(k0, max(nd.k0_noise, k_settle, k_bias)) if math.isfinite(nd.k0_noise) else k0

    def err(k):
        return reduced_order_error(k, nd.dt, n, nd.sigma, nd.e_rms, nd.G)
    e0 = err(k0)
    t_switch = max(nd.t_conv, math.log(nd.v_max / e0) / k0) if (k_final < k0 and e0 > 0) else 0.0
    return {"k0": float(k0), "k0_final": float(k_final), "t_switch": float(t_switch),
            "k0_settle": float(k_settle), "k0_bias": float(k_bias), "t_settle": float(t_settle),
            "predicted_error": {"k0": e0, "k0_final": err(k_final)},
            "predicted_bias": {"k0": nd.e_rms / k0, "k0_final": nd.e_rms / k_final}}


# ------------------------------------------------------------ extended-state observer (per joint)
# e = y - q_hat:  q_hat' = v_hat + l1 e,  v_hat' = a_model + d_hat + l2 e,  d_hat' = l3 e, with the
# triple pole (s + w)^3: l1, l2, l3 = 3 w, 3 w^2, w^3.  Error (q, v, d) per joint: x' = A x + ...,
# A = [[-l1, 1, 0], [-l2, 0, 1], [-l3, 0, 0]].  [DERIVED]

def extended_state_gains(omega):
    """(l1, l2, l3) = (3 w, 3 w^2, w^3) of the triple pole at -``omega`` (1/s)."""
    return 3 * omega, 3 * omega ** 2, omega ** 3


def _eso_matrix(omega):
    l1, l2, l3 = extended_state_gains(omega)
    return np.array([[-l1, 1.0, 0.0], [-l2, 0.0, 1.0], [-l3, 0.0, 0.0]]), np.array([l1, l2, l3])


def extended_state_noise(omega, dt, sigma):
    """Std (rad/s) of v_hat at poles -``omega`` (1/s) from white measurement noise of std ``sigma`` (rad) sampled every
    ``dt`` (s) (PSD sigma^2 dt), per joint: the stationary covariance of the error dynamics
    (continuous Lyapunov equation A P + P A^T + b b^T sigma^2 dt = 0), its v entry."""
    from scipy.linalg import solve_continuous_lyapunov
    A, b = _eso_matrix(omega)
    P = solve_continuous_lyapunov(A, -np.outer(b, b) * sigma ** 2 * dt)
    return math.sqrt(max(P[1, 1], 0.0))


@lru_cache(maxsize=1)
def _unit_response():
    """(t, |v(t)|) of the unit-omega error dynamics from a unit velocity error, t in [0, 60]
    (the response of any omega is this one at omega t): computed once."""
    from scipy.linalg import expm
    A, _ = _eso_matrix(1.0)
    ts = np.linspace(0.0, 60.0, 24001)
    step = expm(A * (ts[1] - ts[0]))
    x, v = np.array([0.0, 1.0, 0.0]), np.empty(len(ts))
    for i in range(len(ts)):
        v[i] = abs(x[1])
        x = step @ x
    return ts, v


def extended_state_floor(v_max, t_conv, tol=TOL):
    """The smallest omega (1/s) with which an initial velocity error v_max (rad/s) stays below
    tol after t_conv (s): the response scales with omega t, so omega = c / t_conv with c the
    last time the unit-omega response |v(c)| exceeds tol / v_max."""
    ts, v = _unit_response()
    above = np.nonzero(v > tol / v_max)[0]
    return float(ts[above[-1]]) / t_conv if len(above) else 0.0


def extended_state_noise_gain(n, dt, sigma, e_dot, floor):
    """omega minimising the predicted RMS error norm of the extended-state observer,
    sqrt(n s(w)^2 + (3 e_dot / w^2)^2), at or above the convergence ``floor`` (1/s).

    Parameters
    ----------
    n : int
        Number of joints.
    dt : float
        Sample time, s.
    sigma : float
        Sensor std, rad.
    e_dot : float
        RMS norm of the rate of the model's acceleration error (rad/s^3): a ramp disturbance
        leaves a velocity error 3 e_dot / w^2 (final value theorem on the error dynamics).
    floor : float
        Convergence floor on omega (extended_state_floor), 1/s.

    Returns
    -------
    (omega, predicted RMS error at omega (rad/s), unconstrained optimum (1/s; 0 when only the
    floor bounds it)).
    """
    def err(w):
        return math.sqrt(n * extended_state_noise(w, dt, sigma) ** 2 + (3 * e_dot / w ** 2) ** 2)
    if sigma > 0 and e_dot > 0:
        res = minimize_scalar(lambda lw: err(math.exp(lw)), method="bounded",
                              bounds=(math.log(0.1), math.log(0.5 / dt)))
        w_opt = math.exp(res.x)
    else:
        w_opt = 0.0 if sigma > 0 else math.inf
    omega = max(floor, w_opt) if math.isfinite(w_opt) else max(floor, 0.1 / dt)
    return omega, err(omega), w_opt
