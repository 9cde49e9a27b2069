"""Gains of the reduced-order observer of seed 000 [S000 (8), (12), (13), Remark 3, (16)].

    c0(q)   = max_{|v| = 1} ||C(q, v)||_2                                       (docs/papers/seed000.md §0)
    k0      = max_q [c0(q)(v_max + eta) - lambda_min(F)] / lambda_min(M(q))      (12)
    lambda1 = min_q lambda_min(M(q)) / 2,  lambda2 = max_q lambda_max(M(q)) / 2  (8)
    radius of E = eta sqrt(lambda1 / lambda2)                                    (13)
    Remark 3: k0 = [c0bar (v_max + eta) - lambda_min(F)] / (2 lambda1)
    k_r     = max_q [c0(q)(eta + r vbar) - lambda_min(F)] / lambda_min(M(q))     (16)

F is the viscous part diag(viscous) of the robot's friction only: the error dynamics see
tau_f(qd) - tau_f(qd_hat), and for tau_f(v) = F v + coulomb tanh(v / w) + offset the offset
cancels and the Coulomb part is monotone, so e^T (tau_f(qd) - tau_f(qd_hat)) >= lambda_min(F)
|e|^2 and the proof of (12) holds with the viscous lambda_min(F) (a conservative gain).

Maxima over configurations by ``ConfigurationStats`` (sampled, then refined locally), kept on
disk by robot content (codegen.core.cache). The default gain of the observer families is the
noise-aware one (``reduced_order_design``, codegen.families.design.noise); (12) stays in its report.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ...core.cache import cached_json, key_digest
from .configurations import MEMORY_BYTES, ConfigurationStats, sample_points
from .noise import (NoiseAwareDesign, check_torque_uncertainty, check_uncertainty, convergence_floor,
                    gravity_statistics, reduced_order_noise_gain, sensor_sigma, torque_error_rms)
from .rigid_batch import TreeBatch

VERSION = 2          # of these designs (part of the disk-cache key)
SAMPLES = 512        # sampled configurations
REFINE = 8           # local searches from the best samples


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
        """The fields as a JSON-ready dict (arrays as lists)."""
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
            f"  ({self.samples} sampled configurations, best {REFINE} refined locally)",
        ])


def _lambda_min_F(robot):
    """lambda_min of the symmetric part of the viscous friction F of ``robot`` (the viscous part
    of its friction only: the module docstring says why)."""
    return float(np.linalg.eigvalsh(0.5 * (robot.F + robot.F.T))[0])


def _gain_objective(lamF, speed):
    """[c0 (speed) - lambda_min(F)] / lambda_min(M), the quantity maximised in (12) and (16)."""
    return lambda lmin, lmax, c0: (c0 * speed - lamF) / lmin


def robot_key(robot):
    """Cache key of what a design for ``robot`` depends on: the content of M(q) and g(q), F and the
    joint ranges."""
    return key_digest([robot.M.serialize(), robot.g.serialize(), np.asarray(robot.F).tolist(),
                       np.asarray(robot.q_lower).tolist(), np.asarray(robot.q_upper).tolist()])


def _disk(kind, robot, compute, **inputs):
    return cached_json("design", {"kind": kind, "version": VERSION, "robot": robot_key(robot), **inputs},
                       compute)


@lru_cache(maxsize=32)
def _design_cached(robot, eta, v_max, samples, seed):
    def compute():
        stats = ConfigurationStats(robot, samples, seed)
        lamF = _lambda_min_F(robot)
        k0, q_k0 = stats.maximise(_gain_objective(lamF, v_max + eta), REFINE)
        lmin, lmax, c0bar = stats.extremes(REFINE)
        lambda1, lambda2 = lmin / 2, lmax / 2
        return dict(robot=robot.name, eta=eta, v_max=v_max, lambda_min_F=lamF, k0=k0,
                    q_k0=[float(x) for x in q_k0],
                    k0_remark3=(c0bar * (v_max + eta) - lamF) / (2 * lambda1), c0bar=c0bar,
                    lambda1=lambda1, lambda2=lambda2, radius=eta * math.sqrt(lambda1 / lambda2),
                    samples=samples)
    d = _disk("reduced_order_gain", robot, compute, eta=eta, v_max=v_max, samples=samples, seed=seed)
    return ReducedOrderDesign(**{**d, "robot": robot.name, "q_k0": np.asarray(d["q_k0"])})


def reduced_order_gain(robot, eta=1.0, v_max=2.0, samples=SAMPLES, seed=0):
    """Design k0 for the reduced-order observer [S000 (12)] (cached in memory and on disk).

    Parameters
    ----------
    robot : RobotModel (n joints)
    eta : float > 0, radius of the estimation-error ball to be attracted [rad/s]
    v_max : float > 0, bound on the joint speed ||qd|| [rad/s]
    samples : int, random configurations sampled before local refinement
    seed : int, seed of the sampling

    Returns
    -------
    ReducedOrderDesign (k0 and the constants of (8), (13), Remark 3)."""
    if eta <= 0 or v_max <= 0:
        raise ValueError(f"eta and v_max must be positive, got eta={eta}, v_max={v_max}")
    return _design_cached(robot, float(eta), float(v_max), int(samples), int(seed))


@lru_cache(maxsize=32)
def _scheduled_cached(robot, eta, vbar, r_max, samples, seed):
    def compute():
        stats = ConfigurationStats(robot, samples, seed)
        lamF = _lambda_min_F(robot)
        gains, q = [], None
        for r in range(1, r_max + 1):       # after r = 1: from the previous maximiser and 2 samples
            k, q = stats.maximise(_gain_objective(lamF, eta + r * vbar), REFINE if q is None else 2,
                                  starts=None if q is None else q[None])
            gains.append(k)
        return gains
    return np.array(_disk("scheduled_gains", robot, compute, eta=eta, vbar=vbar, r_max=r_max,
                          samples=samples, seed=seed))


def scheduled_gains(robot, eta=1.0, vbar=2.0, r_max=6, samples=SAMPLES, seed=0):
    """k_r for r = 1..r_max [S000 (16)]: max_q [c0(q)(eta + r vbar) - lambda_min(F)] / lambda_min(M(q)).

    Parameters
    ----------
    robot : RobotModel (n joints)
    eta : float, error radius [rad/s];  vbar : float, speed step of the schedule [rad/s]
    r_max : int, number of gains;  samples, seed : sampling as in ``reduced_order_gain``

    Returns
    -------
    (r_max,) array of gains k_1 .. k_r_max [1/s] (cached in memory and on disk)."""
    return _scheduled_cached(robot, float(eta), float(vbar), int(r_max), int(samples), int(seed))


@lru_cache(maxsize=32)
def model_statistics(robot, samples=SAMPLES, seed=0):
    """``noise.gravity_statistics`` of ``robot`` over ``samples`` configurations drawn with ``seed``
    (the design's sample points): M, g and dg/dq from the kinematic tree when the robot has one
    (codegen.families.design.rigid_batch, in chunks below MEMORY_BYTES), else from its CasADi
    functions."""
    points = sample_points(robot, samples, seed)
    n = robot.n
    if getattr(robot, "tree", None) is not None:
        chunk = max(1, int(MEMORY_BYTES // (8 * (40 * n + 16 * n * n))))
        return gravity_statistics(
            (lambda b: (b.mass_matrix(),) + b.gravity())(TreeBatch(robot.tree, points[lo:lo + chunk]))
            for lo in range(0, len(points), chunk))
    q = ca.SX.sym("q", n)
    dg = ca.Function("dg", [q], [ca.jacobian(robot.gravity(q), q)])
    S = len(points)
    return gravity_statistics([(np.asarray(robot.M.map(S)(points.T)).reshape(n, S, n).transpose(1, 0, 2),
                                np.asarray(robot.g.map(S)(points.T)).reshape(n, S).T,
                                np.asarray(dg.map(S)(points.T)).reshape(n, S, n).transpose(1, 0, 2))])


@lru_cache(maxsize=32)
def torque_statistics(robot, samples=SAMPLES, seed=0):
    """How a torque error reaches the acceleration of ``robot`` (RobotModel, n joints), over the
    design's sample configurations (``samples`` drawn with ``seed``, as ``model_statistics``).

    Returns
    -------
    dict
        "minv_col_ms": (n,) list, mean_q |M(q)^-1 e_j|^2 (1/(kg m^2)^2): the acceleration error of
        a unit torque error on joint j (codegen.families.design.noise: e = M^-1 dtau);
        "dminv_col_ms": (n,) list, mean_q sum_k |M^-1 dM/dq_k M^-1 e_j|^2: its rate per unit
        speed (d/dt M^-1 = -M^-1 Mdot M^-1, Mdot = sum_k dM/dq_k qd_k);
        "minv_col_max": (n,) list, max_q |M(q)^-1 e_j| (the worst configuration of the samples).
    """
    n = robot.n
    q = ca.SX.sym("q", n)
    Mq = robot.mass_matrix(q)
    dM = ca.Function("dM", [q], [ca.horzcat(*[ca.jacobian(Mq[:, j], q) for j in range(n)])])
    points = sample_points(robot, samples, seed)
    S = len(points)
    Ms = np.asarray(robot.M.map(S)(points.T)).reshape(n, S, n).transpose(1, 0, 2)
    # dM(q): column block j is d M[:, j] / dq, (n, n): entry (i, k) = dM_ij/dq_k
    D = np.asarray(dM.map(S)(points.T)).reshape(n, S, n, n).transpose(1, 0, 2, 3)   # (S, i, j, k)
    Minv = np.linalg.inv(Ms)
    col_ms = np.mean(np.sum(Minv ** 2, axis=1), axis=0)
    # A_k = M^-1 (dM/dq_k) M^-1: (S, k, i, j)
    dMk = D.transpose(0, 3, 1, 2)
    A = Minv[:, None] @ dMk @ Minv[:, None]
    dcol_ms = np.mean(np.sum(A ** 2, axis=(1, 2)), axis=0)
    return {"minv_col_ms": col_ms.tolist(), "dminv_col_ms": dcol_ms.tolist(),
            "minv_col_max": np.sqrt(np.max(np.sum(Minv ** 2, axis=1), axis=0)).tolist()}


def reduced_order_design(robot, dt, noise=None, quantization=None, uncertainty=0.0, eta=1.0, v_max=2.0,
                         t_conv=0.2, torque_uncertainty=0.0):
    """The default k0: the predicted-error minimiser for the sensor and model uncertainty,
    next to the guarantee (12) and Remark 3 (codegen.families.design.noise).

    Parameters
    ----------
    robot : RobotModel (n joints)
    dt : float, sample time (s)
    noise, quantization : float or None, Gaussian std and quantisation step of y (rad);
        both None: a 2^16 counts/rev encoder
    uncertainty : float, relative error of masses and inertias (0.1 = 10 %)
    eta, v_max : float, (12)'s error radius and speed bound (rad/s); v_max is also the initial
        error of the convergence floor (the estimate starts at 0, the robot at up to v_max)
    t_conv : float, time (s) to fall below 1e-2 rad/s from v_max
    torque_uncertainty : float or (n,) floats, torque error per joint (N m; e.g. an identification's
        torque residual): its acceleration error rms_q ||M^-1 diag(t)||_F adds in quadrature to
        the relative one (codegen.families.design.noise)

    Returns
    -------
    NoiseAwareDesign"""
    uncertainty = check_uncertainty(uncertainty)
    tau_unc = check_torque_uncertainty(torque_uncertainty, robot.n, robot.joint_names)
    sigma = sensor_sigma(noise, quantization)
    guarantee = reduced_order_gain(robot, eta=eta, v_max=v_max)
    stats = model_statistics(robot)
    e_tau = torque_error_rms(tau_unc, torque_statistics(robot)["minv_col_ms"]) if tau_unc.any() else 0.0
    e_rms, G = math.hypot(uncertainty * stats["minv_g_rms"], e_tau), stats["minv_dg_rms"]
    floor = convergence_floor(v_max, t_conv)
    k0, choice, why, k_noise, predicted = reduced_order_noise_gain(robot.n, dt, sigma, e_rms, G, floor,
                                                                   guarantee.k0)
    return NoiseAwareDesign(
        robot=robot.name, k0=float(k0), choice=choice, why=why, k0_noise=float(k_noise), k0_floor=floor,
        k0_guarantee=guarantee.k0, k0_remark3=guarantee.k0_remark3,
        predicted_error=predicted, sigma=sigma, noise=noise, quantization=quantization,
        uncertainty=uncertainty, e_rms=e_rms, G=G, dt=float(dt), t_conv=float(t_conv), eta=float(eta),
        v_max=float(v_max), guarantee=guarantee.as_dict(),
        torque_uncertainty=tau_unc.tolist() if tau_unc.any() else None, e_rms_torque=float(e_tau))
