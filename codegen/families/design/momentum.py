"""The momentum observer's default gains and thresholds, as rules of measured or stated inputs.

Seen from an external torque tau_ext (and the torque sensor's noise n), the residual r of the
momentum observer fed by the reduced-order velocity observer (gain k0, its model's torque
corrected by r) is, per joint in a linear picture,

    r = K_O k0 / (s^2 + k0 s + K_O k0) (tau_ext - n)

with natural frequency sqrt(K_O k0) and damping sqrt(k0 / K_O) / 2. The design takes damping
1/sqrt(2) (4 % overshoot): k0 = sqrt(2) omega, K_O = omega / sqrt(2), natural frequency omega. A
contact of ``ratio`` times the threshold crosses it at omega t = x, the root of the step response
1 - e^(-x/sqrt 2) (cos(x/sqrt 2) + sin(x/sqrt 2)) = 1 / ratio (x = 1.03 at ratio 3). Every noise
grows with omega, so omega is the smallest that meets the detection time t_detect less SAMPLES
samples (the contact shows in the next sample, the alarm in the one after, one to spare) and
half the contact's own rise t_rise (a force rising linearly acts as a step half-way up), and the
output lag at omega_f = FILTER omega, counted as its delay 1 / omega_f:

    omega = (x + 1 / FILTER) / (t_detect - SAMPLES dt - t_rise / 2)

Threshold: two noises reach r. The torque noise (std sigma_tau per sample at dt) passes through
the same filter, whose noise bandwidth is omega / (2 sqrt 2): sigma_tau^2 dt omega / (2 sqrt 2); the encoder's (std
sigma_q) enters the velocity x2hat = z + k0 q at gain k0 and the residual through K_O M(q) x2hat,
white from sample to sample: (K_O k0 M_jj sigma_q)^2 = (omega^2 M_jj sigma_q)^2, M_jj the largest diagonal inertia over
sampled configurations; the output lag passes omega_f dt / 2 of the white part's variance. |r_j| of a Gaussian r crosses u sigma_r upwards nu0 e^(-u^2 / 2) times
per second each way, nu0 = omega / (2 pi) (Rice's formula for the second-order filter; the
encoder's white part crosses more often, which the log's calibration measures). For a false-alarm
rate R (per hour of motion, over all n joints) the level is

    th0_j = sigma_r,j sqrt(2 ln(2 n nu0 3600 / R)),
    sigma_r,j^2 = sigma_tau,j^2 dt omega / (2 sqrt 2) + (omega^2 M_jj sigma_q)^2 omega_f dt / 2.

A log measures sigma_r and the tail instead (codegen.logs.detect); these are the defaults
before one.
"""
from __future__ import annotations

import math

import numpy as np

from .noise import check_torque_uncertainty, sensor_sigma

RATIO = 3.0              # the contacts the detection time is promised for: 3x the threshold
T_DETECT = 0.02          # s, the detection time asked for
FALSE_ALARMS = 1.0       # per hour of motion, all joints together
NOISE_SHARE = 0.01       # the default torque noise: 1 % of the joint's torque scale
SAMPLES = 3              # samples of the detection time the response does not get
T_RISE = 0.005           # s, a contact's rise to its full force
FILTER = 4.0             # omega_f / omega: the output lag well above the residual's bandwidth

__all__ = ["design_momentum", "crossing_time", "step_response", "threshold_level", "torque_scale", "largest_inertia"]


ZETA = 1.0 / math.sqrt(2.0)      # the damping of the residual's response


def step_response(x, zeta=ZETA):
    """1 - e^(-zeta x) (cos(w x) + zeta sin(w x) / w), w = sqrt(1 - zeta^2): the unit step response
    of omega^2 / (s^2 + 2 zeta omega s + omega^2) at omega t = x."""
    w = math.sqrt(1.0 - zeta * zeta)
    return 1.0 - math.exp(-zeta * x) * (math.cos(w * x) + zeta * math.sin(w * x) / w)


def crossing_time(ratio=RATIO, zeta=ZETA):
    """x = omega t at which the step response (``step_response``, damping ``zeta``) first reaches
    1 / ``ratio``."""
    if not ratio > 1.0:
        raise ValueError(f"ratio must be > 1 (a contact above its threshold), got {ratio!r}")
    lo, hi = 0.0, math.pi / math.sqrt(1.0 - zeta * zeta)      # rising until its first peak
    for _ in range(80):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if step_response(mid, zeta) < 1.0 / ratio else (lo, mid)
    return (lo + hi) / 2


def threshold_level(n, nu0, false_alarms=FALSE_ALARMS):
    """u such that n joints of a Gaussian residual cross +-u sigma together ``false_alarms``
    times an hour, each nu0 (1/s) e^(-u^2/2) times a second each way (Rice)."""
    if not false_alarms > 0:
        raise ValueError(f"false_alarms must be a positive rate per hour, got {false_alarms!r}")
    arg = 2.0 * n * nu0 * 3600.0 / false_alarms
    return math.sqrt(2.0 * math.log(arg)) if arg > 1.0 else 0.0


def torque_scale(robot, count=64):
    """(n,) the torque scale of each joint of ``robot``, N m: the declared effort limit, or where none is
    declared the largest |g_j(q)| over ``count`` sampled configurations (at least 1 N m)."""
    eff = np.asarray(robot.effort_limit, dtype=float)
    if np.all(np.isfinite(eff)):
        return eff
    Q = robot.sample_configurations(count, seed=0)
    g = np.abs(np.column_stack([np.asarray(robot.g(q)).reshape(-1) for q in Q]))
    return np.where(np.isfinite(eff), eff, np.maximum(g.max(axis=1), 1.0))


def largest_inertia(robot, count=64):
    """(n,) max over ``count`` sampled configurations of ``robot`` of M_jj(q) (kg m^2)."""
    Q = robot.sample_configurations(count, seed=0)
    return np.max([np.diag(np.asarray(robot.M(q))) for q in Q], axis=0)


def design_momentum(robot, dt, torque_noise=None, t_detect=T_DETECT, false_alarms=FALSE_ALARMS, ratio=RATIO,
                    noise=None, quantization=None, t_rise=T_RISE):
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
    noise, quantization : float, optional
        The encoder's noise std and step (rad); both None: the default encoder
        (codegen.families.design.noise.sensor_sigma).
    t_rise : float
        A contact's rise to its full force (s).

    Returns
    -------
    dict
        omega (1/s), k0 = sqrt(2) omega, K_O = omega / sqrt(2), omega_f = FILTER omega, th0 (n,) N m, th1 (n,) N m s/rad (0: no velocity term
        until a log measures one), sigma_r (n,) N m, level u, nu0 (1/s), and the inputs.
    """
    n = robot.n
    budget = t_detect - SAMPLES * dt - t_rise / 2 if isinstance(t_detect, (int, float)) else 0.0
    if not budget > SAMPLES * dt:
        raise ValueError(f"t_detect must be a time (s) above {2 * SAMPLES} samples and half the contact's rise "
                         f"({2 * SAMPLES * dt + t_rise / 2:g} s), got {t_detect!r}")
    stated = torque_noise is not None
    sigma = (NOISE_SHARE * torque_scale(robot) if not stated else
             check_torque_uncertainty(torque_noise, n, robot.joint_names))
    x = crossing_time(ratio)
    omega = (x + 1.0 / FILTER) / budget
    sigma_q, M = sensor_sigma(noise, quantization), largest_inertia(robot)
    omega_f = FILTER * omega
    white = min(1.0, omega_f * dt / (2.0 - min(omega_f * dt, 1.0)))      # a first-order lag's share of white noise
    sigma_r = np.sqrt(sigma ** 2 * dt * omega / (4.0 * ZETA) + (omega ** 2 * M * sigma_q) ** 2 * white)
    nu0 = omega / (2.0 * math.pi)
    u = threshold_level(n, nu0, false_alarms)
    return {"omega": float(omega), "k0": float(omega / ZETA), "K_O": float(omega * ZETA), "omega_f": float(omega_f),
            "th0": (u * sigma_r).tolist(), "th1": [0.0] * n, "sigma_r": sigma_r.tolist(),
            "level": float(u), "nu0": float(nu0), "crossing": float(x),
            "torque_noise": sigma.tolist(), "torque_noise_rule": "stated" if stated else
            f"{NOISE_SHARE:g} x the torque scale (effort limit, else the largest |g|)",
            "sigma_q": float(sigma_q), "M_jj": M.tolist(), "t_detect": float(t_detect), "t_rise": float(t_rise), "ratio": float(ratio), "false_alarms_per_hour": float(false_alarms),
            "dt": float(dt), "choice": "k0 = sqrt(2) omega, K_O = omega / sqrt(2) (damping 1/sqrt 2)",
            "why": f"the slowest in which a contact of {ratio:g}x the threshold crosses it within t_detect - {SAMPLES} dt "
                   f"- t_rise / 2"}
