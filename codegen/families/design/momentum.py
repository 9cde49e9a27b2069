"""The momentum observer's default gains and thresholds, as rules of measured or stated inputs.

Seen from an external torque tau_ext, the residual r of the momentum observer fed by the
reduced-order velocity observer (gain k0) is the product of two first-order lags

    r = K_O k0 / ((s + K_O)(s + k0)) tau_ext                                  (per joint)

(the velocity observer's model lacks tau_ext, so its estimate lags by 1/k0; the momentum
integrator by 1/K_O). For a given fastest pole a double pole is the quickest without overshoot,
so K_O = k0 = omega, and a contact of ``ratio`` times the threshold crosses it after
x / omega, x the root of (1 + x) e^-x = 1 - 1/ratio (x = 1.19 at ratio 3):

    omega = x / (t_detect / 2)

half the detection budget t_detect left for the sampling and the contact's own rise.

Threshold: the torque noise (std sigma_tau per sample at dt) passes through the same filter,
sigma_r^2 = sigma_tau^2 dt omega / 4, and |r_j| of a Gaussian r crosses u sigma_r upwards
nu0 e^(-u^2 / 2) times per second each way, nu0 = omega / (2 pi) (Rice's formula for the double
pole). For a false-alarm rate R (per hour of motion, over all n joints) the level is

    th0_j = sigma_r,j sqrt(2 ln(2 n nu0 3600 / R)).

A log measures sigma_r and the tail instead (codegen.logs.detect); these are the defaults
before one.
"""
from __future__ import annotations

import math

import numpy as np

from .noise import check_torque_uncertainty

RATIO = 3.0              # the contacts the detection time is promised for: 3x the threshold
T_DETECT = 0.02          # s, the detection time asked for
FALSE_ALARMS = 1.0       # per hour of motion, all joints together
NOISE_SHARE = 0.01       # the default torque noise: 1 % of the joint's torque scale

__all__ = ["design_momentum", "crossing_time", "threshold_level", "torque_scale"]


def crossing_time(ratio=RATIO):
    """x = omega t at which the double-pole step response 1 - (1 + x) e^-x reaches 1 / ratio."""
    if not ratio > 1.0:
        raise ValueError(f"ratio must be > 1 (a contact above its threshold), got {ratio!r}")
    target, x = 1.0 - 1.0 / ratio, 1.0
    for _ in range(60):                                    # Newton on (1 + x) e^-x - target
        f, df = (1 + x) * math.exp(-x) - target, -x * math.exp(-x)
        x -= f / df
    return x


def threshold_level(n, nu0, false_alarms=FALSE_ALARMS):
    """u such that n joints of a Gaussian residual cross +-u sigma together ``false_alarms``
    times an hour, each nu0 (1/s) e^(-u^2/2) times a second each way (Rice)."""
    if not false_alarms > 0:
        raise ValueError(f"false_alarms must be a positive rate per hour, got {false_alarms!r}")
    arg = 2.0 * n * nu0 * 3600.0 / false_alarms
    return math.sqrt(2.0 * math.log(arg)) if arg > 1.0 else 0.0


def torque_scale(robot, count=64):
    """(n,) the torque scale of each joint, N m: the declared effort limit, or where none is
    declared the largest |g_j(q)| over ``count`` sampled configurations (at least 1 N m)."""
    eff = np.asarray(robot.effort_limit, dtype=float)
    if np.all(np.isfinite(eff)):
        return eff
    Q = robot.sample_configurations(count, seed=0)
    g = np.abs(np.column_stack([np.asarray(robot.g(q)).reshape(-1) for q in Q]))
    return np.where(np.isfinite(eff), eff, np.maximum(g.max(axis=1), 1.0))


def design_momentum(robot, dt, torque_noise=None, t_detect=T_DETECT, false_alarms=FALSE_ALARMS, ratio=RATIO):
    """The default gains and thresholds of the momentum observer (module docstring).

    Parameters
    ----------
    robot : RobotModel (n joints)
    dt : float
        Sample time (s).
    torque_noise : float or (n,) floats, optional
        Std of the measured torque per sample (N m); default NOISE_SHARE of ``torque_scale``.
    t_detect : float
        Time (s) in which a contact of ``ratio`` times the threshold is to be detected.
    false_alarms : float
        False alarms per hour of motion the thresholds allow (all joints).

    Returns
    -------
    dict
        omega (1/s, k0 = K_O = omega), th0 (n,) N m, th1 (n,) N m s/rad (0: no velocity term
        until a log measures one), sigma_r (n,) N m, level u, nu0 (1/s), and the inputs.
    """
    n = robot.n
    if not (isinstance(t_detect, (int, float)) and t_detect > 2 * dt):
        raise ValueError(f"t_detect must be a time (s) above two samples ({2 * dt:g} s), got {t_detect!r}")
    stated = torque_noise is not None
    sigma = (NOISE_SHARE * torque_scale(robot) if not stated else
             check_torque_uncertainty(torque_noise, n, robot.joint_names))
    x = crossing_time(ratio)
    omega = x / (t_detect / 2.0)
    sigma_r = sigma * math.sqrt(dt * omega / 4.0)
    nu0 = omega / (2.0 * math.pi)
    u = threshold_level(n, nu0, false_alarms)
    return {"omega": float(omega), "k0": float(omega), "K_O": float(omega),
            "th0": (u * sigma_r).tolist(), "th1": [0.0] * n, "sigma_r": sigma_r.tolist(),
            "level": float(u), "nu0": float(nu0), "crossing": float(x),
            "torque_noise": sigma.tolist(), "torque_noise_rule": "stated" if stated else
            f"{NOISE_SHARE:g} x the torque scale (effort limit, else the largest |g|)",
            "t_detect": float(t_detect), "ratio": float(ratio), "false_alarms_per_hour": float(false_alarms),
            "dt": float(dt), "choice": "double pole k0 = K_O = omega",
            "why": f"a contact of {ratio:g}x the threshold crosses it in t_detect / 2"}
