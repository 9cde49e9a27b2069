"""Lotfi–Namvar adaptive observer, numpy reference (SPEC §3.1–3.2, seed 002).

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

The rows and observable joints come from ``robot.source["nonminimal"]`` (plain data the spec
adds to its robot source); without it: every row of J_p that is not identically zero and every
joint whose column is not, found here by sampling the reference robot's own J_p.
"""
from __future__ import annotations

import numpy as np

_TOL = 1e-9


def _default_rows(robot, count=64, seed=0):
    rng = np.random.default_rng(seed)
    J = np.array([robot.com_jacobian(q) for q in rng.uniform(-np.pi, np.pi, (count, robot.n))])
    scale = max(1.0, np.abs(J).max())
    masses = np.repeat(np.asarray(robot.masses, float), robot.dim)
    rows = [r for r in range(J.shape[1]) if np.abs(J[:, r]).max() > _TOL * scale and masses[r] > _TOL]
    joints = [k for k in range(robot.n) if np.abs(J[:, rows, k]).max() > _TOL * scale]
    return rows, joints


def _coords(robot):
    """(rows, joints, a) of the robot's non-minimal model, cached on the robot."""
    c = getattr(robot, "_nonminimal_cache", None)
    if c is None:
        nm = (getattr(robot, "source", None) or {}).get("nonminimal")
        rows, joints = (nm["rows"], nm["joints"]) if nm else _default_rows(robot)
        go = np.asarray(robot.gravity_vector, float)
        a = np.array([go[r % robot.dim] for r in rows])
        c = robot._nonminimal_cache = (list(rows), list(joints), a)
    return c


def _split(robot, x, y, p):
    rows, joints, a = _coords(robot)
    r, n = len(rows), robot.n
    q = y[:n]
    return (rows, joints, a, r, q, y[n:], x[:r], x[r:2 * r], x[2 * r:3 * r], x[3 * r:],
            p[:r], p[r:2 * r], p[2 * r:3 * r])


def rhs(robot, x, y, u, p):
    rows, joints, a, r, q, ff, zh1, zh2, zeta, th, al, la, ga = _split(robot, x, y, p)
    pi = robot.com_positions(q)[rows]
    k1, k2 = la + al, la * al
    return np.concatenate([-k1 * zh1 + zh2 + zeta * th + k1 * pi,
                           -k2 * zh1 + a + al * zeta * th + k2 * pi,
                           -al * zeta + ff,
                           ga * zeta * (pi - zh1)])


def output(robot, x, y, u, p):
    rows, joints, a, r, q, ff, zh1, zh2, zeta, th, al, la, ga = _split(robot, x, y, p)
    nuhat = zh2 + zeta * th
    Jn = robot.com_jacobian(q)[rows][:, joints]
    qd_hat = np.linalg.solve(Jn.T @ Jn, Jn.T @ nuhat)
    return np.concatenate([qd_hat, nuhat, th])


def jump(robot, x, y, p):
    """thetahat clipped into [theta_min, theta_max] when projection = 1 (identity otherwise)."""
    r = len(_coords(robot)[0])
    if p[4 * r + 1] == 0.0:
        return np.array(x, dtype=float)
    x = np.array(x, dtype=float)
    th = x[3 * r:]
    x[3 * r:] = th + p[4 * r + 1] * (np.clip(th, p[4 * r + 2], p[4 * r + 3]) - th)
    return x


def init(robot, y0, est0, p):
    rows, joints, a = _coords(robot)
    r, n = len(rows), robot.n
    q0 = y0[:n]
    Jn = robot.com_jacobian(q0)[rows][:, joints]
    return np.concatenate([p[4 * r] * robot.com_positions(q0)[rows], Jn @ est0[:len(joints)],
                           np.zeros(r), p[3 * r:4 * r]])


def sizes(robot):
    rows, joints, _ = _coords(robot)
    r, n = len(rows), robot.n
    return {"nx": 4 * r, "ny": n + r, "nu": n, "nest": len(joints) + 2 * r}
