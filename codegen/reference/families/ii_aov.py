"""Reconstructed Astolfi-Ortega-Venkatraman I&I observer (docs/papers/seed003.md §5 [DERIVED]), numpy only.

    M^{-1} = T T^T (T lower),  T^{-1} = T^T M,  dT/dq_k = T Phi(T^{-1} d(M^{-1})/dq_k T^{-T})
        (Phi: lower triangle with half diagonal; from d(T T^T) = d(M^{-1}), [DERIVED])
    S(q, b)  = -T^T M sum_k dT/dq_k (T b)_k - T^T C(q, T b) T
    Hbar_i(q, p) = k1 T^{-1} e_i - T^T M dT/dq_i p - T^T C(q, e_i) T p
    beta = sum_i int_0^{y_i} Hbar_i([qhat with sigma at i], phat) d sigma (Gauss-Legendre, N nodes)
    dbeta/dq exact; dbeta/dphat: Hbar is linear in p; dbeta/dqhat: dHbar_i/dq_j by the
    complex step Im(Hbar_i(q + 1e-30 i e_j)) / 1e-30 (exact to round-off, no subtraction), which
    needs a robot whose M, C, dMw_dq accept complex q: the closed-form robots. A pinocchio robot
    would need second derivatives of M, which pinocchio's Python API does not give: not supported.

    f     = S(y, pbh) pbh + T^T (u - g(y) - tau_f(T pbh)),   pbh = xi + beta  (tau_f: the friction)
    qhat' = T pbh - psi1 (qhat - y);   phat' = f - psi2 (phat - pbh)
    xi'   = f - dbeta/dq T pbh - dbeta/dqhat qhat' - dbeta/dphat phat'
    r'    = -(k1/4)(r - c_r) + (r/k1)(||Delta_q T||_F^2 + ||Delta_p T||_F^2)
    Delta_p T = Cbar(y, pbh - phat) (column k = S(y, T e_k)(pbh - phat)); Delta_q T = (Hbar(y, phat) - dbeta/dq) T
    psi1 = k2 + (r^2/2)||T||^2 + (r^2/k1)||T||^2 ||Deltabar_q||^2
    psi2 = k3 + (r^2/2)||dbeta/dq T||^2 + (r^2/k1)||T||^2 deltabar_p^2
    Deltabar_q,ji = k1 a_ji + sum_m |phat_m| b_jim
p = [k1, k2, k3, c_r, deltabar_p, r0, a (n^2 row-major), b (n^3, j,i,m)]; est = [T phat; T pbh].
"""
from __future__ import annotations

import numpy as np

from ._family import bound
from ..robots.urdf import UrdfRobot
from . import ii_speed
from .ii_speed import DEFAULT_N, column_nodes, quadrature, sizes  # noqa: F401  (same sizes)

SCALARS = ("k1", "k2", "k3", "c_r", "deltabar_p", "r0")
_H = 1e-30


def params(p, n):
    """(scalars dict, a (n, n), b (n, n, n)) of p = [SCALARS, a, b] (reference/ii_speed.params)."""
    return ii_speed.params(p, n, SCALARS)


def _chol_lower(A):
    """Cholesky without conjugation (analytic in the entries, so complex steps pass through)."""
    n = A.shape[0]
    L = np.zeros_like(A)
    for j in range(n):
        L[j, j] = np.sqrt(A[j, j] - np.sum(L[j, :j] * L[j, :j]))
        for i in range(j + 1, n):
            L[i, j] = (A[i, j] - np.sum(L[i, :j] * L[j, :j])) / L[j, j]
    return L


def _phi(X):
    """Lower triangle of X with half its diagonal."""
    return np.tril(X, -1) + 0.5 * np.diag(np.diag(X))


def kinematics(robot, q):
    """M^{-1} = T T^T (T lower) and dT/dq_k = T Phi(T^{-1} d(M^{-1})/dq_k T^{-T})  (docs/papers/seed003.md §5 [DERIVED]).

    Parameters
    ----------
    robot : closed-form reference robot (n joints; M, C and dMw_dq accept complex q)
    q : (n,) array, real or complex
        rad.

    Returns
    -------
    M, T, Tinv : (n, n) arrays
    dT : list of n (n, n) arrays
    """
    if not hasattr(robot, "dMw_dq") or isinstance(robot, UrdfRobot):
        raise NotImplementedError("the AOV reference needs closed-form (complex-capable) M and C; "
                                  "pinocchio robots are not supported (no second derivatives of M)")
    n = robot.n
    Mq = robot.M(q)
    Minv = np.linalg.inv(Mq)
    T = _chol_lower(Minv)
    Tinv = T.T @ Mq
    E = np.eye(n)
    dT = []
    for k in range(n):
        dM = np.column_stack([robot.dMw_dq(q, E[c])[:, k] for c in range(n)])
        dT.append(T @ _phi(Tinv @ (-Minv @ dM @ Minv) @ Tinv.T))
    return Mq, T, Tinv, dT


def S(robot, q, b):
    """S(q, b) = -T^T M sum_k dT/dq_k (T b)_k - T^T C(q, T b) T  (docs/papers/seed003.md §5) (n, n), skew-symmetric;
    ``robot`` as in ``kinematics``, q (n,) rad, b (n,)."""
    Mq, T, _, dT = kinematics(robot, q)
    Tb = T @ b
    return -T.T @ Mq @ sum(dT[k] * Tb[k] for k in range(robot.n)) - T.T @ robot.C(q, Tb) @ T


def hbar_column(robot, q, p, k1, i):
    """Hbar_i(q, p) = k1 T^{-1} e_i - T^T M dT/dq_i p - T^T C(q, e_i) T p  (docs/papers/seed003.md §5) (n,);
    ``robot`` as in ``kinematics``, q (n,) rad (complex allowed), p (n,) the momentum-like
    estimate, k1 (1/s), i the column."""
    Mq, T, Tinv, dT = kinematics(robot, q)
    e = np.zeros(robot.n)
    e[i] = 1.0
    return k1 * Tinv[:, i] - T.T @ Mq @ dT[i] @ p - T.T @ robot.C(q, e) @ T @ p


def beta_and_derivatives(robot, y, qhat, phat, k1, N, derivatives=True, periodic=None, N_period=None):
    """beta = sum_i int_0^{y_i} Hbar_i and its derivatives (docs/papers/seed003.md §5 [DERIVED]).

    Parameters
    ----------
    robot : closed-form reference robot (n joints)
    y : (n,) array
        q, rad.
    qhat : (n,) array
        rad.
    phat : (n,) array
    k1 : float
        1/s.
    N, derivatives, periodic, N_period
        As in reference/ii_speed.py ``beta_and_derivatives`` (nodes by ``column_nodes``).

    Returns
    -------
    beta : (n,) array
    dbdq, dbdqhat, dbdphat : (n, n) arrays
        dbeta/dq (exact), dbeta/dqhat (complex step), dbeta/dphat (exact).
    """
    n = robot.n
    periodic = [False] * n if periodic is None else periodic
    beta = np.zeros(n)
    dqh, dph, dy = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    for i in range(n):
        z = np.array(qhat, dtype=float)
        for sk, h in column_nodes(y[i], N, periodic[i], N_period):
            z[i] = sk
            beta += h * hbar_column(robot, z, phat, k1, i)
            if derivatives:
                for j in range(n):
                    if j != i:
                        zc = z.astype(complex)
                        zc[j] += 1j * _H
                        dqh[:, j] += h * np.imag(hbar_column(robot, zc, phat, k1, i)) / _H
                Mq, T, _, dT = kinematics(robot, z)
                e = np.zeros(n)
                e[i] = 1.0
                dph += h * (-T.T @ Mq @ dT[i] - T.T @ robot.C(z, e) @ T)
        z[i] = y[i]
        dy[:, i] = hbar_column(robot, z, phat, k1, i)
    return beta, dy, dqh, dph


def rhs(robot, x, y, u, p, N=None, periodic=None, N_period=None):
    """[xi'; qhat'; phat'; r'] (docs/papers/seed003.md §5, module docstring).

    Parameters
    ----------
    robot : closed-form reference robot (n joints)
    x : (3n + 1,) array
        [xi; qhat (rad); phat; r].
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m.
    p : (6 + n^2 + n^3,) array
        See ``params``.
    N, periodic, N_period
        The quadrature (N None: DEFAULT_N).

    Returns
    -------
    (3n + 1,) array
    """
    n = robot.n
    s, a, b = params(p, n)
    k1 = s["k1"]
    xi, qhat, phat, r = x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n]
    beta, dbdq, dqh, dph = beta_and_derivatives(robot, y, qhat, phat, k1, N or DEFAULT_N, True, periodic,
                                                   N_period)
    pbh = xi + beta
    _, T, _, _ = kinematics(robot, y)
    qd_hat = T @ pbh
    f = S(robot, y, pbh) @ pbh + T.T @ (u - robot.g(y) - robot.friction_torque(qd_hat))
    Hb = np.column_stack([hbar_column(robot, y, phat, k1, i) for i in range(n)])
    DpT = np.column_stack([S(robot, y, T[:, k]) @ (pbh - phat) for k in range(n)])
    DqT = (Hb - dbdq) @ T
    dbar_q = k1 * a + np.einsum("jim,m->ji", b, np.abs(phat))
    T2 = np.sum(T ** 2)
    psi1 = s["k2"] + r ** 2 / 2 * T2 + r ** 2 / k1 * T2 * np.sum(dbar_q ** 2)
    psi2 = s["k3"] + r ** 2 / 2 * np.sum((dbdq @ T) ** 2) + r ** 2 / k1 * T2 * s["deltabar_p"] ** 2
    qhat_dot = qd_hat - psi1 * (qhat - y)
    phat_dot = f - psi2 * (phat - pbh)
    xi_dot = f - dbdq @ qd_hat - dqh @ qhat_dot - dph @ phat_dot
    rdot = -(k1 / 4) * (r - s["c_r"]) + r / k1 * (np.sum(DqT ** 2) + np.sum(DpT ** 2))
    return np.concatenate([xi_dot, qhat_dot, phat_dot, [rdot]])


def output(robot, x, y, u, p, N=None, periodic=None, N_period=None):
    """est = [T(y) phat; T(y) (xi + beta)] (2n,), rad/s, of the state ``x``; ``robot``, ``y``,
    ``u``, ``p`` and the quadrature ``N``, ``periodic``, ``N_period`` as in ``rhs``."""
    n = robot.n
    xi, qhat, phat = x[:n], x[n:2 * n], x[2 * n:3 * n]
    beta, *_ = beta_and_derivatives(robot, y, qhat, phat, params(p, n)[0]["k1"], N or DEFAULT_N, False,
                                    periodic, N_period)
    T = kinematics(robot, y)[1]
    return np.concatenate([T @ phat, T @ (xi + beta)])


def init(robot, y0, est0, p, N=None, periodic=None, N_period=None):
    """x(0) = [T^{-1} est0[n:] - beta; y0; phat0 = T^{-1} est0[:n]; r0] (3n + 1,); y0 (n,) rad,
    est0 (2n,) rad/s; ``robot``, ``p`` (k1, r0 read from it) and the quadrature ``N``,
    ``periodic``, ``N_period`` as in ``rhs``."""
    n = robot.n
    s = params(p, n)[0]
    Tinv = kinematics(robot, y0)[2]
    phat0 = Tinv @ est0[:n]
    beta, *_ = beta_and_derivatives(robot, y0, y0, phat0, s["k1"], N or DEFAULT_N, False, periodic,
                                   N_period)
    return np.concatenate([Tinv @ est0[n:] - beta, y0, phat0, [s["r0"]]])


def configure(robot, options):
    """This family bound to the quadrature the spec declares (reference/ii_speed.py ``quadrature``):
    ``options`` a codegen.core.options.QuadratureOptions, its periodic joints checked against
    ``robot``."""
    return bound(__name__, **quadrature(robot, options))
