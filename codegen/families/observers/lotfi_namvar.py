"""Adaptive velocity observer of Lotfi & Namvar on the non-minimal model (seed 002, docs/papers/seed002.md §3.2).

Per selected CoM coordinate j (channel), states zhat_{j1}, zhat_{j2}, zeta_j, thetahat_j:

    zhat_{j1}'  = -(lambda_j + alpha_j) zhat_{j1} + zhat_{j2} + zeta_j thetahat_j
                  + (lambda_j + alpha_j) pi_j                                  [S002 (13),(17)]
    zhat_{j2}'  = -lambda_j alpha_j zhat_{j1} + a_j + alpha_j zeta_j thetahat_j
                  + lambda_j alpha_j pi_j                                      [S002 (13),(17)]
    zeta_j'     = -alpha_j zeta_j + f_{f,j},      zeta_j(0) = 0                [S002 (12)]
    thetahat_j' = gamma_j zeta_j (pi_j - zhat_{j1})                            [S002 (13)]
    nuhat_j     = zhat_{j2} + zeta_j thetahat_j                                [S002 (13)]
    qd_hat      = (J_n^T J_n)^{-1} J_n^T nuhat     (a solve, never an inverse)  [S002 §IV], A2-6

with pi = rows of the link CoM positions p(q) and a_j the g_o entry of row j (A2-2).

Vectors (r channels, n_o observable joints, see ``_nonminimal``):
  x   = [zhat1 (r), zhat2 (r), zeta (r), thetahat (r)]
  y   = [q (n), f_f (r)]                     measured joints and CoM forces
  u   = tau (n)                              unused (kept so every observer takes the torque)
  est = [qd_hat (n_o), nuhat (r), thetahat (r)]
  p   = [alpha (r), lambda (r), gamma (r), thetahat0 (r), zhat1_from_y0, projection,
         theta_min, theta_max]

init: zhat1(0) = zhat1_from_y0 pi(q0) (0: Table II's zhat(0) = 0), zhat2(0) = J_n(q0) est0[qd],
zeta(0) = 0, thetahat(0) = thetahat0.
Projection [S002 §IV-A; ASSUMPTION bounds 0.05..20, off by default, docs/papers/seed002.md §3.2]: when
projection = 1 the jump map clips thetahat into [theta_min, theta_max] before every step
(a clipped, not smooth, projection: the box is invariant exactly at every sample).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...core.options import InputRanges, NonMinimalOptions
from ...core.spec import ObserverSpec
from ._nonminimal import nonminimal  # public: p rows, J_n and the CoM forces f_f of a robot (docs/papers/seed002.md §3.1)

# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed002_2r"}, {"robot": "seed002_2r", "design": {"rows": [1, 2, 3]}}]

# [S002 Table II]: alpha, lambda, gamma, thetahat(0) for j = 1..4 (zhat(0) = 0, zeta(0) = 0)
TABLE_II = {"alpha": [30.0, 30.0, 30.0, 30.0], "lambda": [12.0, 12.0, 12.0, 12.0],
            "gamma": [200.0, 250.0, 250.0, 100.0], "thetahat0": [3.0, 3.0, 0.5, 0.5]}
ADAPTATION_RATE = 500.0  # 1/s, the default gamma_j of other robots (see default_gains)


def default_gains(nm):
    """Gains per channel of the NonMinimal coordinates ``nm`` (observers/_nonminimal.py).

    Table II for seed002_2r with its four rows; otherwise, per channel [ASSUMPTION]:
    alpha = 30, lambda = 12 (Table II), thetahat0 = 2 theta_nominal (100 % error, as Table II's
    link-2 guess), and gamma = ADAPTATION_RATE lambda / zeta_nom^2 with zeta_nom = m g / alpha
    the static-load level of zeta, so that the linearised parameter-error rate
    gamma zeta^2 / lambda is about ADAPTATION_RATE (1/s). Returns a dict of (r,) arrays:
    alpha, lambda, gamma, thetahat0."""
    if nm.robot.name == "seed002_2r" and nm.rows == [0, 1, 2, 3]:
        return {k: np.array(v) for k, v in TABLE_II.items()}
    r = nm.r
    alpha, lam = np.full(r, 30.0), np.full(r, 12.0)
    g = max(float(np.linalg.norm(nm.g_o)), 1.0)
    zeta_nom = (g / nm.theta) / alpha
    return {"alpha": alpha, "lambda": lam, "gamma": ADAPTATION_RATE * lam / zeta_nom ** 2,
            "thetahat0": 2.0 * nm.theta}


def build(robot, rows="all", alpha=None, lam=None, gamma=None, thetahat0=None,
          zhat1_from_y0=None, projection=False, theta_min=0.05, theta_max=20.0):
    """Lotfi–Namvar observer for ``robot`` (docs/papers/seed002.md §3.2)  [S002 (12), (13), (17)].

    Gains are per channel (scalars broadcast); None takes ``default_gains``.

    Parameters
    ----------
    robot : models.RobotModel
        With CoM kinematics (``com_positions``, ``dim``) and link masses.
    rows : "all", int or list of int
        "all" (default, the seed's J_n = J_p), an int k (k best-conditioned rows) or a list of
        row indices into p (see ``_nonminimal.nonminimal``); r channels.
    alpha, lam : (r,) array_like or float, optional
        Filter gains alpha_j and lambda_j, 1/s.
    gamma : (r,) array_like or float, optional
        Adaptation gains gamma_j, 1/(kg^2 m^2).
    thetahat0 : (r,) array_like or float, optional
        Initial estimates of theta_j = 1/m_link, 1/kg.
    zhat1_from_y0 : float, optional
        zhat1(0) = zhat1_from_y0 pi(q0); None: 0 for seed002_2r (Table II), 1 otherwise.
    projection : bool
        Clip thetahat into [theta_min, theta_max] before every step (the jump map).
    theta_min, theta_max : float
        Projection box, 1/kg [ASSUMPTION 0.05..20, docs/papers/seed002.md §3.2].

    Returns
    -------
    codegen.core.spec.ObserverSpec
        Family ``lotfi_namvar``, vectors as in the module docstring; the gains are the
        defaults of its runtime parameters p.
    """
    nm = nonminimal(robot, rows)
    r, n, no = nm.r, robot.n, len(nm.joints)
    gains = default_gains(nm)
    for key, val in (("alpha", alpha), ("lambda", lam), ("gamma", gamma), ("thetahat0", thetahat0)):
        if val is not None:
            v = np.broadcast_to(np.asarray(val, float), (r,)).copy()
            gains[key] = v
    if zhat1_from_y0 is None:
        zhat1_from_y0 = 0.0 if robot.name == "seed002_2r" else 1.0
    if not (np.all(gains["alpha"] > 0) and np.all(gains["lambda"] > 0) and np.all(gains["gamma"] > 0)):
        raise ValueError(f"alpha, lambda, gamma must be positive, got {gains}")

    x = ca.SX.sym("x", 4 * r)
    y, u = ca.SX.sym("y", n + r), ca.SX.sym("u", n)
    p = ca.SX.sym("p", 4 * r + 4)
    zh1, zh2, zeta, th = x[:r], x[r:2 * r], x[2 * r:3 * r], x[3 * r:]
    al, la, ga = p[:r], p[r:2 * r], p[2 * r:3 * r]
    th0, from_y0, proj, th_lo, th_hi = p[3 * r:4 * r], p[4 * r], p[4 * r + 1], p[4 * r + 2], p[4 * r + 3]
    q, ff = y[:n], y[n:]
    pi = nm.pi(q)
    a = ca.DM(nm.a)
    k1, k2 = la + al, la * al                                           # k_j = [lambda+alpha, lambda alpha]
    ztheta = zeta * th
    xdot = ca.vertcat(
        -k1 * zh1 + zh2 + ztheta + k1 * pi,                             # [S002 (13)]
        -k2 * zh1 + a + al * ztheta + k2 * pi,                          # [S002 (13)]
        -al * zeta + ff,                                                # [S002 (12)]
        ga * zeta * (pi - zh1))                                         # [S002 (13)]
    nuhat = zh2 + ztheta
    Jn = nm.jacobian(q)
    qd_hat = ca.solve(ca.mtimes(Jn.T, Jn), ca.mtimes(Jn.T, nuhat))     # left pseudo-inverse, A2-6
    est = ca.vertcat(qd_hat, nuhat, th)

    # projection by clipping (jump map applied before every step); exact identity when off
    th_clip = ca.fmin(ca.fmax(th, th_lo), th_hi)
    xj = ca.vertcat(zh1, zh2, zeta, th + proj * (th_clip - th))

    y0, est0 = ca.SX.sym("y0", n + r), ca.SX.sym("est0", no + 2 * r)
    q0 = y0[:n]
    x0 = ca.vertcat(from_y0 * nm.pi(q0), ca.mtimes(nm.jacobian(q0), est0[:no]),
                    ca.DM.zeros(r), th0)

    ch = nm.row_names
    jn = nm.joint_names
    p_default = np.concatenate([gains["alpha"], gains["lambda"], gains["gamma"], gains["thetahat0"],
                                [float(zhat1_from_y0), 1.0 if projection else 0.0,
                                 float(theta_min), float(theta_max)]])
    mass = 1.0 / nm.theta
    return ObserverSpec(
        family="lotfi_namvar", robot=robot,
        x_names=[f"{s}_{c}" for s in ("zhat1", "zhat2", "zeta", "thetahat") for c in ch],
        y_names=[f"q_{j}" for j in robot.joint_names] + [f"f_f_{c}" for c in ch],
        u_names=[f"tau_{j}" for j in robot.joint_names],
        p_names=[f"{s}_{c}" for s in ("alpha", "lambda", "gamma", "thetahat0") for c in ch]
        + ["zhat1_from_y0", "projection", "theta_min", "theta_max"],
        est_names=[f"qd_hat_{j}" for j in jn] + [f"nuhat_{c}" for c in ch]
        + [f"thetahat_{c}" for c in ch],
        p_default=p_default,
        rhs=ca.Function("rhs", [x, y, u, p], [xdot]),
        output=ca.Function("output", [x, y, u, p], [est]),
        init=ca.Function("init", [y0, est0, p], [x0]),
        jump=ca.Function("jump", [x, y, p], [xj]),
        options=NonMinimalOptions(**nm.source),
        # cross-check inputs: f_f = m (acc - g_o) with acc ~ N(0, 10^2); zhat1 = pi(q) + N(0, 0.1^2),
        # zhat2 ~ N(0, 1), zeta ~ f_f / alpha (alpha = 30, Table II), thetahat in [0.2, 3] theta;
        # u is unused
        inputs=InputRanges(y_extra=tuple(zip(-mass * nm.a, 10.0 * mass)), u="plain", u_scale=10.0,
                           est_scale=0.0, init_p=(("zhat1_from_y0", 1.0),),
                           x_scale=(0.1,) * r + (1.0,) * r + (0.0,) * (2 * r),
                           x_normal=tuple((f"zeta_{c}", -m * a / 30.0, 10.0 * m / 30.0)
                                          for c, m, a in zip(ch, mass, nm.a)),
                           x_uniform=tuple((f"thetahat_{c}", 0.2 * t, 3.0 * t) for c, t in zip(ch, nm.theta))),
        design={"row_names": ch, "observable_joints": jn, "theta_true": nm.theta.tolist(),
                "a": nm.a.tolist()},
    )

