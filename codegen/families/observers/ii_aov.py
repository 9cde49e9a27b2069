"""Original I&I speed observer of Astolfi, Ortega & Venkatraman (CDC 2009), as reconstructed in
docs/papers/seed003.md §5 [DERIVED] (A3-5): the comparison observer of seed 003.

Cholesky velocity: M(q)^{-1} = T T^T (T lower), pbar = T^{-1} qd, T^{-1} = T^T M.

    S(q, b)   = -T^T M Tdot(b) - T^T C(q, T b) T,  Tdot(b) = sum_k dT/dq_k (T b)_k     (skew)
    Cbar(q, a) b = S(q, b) a
    Hbar(q, p) = (k1 I + Cbar(q, p)) T^{-1};   column i, with T T^{-1} e_i = e_i:
    Hbar_i     = k1 T^{-1} e_i - T^T M (dT/dq_i) p - T^T C(q, e_i) T p                   [DERIVED]
    pbarhat    = xi + beta(q, qhat, phat)        (beta as in §4, column-wise quadrature)
    f          = S(q, pbarhat) pbarhat + T^T (u - g(q) - tau_f(T pbarhat))   (tau_f: the friction,
                 F v + coulomb tanh(v / w) + offset, models/robot.py; the seed's F v)
    qhat' = T pbarhat - psi1 (qhat - q);   phat' = f - psi2 (phat - pbarhat)
    xi'   = f - dbeta/dq T pbarhat - dbeta/dqhat qhat' - dbeta/dphat phat'
    Delta_p T = Cbar(q, pbarhat - phat);   Delta_q T = (Hbar(q, phat) - dbeta/dq) T
    r'   = -(k1/4)(r - c_r) + (r/k1)(||Delta_q T||^2 + ||Delta_p T||^2),   c_r = 1 (original)
    psi1 = k2 + (r^2/2)||T||^2 + (r^2/k1)||T||^2 ||Deltabar_q||^2
    psi2 = k3 + (r^2/2)||dbeta/dq T||^2 + (r^2/k1)||T||^2 ||Deltabar_p||^2

Norms are Frobenius (as in ii_speed). Bounds, computed by design.ii_aov_bounds [DERIVED]:
Deltabar_p = max_q max_{|a|=1} ||Cbar(q, a) T^{-1}||_F and Deltabar_q,ji(phat) = k1 a_ji +
sum_m |phat_m| b_jim from the affine split Hbar = k1 T^{-1} + sum_m p_m Cbar(q, e_m) T^{-1}.

State x = [xi; qhat; phat; r] (3n+1), est = [T(y) phat; T(y) pbarhat] (filtered and unfiltered
speed estimates). init(y0, est0 = [qd_f0; qd_hat0]): qhat = y0, phat = T(y0)^{-1} qd_f0,
xi = T(y0)^{-1} qd_hat0 - beta(y0, y0, phat), r = r0.
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca

from ..design import ii_aov_bounds
from ...core.symbolic import cholesky_velocity, routine, skew_S
from ._ii_common import (DEFAULT_N, beta_directional, column_routines, designed_bounds,
                         filter_symbols, frobenius_sq, ii_spec, lemma2_bound, lemma2_names,
                         lemma2_values, quadrature_beta, resolve_wrap, split_params)

# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed003_2r_abs", "design": {"N": 4}}]

SCALARS = ("k1", "k2", "k3", "c_r", "deltabar_p", "r0")


def p_names(n):
    """Parameter names for ``n`` joints: the scalars, then a_ji (row-major j, i), then b_jim
    (C order j, i, m) of the Lemma-2-style bound Deltabar_q (6 + n^2 + n^3 names)."""
    return lemma2_names(SCALARS, "dq_k1", "dq_p", n)


def hbar_column(robot, q, v, k1, e):
    """Hbar(q, v) e = k1 T^{-1} e - T^{-1} (dT/dq e) v - T^T C(q, e) T v  [DERIVED, docs/papers/seed003.md §5]: at
    e = e_i, column i of the ideal Jacobian Hbar(q, v) = (k1 I + Cbar(q, v)) T^{-1}.

    Parameters
    ----------
    robot : RobotModel (n joints)
    q : SX (n,) pure configuration symbols [rad or m] (AD of T needs them)
    v : SX (n,) Cholesky velocity;  k1 : float or SX, gain (> 4)
    e : SX or DM (n,) direction (e_i for column i; Hbar is linear in it)

    Returns
    -------
    SX (n,)"""
    _, T, Tinv = cholesky_velocity(robot, q)
    dT = ca.jtimes(T, q, e)
    return (k1 * ca.mtimes(Tinv, e) - ca.mtimes(Tinv, ca.mtimes(dT, v))
            - ca.mtimes(T.T, ca.mtimes(robot.coriolis(q, e), ca.mtimes(T, v))))


@lru_cache(maxsize=32)
def _skew_routine(robot):
    """S(q, b) (symbolic.skew_S) as one routine in the C: the RHS calls it n + 1 times."""
    q, b = ca.SX.sym("q", robot.n), ca.SX.sym("b", robot.n)
    return routine("S", [q, b], [skew_S(robot, q, b)])


def build(robot, k1=10.0, k2=8.0, k3=2.5, c_r=1.0, r0=1.0, N=DEFAULT_N, bounds=None,
          samples=None, refine=True, wrap="auto", N_period=None):
    """AOV observer for ``robot`` (defaults: seed-003 comparison k1 = 10, docs/papers/seed003.md §5 item 5), the
    equations of the module docstring [DERIVED, docs/papers/seed003.md §5].

    Parameters
    ----------
    robot : RobotModel (n joints)
    k1 : float
        Gain of the ideal Jacobian Hbar; k1 > 4.
    k2, k3 : float
        Constant parts of the filter gains psi1, psi2.
    c_r : float
        Lower bound of the dynamic scaling r (1 in the original); r0 >= c_r > 0.
    r0 : float
        Initial r (a runtime parameter).
    N : int
        Gauss-Legendre nodes per integral of beta.
    bounds : IIAovDesign, optional
        Offline bounds (Deltabar_p, coefficients of Deltabar_q); when None,
        design.ii_aov_bounds(robot, samples=, refine=).
    samples, refine, wrap, N_period
        The design's sampling and refinement, and the quadrature of beta over 2 pi-periodic
        joints, as in ii_speed.build.

    Returns
    -------
    ObserverSpec
        State [xi; qhat; phat; r] (3n + 1), est = [T(y) phat; T(y) pbarhat] (2n)
        [rad/s or m/s].
    """
    if not k1 > 4:
        raise ValueError(f"k1 must be > 4, got {k1}")
    if not (r0 >= c_r > 0):
        raise ValueError(f"need r0 >= c_r > 0, got r0={r0}, c_r={c_r}")
    design = designed_bounds(bounds, ii_aov_bounds, robot, samples, refine)
    n = robot.n
    periodic = resolve_wrap(robot, wrap)
    N_period = int(N_period or N)
    pn = p_names(n)
    p_default = lemma2_values([k1, k2, k3, c_r, design.deltabar_p, r0], design.dq_k1, design.dq_p)
    x, y, u, p, (xi, qhat, phat, r) = filter_symbols(n, len(pn))
    s, a, b = split_params(p, n, SCALARS)
    K1 = s["k1"]

    cols = column_routines(robot, hbar_column, "hbar")
    beta, dbdq = quadrature_beta(cols, K1, y, qhat, phat, N, periodic, N_period)
    pbh = xi + beta
    My, T, Tinv = cholesky_velocity(robot, y)
    qd_hat = ca.mtimes(T, pbh)
    S = _skew_routine(robot)
    f = (ca.mtimes(S(y, pbh), pbh)
         + ca.mtimes(T.T, u - robot.gravity(y) - robot.friction_torque(qd_hat)))
    Hb_phat = ca.horzcat(*[col(y, phat, K1) for col in cols])
    DpT = ca.horzcat(*[ca.mtimes(S(y, T[:, k]), pbh - phat) for k in range(n)])  # Cbar(y, pbh - phat)
    DqT = ca.mtimes(Hb_phat - dbdq, T)
    dbar_q = lemma2_bound(K1, a, b, phat)
    T2 = frobenius_sq(T)
    psi1 = s["k2"] + r ** 2 / 2 * T2 + r ** 2 / K1 * T2 * frobenius_sq(dbar_q)
    psi2 = s["k3"] + r ** 2 / 2 * frobenius_sq(ca.mtimes(dbdq, T)) + r ** 2 / K1 * T2 * s["deltabar_p"] ** 2
    qhat_dot = qd_hat - psi1 * (qhat - y)
    phat_dot = f - psi2 * (phat - pbh)
    xi_dot = f - ca.mtimes(dbdq, qd_hat) - beta_directional(beta, qhat, phat, qhat_dot, phat_dot)
    rdot = -(K1 / 4) * (r - s["c_r"]) + r / K1 * (frobenius_sq(DqT) + frobenius_sq(DpT))
    xdot = ca.vertcat(xi_dot, qhat_dot, phat_dot, rdot)

    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", 2 * n)
    _, _, Tinv0 = cholesky_velocity(robot, y0)
    phat0 = ca.mtimes(Tinv0, est0[:n])
    beta0, _ = quadrature_beta(cols, K1, y0, y0, phat0, N, periodic, N_period)
    x0 = ca.vertcat(ca.mtimes(Tinv0, est0[n:]) - beta0, y0, phat0, s["r0"])

    j = list(robot.joint_names)
    return ii_spec("ii_aov", robot, ("qhat", "phat"),
                   [f"qd_f_{q}" for q in j] + [f"qd_hat_{q}" for q in j],
                   (ca.Function("rhs", [x, y, u, p], [xdot]),
                    ca.Function("output", [x, y, u, p], [ca.vertcat(ca.mtimes(T, phat), qd_hat)]),
                    ca.Function("init", [y0, est0, p], [x0])),
                   pn, p_default, (N, periodic, N_period, wrap), c_r, design, "[T(y) phat; T(y) pbarhat]")
