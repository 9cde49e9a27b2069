"""Steady-state Kalman-Bucy velocity observer on a constant-jerk model with the model's
acceleration as a friction-aware measurement (codegen.families.observers.kalman_model), numpy.

x = [q_hat; v_hat; a_hat; j_hat; c] (4n + 1), the clock c' = 1, omega = omega0 while c < t_switch, then
omega; e = y - q_hat, block b = 1..4 of x' (derivative b - 1):

    x'_b = x_(b+1) + omega^b g_b e                    (x_5 = 0; g the Butterworth-4 coefficients
                                                        2.6131259, 3.4142136, 2.6131259, 1)
  model variant, once c >= t_switch (omega the steady one), with s = erf(v_hat / (sqrt 2 width)),
  at the configuration y_cfg:
    z     = tau - nle(y_cfg, v_hat) - F v_hat - b - Fc s
    D     = diag(sigma_tau^2 + Fc^2 (1 - s^2)) / (sigma_q^2 omega^4)
    r_k   = M (D + p_k M M)^-1 [M e, z - M a_hat]       (= (C_hat + p_k)^-1 [e, e_a])
    x'_b += sum_k p_k (omega^b cq_bk r_k[:, 0] + omega^(b-2) ca_bk r_k[:, 1])

y = q (n, rad), u = tau (n, N m), est = v_hat (n, rad/s). p as the spec's p_names: [omega,
omega0, t_switch] and, model variant, [sigma_q, width, sigma_tau (n), coulomb (n), offset (n),
pole (K), cq (4K, b-major), ca (4K, b-major)]. The variant is the spec's declared option (VariantOptions).
"""
from __future__ import annotations

import math

import numpy as np

from ._family import bound

VARIANTS = ("kinematic", "model")


def butterworth4():
    """(g1, g2, g3, g4): the coefficients of s^4 + g1 s^3 + g2 s^2 + g3 s + g4, the normalised
    Butterworth polynomial of order 4, (s^2 + 2 sin(pi/8) s + 1)(s^2 + 2 cos(pi/8) s + 1):
    g1 = g3 = 2 (sin(pi/8) + cos(pi/8)), g2 = 2 + 4 sin(pi/8) cos(pi/8), g4 = 1."""
    a, b = 2 * math.sin(math.pi / 8), 2 * math.cos(math.pi / 8)
    return np.array([a + b, 2 + a * b, a + b, 1.0])


def configure(robot, options):
    """This family bound to the variant its spec declares.

    Parameters
    ----------
    robot : reference robot
    options : codegen.core.options.VariantOptions
        ``variant`` "kinematic" or "model".

    Returns
    -------
    family bound to ``variant``
    """
    variant = getattr(options, "variant", None)
    if variant not in VARIANTS:
        raise ValueError(f"options: unknown kalman_model variant {variant!r} (one of {VARIANTS})")
    return bound(__name__, variant=variant)


def _blocks(x, n):
    x = np.asarray(x, dtype=float)
    return x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n:4 * n], float(x[4 * n])


def _poles(p, n):
    """K of a model-variant parameter vector of length 5 + 3n + 9K."""
    K, rem = divmod(len(p) - 5 - 3 * n, 9)
    if rem or K < 1:
        raise ValueError(f"p: {len(p)} parameters is not 5 + 3n + 9K for n = {n}")
    return K


def rhs_split(robot, x, y_cfg, y, u, p, variant):
    """x' (4n + 1,) of the module docstring: ``rhs_model`` with the model's gain structure
    ``model`` at the configuration y_cfg (none in the kinematic variant).

    Parameters
    ----------
    robot : reference robot (n joints): M, nle, F
    x : (4n + 1,) array
        [q_hat; v_hat; a_hat; j_hat; clock].
    y_cfg : (n,) array
        Configuration of the model (rad).
    y : (n,) array
        Measured q of the output injection (rad).
    u : (n,) array
        Measured tau (N m).
    p : array
        The spec's parameters (module docstring).
    variant : {"kinematic", "model"}
        As bound by ``configure``.
    """
    m = model(robot, x, y_cfg, y, u, p) if variant == "model" else None
    return rhs_model(robot, x, y, u, p, m)


def rhs_model(robot, x, y, u, p, m):
    """x' (4n + 1,): the kinematic blocks x'_b = x_(b+1) + omega^b g_b e plus, with the gain
    structure ``m`` (``model``; None: none), the model's injection G_e[b] e + G_a[b] (a - a_hat)
    into block b, a = a_m + M^-1 (F (v_m - v_hat) + Fc (s(v_m) - s(v_hat))): the model's
    acceleration at m's velocity v_m with its friction terms at this v_hat; the clock c' = 1.

    Parameters
    ----------
    robot : reference robot (n joints)
    x, y, u, p
        As in ``rhs_split``.
    m : tuple or None
        ``model``'s gain matrices and acceleration, or None (the kinematic flow).
    """
    n = robot.n
    qh, vh, ah, jh, _ = _blocks(x, n)
    p = np.asarray(p, dtype=float)
    w = _omega(x, p, n)
    g = butterworth4()
    e = np.asarray(y, float) - qh
    out = [vh + w * g[0] * e, ah + w ** 2 * g[1] * e, jh + w ** 3 * g[2] * e, w ** 4 * g[3] * e]
    if m is not None:
        G_e, G_a, a_m, M, v_m = m
        fc = p[5 + n:5 + 2 * n]
        a = a_m + np.linalg.solve(M, robot.F @ (v_m - vh) + fc * (_sign(v_m, p) - _sign(vh, p)))
        out = [o + G_e[b] @ e + G_a[b] @ (a - ah) for b, o in enumerate(out)]
    return np.concatenate(out + [[1.0]])


def _sign(v, p):
    """erf(v / (sqrt 2 width)) per joint, the mean of sign(v) for v ~ N(v, width^2); p[4] = width."""
    return np.array([math.erf(x / (math.sqrt(2.0) * float(p[4]))) for x in v])


def model(robot, x, y_cfg, y, u, p):
    """The model's gain structure at the configuration ``y_cfg`` and the velocity v_hat of x,
    once the clock x[4n] >= t_switch (None before: the kinematic flow): (G_e (4, n, n),
    G_a (4, n, n), a_m (n,), M (n, n), v_hat (n,)) with

        G_e[b] = sum_k p_k omega^b cq_bk (C_hat + p_k I)^-1,   G_a[b] = sum_k p_k omega^(b-2) ca_bk (C_hat + p_k I)^-1,
        (C_hat + p_k I)^-1 = M (D + p_k M M)^-1 M   (a dense solve per pole),   a_m = M^-1 z

    (module docstring); robot, x, y, u, p as in ``rhs_split`` (y unused: the injection takes
    the position error in ``rhs_model``)."""
    n = robot.n
    _, vh, _, _, clock = _blocks(x, n)
    p = np.asarray(p, dtype=float)
    if clock < float(p[2]):
        return None
    w = float(p[0])
    K = _poles(p, n)
    sig_q = p[3]
    st, fc, off = p[5:5 + n], p[5 + n:5 + 2 * n], p[5 + 2 * n:5 + 3 * n]
    base = 5 + 3 * n
    pk = p[base:base + K]
    cq = p[base + K:base + 5 * K].reshape(4, K)
    ca = p[base + 5 * K:base + 9 * K].reshape(4, K)
    M = robot.M(y_cfg)
    s = _sign(vh, p)
    z = np.asarray(u, float) - robot.nle(y_cfg, vh) - robot.F @ vh - off - fc * s
    D = np.diag((st ** 2 + fc ** 2 * (1 - s ** 2)) / (sig_q ** 2 * w ** 4))
    M2 = M @ M
    G_e, G_a = np.zeros((4, n, n)), np.zeros((4, n, n))
    for k in range(K):
        R = M @ np.linalg.solve(D + pk[k] * M2, M)
        for b in range(4):
            G_e[b] += pk[k] * w ** (b + 1) * cq[b, k] * R
            G_a[b] += pk[k] * w ** (b - 1) * ca[b, k] * R
    return G_e, G_a, np.linalg.solve(M, z), M, vh.copy()


def _omega(x, p, n):
    """omega0 while the clock x[4n] < t_switch, else omega (p = [omega, omega0, t_switch, ...])."""
    return float(p[1]) if float(x[4 * n]) < float(p[2]) else float(p[0])


def rhs(robot, x, y, u, p, variant):
    """The flow: ``rhs_split`` with the model at y itself.

    Parameters
    ----------
    robot, x, y, u, p, variant
        As in ``rhs_split`` (y also the model's configuration).
    """
    return rhs_split(robot, x, y, y, u, p, variant)


def output(robot, x, y, u, p):
    """v_hat (n,) rad/s.

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (4n + 1,) array
        The state.
    y, u, p
        Measurement (rad), torque (N m) and parameters: unused.
    """
    return _blocks(x, robot.n)[1].copy()


def rate(robot, x, p):
    """The gain rate omega_s g1 of q_hat' = [... + omega_s g1 y] - omega_s g1 q_hat (integrated
    by etdrk4), omega_s the bandwidth at the clock x[4n]; robot, x and p as in ``rhs``."""
    return _omega(x, p, robot.n) * butterworth4()[0]


def rate_states(robot):
    """0/1 per state (4n + 1,) of ``robot``: the linear gain term acts on q_hat."""
    n = robot.n
    return np.concatenate([np.ones(n), np.zeros(3 * n + 1)])


def init(robot, y0, est0, p):
    """x(0) = [y(0); est0; 0; 0; 0] (4n + 1,): the clock at 0.

    Parameters
    ----------
    robot : reference robot (n joints)
    y0 : (n,) array
        First measurement (rad).
    est0 : (n,) array
        Initial velocity estimate (rad/s).
    p : array
        Parameters (unused).
    """
    n = robot.n
    return np.concatenate([np.asarray(y0, float), np.asarray(est0, float), np.zeros(2 * n + 1)])


def sizes(robot):
    """{"nx": 4n + 1, "ny": n, "nu": n, "nest": n}, n the joints of ``robot``."""
    n = robot.n
    return {"nx": 4 * n + 1, "ny": n, "nu": n, "nest": n}
