"""Lotfi–Namvar adaptive observer, numpy reference (docs/papers/seed002.md §3.1–3.2, seed 002).

Per channel j (a selected CoM coordinate, pi_j = p_{rows[j]}(q)):
    zhat_{j1}'  = -(lambda_j + alpha_j) zhat_{j1} + zhat_{j2} + zeta_j thetahat_j
                  + (lambda_j + alpha_j) pi_j                                  [S002 (13),(17)]
    zhat_{j2}'  = -lambda_j alpha_j zhat_{j1} + a_j + alpha_j zeta_j thetahat_j + lambda_j alpha_j pi_j
    zeta_j'     = -alpha_j zeta_j + f_{f,j}                                    [S002 (12)]
    thetahat_j' = gamma_j zeta_j (pi_j - zhat_{j1})
    nuhat = zhat2 + zeta thetahat,  qd_hat = lstsq(J_n, nuhat)  (left pseudo-inverse, A2-6)
a = g_o entries of the rows (A2-2). Layouts as in the symbolic family:
x = [zhat1, zhat2, zeta, thetahat] (r each), y = [q (n), f_f (r)], u = tau (unused),
est = [qd_hat (n_o), nuhat (r), thetahat (r)],
p = [alpha, lambda, gamma, thetahat0 (r each), zhat1_from_y0, projection, theta_min, theta_max].

The rows and observable joints are the spec's declared options (codegen.core.options.
NonMinimalOptions), bound by ``configure``; a = g_o entries of the rows, g_o the reference
robot's own gravity vector (the declared one must agree).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._family import bound


class NonMinimal(NamedTuple):
    """Seed 002's non-minimal coordinates on a reference robot (docs/papers/seed002.md §3.1, A2-2).

    Attributes
    ----------
    rows : list of int
        Selected rows of the stacked CoM positions p(q) (dim n), r of them.
    joints : list of int
        Observable joints, n_o of them.
    a : (r,) array
        g_o entries of the rows, m/s^2.
    """

    rows: list
    joints: list
    a: np.ndarray


def configure(robot, options):
    """This family bound to the declared rows and joints (codegen.core.options.NonMinimalOptions).

    Parameters
    ----------
    robot : reference robot with ``com_positions``, ``com_jacobian``, ``gravity_vector``, ``dim``
    options : codegen.core.options.NonMinimalOptions

    Returns
    -------
    family bound to ``nm`` (a ``NonMinimal``)
    """
    if not all(hasattr(options, k) for k in ("rows", "joints", "g_o")):
        raise ValueError(f"lotfi_namvar: options must be NonMinimalOptions (rows, joints, g_o), got {options!r}")
    go = np.asarray(robot.gravity_vector, dtype=float)
    if not np.allclose(options.g_o, go, rtol=1e-9, atol=1e-12):
        raise ValueError(f"lotfi_namvar: declared g_o {list(options.g_o)} differs from the reference robot's {go}")
    rows, joints = list(options.rows), list(options.joints)
    if not (all(0 <= r < robot.dim * robot.n for r in rows) and all(0 <= k < robot.n for k in joints)):
        raise ValueError(f"lotfi_namvar: rows {rows} or joints {joints} out of range for {robot.n} joints")
    return bound(__name__, nm=NonMinimal(rows, joints, np.array([go[r % robot.dim] for r in rows])))


def _split(robot, nm, x, y, p):
    r, n = len(nm.rows), robot.n
    return (r, y[:n], y[n:], x[:r], x[r:2 * r], x[2 * r:3 * r], x[3 * r:],
            p[:r], p[r:2 * r], p[2 * r:3 * r])


def rhs(robot, x, y, u, p, nm):
    """[zhat1'; zhat2'; zeta'; thetahat']  [S002 (12), (13), (17)].

    Parameters
    ----------
    robot : reference robot with CoM kinematics (n joints)
    x : (4r,) array
        [zhat1 (m); zhat2 (m/s); zeta (N s); thetahat (1/kg)].
    y : (n + r,) array
        [q (rad); f_f (N)].
    u : (n,) array
        tau, N m (unused).
    p : (4r + 4,) array
        [alpha; lambda; gamma; thetahat0 (r each); zhat1_from_y0; projection; theta_min;
        theta_max].
    nm : NonMinimal
        The bound rows, joints and a.

    Returns
    -------
    (4r,) array
    """
    r, q, ff, zh1, zh2, zeta, th, al, la, ga = _split(robot, nm, x, y, p)
    pi = robot.com_positions(q)[nm.rows]
    k1, k2 = la + al, la * al
    return np.concatenate([-k1 * zh1 + zh2 + zeta * th + k1 * pi,
                           -k2 * zh1 + nm.a + al * zeta * th + k2 * pi,
                           -al * zeta + ff,
                           ga * zeta * (pi - zh1)])


def output(robot, x, y, u, p, nm):
    """est = [qd_hat (n_o, rad/s); nuhat (r, m/s); thetahat (r)], qd_hat by the left
    pseudo-inverse of J_n (A2-6), from the state ``x`` and the measured q in ``y``; ``robot``,
    ``u`` (unused), ``p`` and ``nm`` as in ``rhs``."""
    r, q, ff, zh1, zh2, zeta, th, al, la, ga = _split(robot, nm, x, y, p)
    nuhat = zh2 + zeta * th
    Jn = robot.com_jacobian(q)[nm.rows][:, nm.joints]
    qd_hat = np.linalg.solve(Jn.T @ Jn, Jn.T @ nuhat)
    return np.concatenate([qd_hat, nuhat, th])


def jump(robot, x, y, p, nm):
    """x+ (4r,): thetahat of the state ``x`` clipped into [theta_min, theta_max] when projection
    = 1 (identity otherwise); ``robot``, ``y`` (unused), ``p`` (projection, theta_min,
    theta_max read from it) and ``nm`` as in ``rhs``."""
    r = len(nm.rows)
    if p[4 * r + 1] == 0.0:
        return np.array(x, dtype=float)
    x = np.array(x, dtype=float)
    th = x[3 * r:]
    x[3 * r:] = th + p[4 * r + 1] * (np.clip(th, p[4 * r + 2], p[4 * r + 3]) - th)
    return x


def init(robot, y0, est0, p, nm):
    """x(0) = [zhat1_from_y0 pi(q0); J_n(q0) qd_hat(0); 0; thetahat0]  (docs/papers/seed002.md §3.2).

    Parameters
    ----------
    robot, p, nm
        As in ``rhs``.
    y0 : (n + r,) array
        [q(0) (rad); f_f(0) (N)].
    est0 : (n_o + 2r,) array
        [qd_hat(0) (rad/s); nuhat(0); thetahat(0)] (only qd_hat(0) is read).

    Returns
    -------
    (4r,) array
    """
    r, n = len(nm.rows), robot.n
    q0 = y0[:n]
    Jn = robot.com_jacobian(q0)[nm.rows][:, nm.joints]
    return np.concatenate([p[4 * r] * robot.com_positions(q0)[nm.rows], Jn @ est0[:len(nm.joints)],
                           np.zeros(r), p[3 * r:4 * r]])


def sizes(robot, nm):
    """{"nx": 4r, "ny": n + r, "nu": n, "nest": n_o + 2r} for ``robot`` (n joints) and ``nm``
    (r rows, n_o joints)."""
    r, n = len(nm.rows), robot.n
    return {"nx": 4 * r, "ny": n + r, "nu": n, "nest": len(nm.joints) + 2 * r}
