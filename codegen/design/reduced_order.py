"""Gains of the reduced-order observer of seed 000 [S000 (8), (12), (13), Remark 3, (16)].

    c0(q)   = max_{|v| = 1} ||C(q, v)||_2                                       (SPEC §0)
    k0      = max_q [c0(q)(v_max + eta) - lambda_min(F)] / lambda_min(M(q))      (12)
    lambda1 = min_q lambda_min(M(q)) / 2,  lambda2 = max_q lambda_max(M(q)) / 2  (8)
    radius of E = eta sqrt(lambda1 / lambda2)                                    (13)
    Remark 3: k0 = [c0bar (v_max + eta) - lambda_min(F)] / (2 lambda1)
    k_r     = max_q [c0(q)(eta + r vbar) - lambda_min(F)] / lambda_min(M(q))     (16)

Maxima over configurations by ``ConfigurationStats`` (sampled, then refined locally).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .configurations import ConfigurationStats


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


def _lambda_min_F(robot):
    """lambda_min of the symmetric part of the viscous friction F."""
    return float(np.linalg.eigvalsh(0.5 * (robot.F + robot.F.T))[0])


def _gain_objective(lamF, speed):
    """[c0 (speed) - lambda_min(F)] / lambda_min(M), the quantity maximised in (12) and (16)."""
    return lambda lmin, lmax, c0: (c0 * speed - lamF) / lmin


@lru_cache(maxsize=32)
def _design_cached(robot, eta, v_max, samples, seed):
    stats = ConfigurationStats(robot, samples, seed)
    lamF = _lambda_min_F(robot)
    k0, q_k0 = stats.maximise(_gain_objective(lamF, v_max + eta))
    lmin, lmax, c0bar = stats.extremes()
    lambda1, lambda2 = lmin / 2, lmax / 2
    return ReducedOrderDesign(
        robot=robot.name, eta=eta, v_max=v_max, lambda_min_F=lamF, k0=k0, q_k0=np.asarray(q_k0),
        k0_remark3=(c0bar * (v_max + eta) - lamF) / (2 * lambda1), c0bar=c0bar,
        lambda1=lambda1, lambda2=lambda2, radius=eta * np.sqrt(lambda1 / lambda2), samples=samples)


def reduced_order_gain(robot, eta=1.0, v_max=2.0, samples=2000, seed=0):
    """Design k0 for the reduced-order observer [S000 (12)] (cached).

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


def scheduled_gains(robot, eta=1.0, vbar=2.0, r_max=6, samples=2000, seed=0):
    """k_r for r = 1..r_max [S000 (16)]: max_q [c0(q)(eta + r vbar) - lambda_min(F)] / lambda_min(M(q)).

    Parameters
    ----------
    robot : RobotModel (n joints)
    eta : float, error radius [rad/s];  vbar : float, speed step of the schedule [rad/s]
    r_max : int, number of gains;  samples, seed : sampling as in ``reduced_order_gain``

    Returns
    -------
    (r_max,) array of gains k_1 .. k_r_max [1/s]."""
    stats = ConfigurationStats(robot, samples, seed)
    lamF = _lambda_min_F(robot)
    return np.array([stats.maximise(_gain_objective(lamF, eta + r * vbar))[0]
                     for r in range(1, r_max + 1)])
