"""I&I globally exponentially convergent speed observer, Arbo, Grotli & Gravdahl (seed 003, docs/papers/seed003.md §4.1).

    H(q, x)   = M(q)^{-1} (k1 I - C(q, x))        Christoffel C (A3-1)                  [S003 (11)]
    beta      = sum_i int_0^{y_i} H_i([s_y with sigma in place i], s_x) d sigma          [S003 (12)]
    xhat      = xi + beta                                                                [S003 (3b)]
    e_y = s_y - y,   e_x = s_x - xhat                                                    [S003 (17),(18)]
    M Delta_x = C(y, e_x),   M Delta_y = k1 I - C(y, s_x) - M dbeta/dy                   [S003 (16),(22)]
    psi1 = k2 + r^2/2 + r^2 k_M^2/(k1 k_m) ||Deltabar_y||^2                               [S003 (53)]
    psi2 = k3 + r^2/2 ||dbeta/dy||^2 + r^2 k_M^2/(k1 k_m) ||Deltabar_x||^2                [S003 (54)]
    s_y' = alpha2 = xhat - psi1 e_y                                                      [S003 (44)]
    s_x' = alpha3 = FD(y, xhat, u) - psi2 e_x                                            [S003 (45)]
    xi'  = alpha1 = FD(y, xhat, u) - dbeta/dy xhat - dbeta/ds_y alpha2 - dbeta/ds_x alpha3   [S003 (6)]
    r'   = -(k1/(4 k_m))(r - c_r) + r/(k1 k_m) (||M Delta_y||^2 + ||M Delta_x||^2)      [S003 (38)]

with FD(y, v, u) = M(y)^{-1}(u - C(y, v) v - F v - g(y)) the robot's forward dynamics (F = 0 in
the seed; a robot with friction keeps its F [ASSUMPTION]).

Implementation choices:
- H_i(q, x) = M(q)^{-1}(k1 e_i - C(q, e_i) x) (symmetry P2): one Christoffel matrix and one
  unpivoted LDL^T solve per quadrature node, no symbolic inverse; one routine per column in the
  C (H e_i: C(q, e_i) costs half the general C(q, e)), called at every node (_ii_common.column_routines).
- beta by N-node Gauss-Legendre (``N``, a generation parameter), the intervals of 2 pi-periodic
  joints reduced to |rho| <= pi plus whole periods (``wrap``, ``N_period``; _ii_common and
  docs/quadrature.md; declared as ``spec.options`` (codegen.core.options.QuadratureOptions), which the
  reference's configure() reads); dbeta/dy exact (13);
  dbeta/ds_y alpha2 + dbeta/ds_x alpha3 by one forward AD sweep of the quadrature (14),(15).
- Norms of matrices in (38), (53), (54) are Frobenius norms [DERIVED]: an upper bound of the
  spectral norm (so (37) still holds) that is smooth and cheap in C; Lemma 2 bounds exactly
  the Frobenius norm, and Deltabar_x = max(k_c/k_m, k_cF/k_M) keeps (54) dominating
  ||M Delta_x||_F (= k_c/k_m of Lemma 1 whenever k_M k_c/k_m >= k_cF, e.g. the seed's arm).
- Deltabar_y(s_x) = k1 a + sum_m |s_x,m| b^(m) entrywise, a and b designed offline (design.ii).

State x = [xi; s_y; s_x; r] (3n+1), y = q, u = tau, estimate est = [s_x; xhat]: the first n
entries are the observer's output s_x (seed 003 §II-B), the last n the unfiltered xhat.
init(y0, est0 = [s_x0; xhat0]) sets s_y = y0, s_x = s_x0, xi = xhat0 - beta(y0, y0, s_x0) and
r = r0 (a parameter). A filter state with s_y(0) != y(0) (Table I) is set through ``state``.
"""
from __future__ import annotations

import casadi as ca

from ..design import ii_speed_bounds
from ...core.symbolic import ldl_solve
from ._ii_common import DEFAULT_N  # public: default quadrature nodes N (docs/quadrature.md)
from ._ii_common import (beta_directional, column_routines, designed_bounds, filter_symbols,
                         frobenius_sq, ii_spec, lemma2_bound, lemma2_names, lemma2_values,
                         quadrature_beta, resolve_wrap, split_params)

# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed003_2r_abs", "design": {"N": 4}}]

SCALARS = ("k1", "k2", "k3", "c_r", "k_m", "k_M", "deltabar_x", "r0")


def p_names(n):
    """Parameter names for ``n`` joints: the scalars, then a_ji (row-major j, i), then b_jim
    (C order j, i, m) of the Lemma-2 bound Deltabar_y (8 + n^2 + n^3 names)."""
    return lemma2_names(SCALARS, "dy_k1", "dy_sx", n)


def h_column(robot, q, x, k1, e):
    """H(q, x) e = M(q)^{-1} (k1 e - C(q, e) x)  [S003 (11)]: at e = e_i, column i of the
    target Jacobian, by symmetry P2 and one LDL^T solve (no symbolic inverse).

    Parameters
    ----------
    robot : RobotModel (n joints)
    q : SX (n,) configuration [rad or m]
    x : SX (n,) velocity [rad/s or m/s]
    k1 : float or SX
        Observer gain k1 (> 4).
    e : SX or DM (n,)
        Direction (e_i for column i; H is linear in it).

    Returns
    -------
    SX (n,)"""
    return ldl_solve(robot.mass_matrix(q), k1 * e - ca.mtimes(robot.coriolis(q, e), x))


def build(robot, k1=40.0, k2=8.0, k3=2.5, c_r=1e-3, r0=0.1, N=DEFAULT_N, bounds=None,
          samples=None, refine=True, wrap="auto", N_period=None):
    """I&I speed observer for ``robot`` (defaults: seed 003 Table II gains, r(0) = 0.1), the
    equations of the module docstring [S003 (3)-(54)].

    Parameters
    ----------
    robot : RobotModel (n joints)
    k1 : float
        Gain of the target Jacobian H [S003 (11)]; k1 > 4 [S003 (55)].
    k2, k3 : float
        Constant parts of the filter gains psi1, psi2 [S003 (53),(54)].
    c_r : float
        Lower bound of the dynamic scaling r [S003 (38)]; r0 > c_r > 0.
    r0 : float
        Initial r (a runtime parameter).
    N : int
        Gauss-Legendre nodes per integral of beta [S003 (12)].
    bounds : IISpeedDesign, optional
        Offline bounds (k_m, k_M, Deltabar_x, Lemma-2 coefficients); when None,
        design.ii_speed_bounds(robot, samples=, refine=).
    samples : int, optional
        Configurations sampled by the design when ``bounds`` is None (default 2000 for n <= 3,
        300 above).
    refine : bool
        Refine the sampled sups locally (design only).
    wrap : "auto", bool or sequence of n bool
        Joints whose interval is reduced to |rho| <= pi plus whole periods
        (_ii_common.resolve_wrap).
    N_period : int, optional
        Trapezoid nodes over one period of a wrapped joint (default N).

    Returns
    -------
    ObserverSpec
        State [xi; s_y; s_x; r] (3n + 1), est = [s_x; xhat] (2n) [rad/s or m/s].
    """
    if not k1 > 4:
        raise ValueError(f"k1 must be > 4 [S003 (55)], got {k1}")
    if not (r0 > c_r > 0):
        raise ValueError(f"need r0 > c_r > 0 [S003 (38)], got r0={r0}, c_r={c_r}")
    design = designed_bounds(bounds, ii_speed_bounds, robot, samples, refine)
    n = robot.n
    periodic = resolve_wrap(robot, wrap)
    N_period = int(N_period or N)
    pn = p_names(n)
    p_default = lemma2_values([k1, k2, k3, c_r, design.k_m, design.k_M, design.deltabar_x, r0],
                              design.dy_k1, design.dy_sx)
    x, y, u, p, (xi, s_y, s_x, r) = filter_symbols(n, len(pn))
    s, a, b = split_params(p, n, SCALARS)
    K1 = s["k1"]

    cols = column_routines(robot, h_column, "h", specialise=True)   # H e_i costs half of H e
    beta, dbdy = quadrature_beta(cols, K1, y, s_y, s_x, N, periodic, N_period)   # [S003 (12),(13)]
    xhat = xi + beta                                                    # [S003 (3b)]
    e_y, e_x = s_y - y, s_x - xhat                                      # [S003 (17),(18)]
    fd = robot.forward_dynamics(y, xhat, u)
    My = robot.mass_matrix(y)
    MDx = robot.coriolis(y, e_x)                                        # M Delta_x [S003 (22)]
    MDy = K1 * ca.DM.eye(n) - robot.coriolis(y, s_x) - ca.mtimes(My, dbdy)   # M Delta_y [S003 (16)]
    dbar_y = lemma2_bound(K1, a, b, s_x)                                # Lemma 2 [DERIVED]
    g = r ** 2 * s["k_M"] ** 2 / (K1 * s["k_m"])
    psi1 = s["k2"] + r ** 2 / 2 + g * frobenius_sq(dbar_y)              # [S003 (53)]
    psi2 = s["k3"] + r ** 2 / 2 * frobenius_sq(dbdy) + g * s["deltabar_x"] ** 2   # [S003 (54)]
    alpha2 = xhat - psi1 * e_y                                          # [S003 (44)]
    alpha3 = fd - psi2 * e_x                                            # [S003 (45)]
    alpha1 = fd - ca.mtimes(dbdy, xhat) - beta_directional(beta, s_y, s_x, alpha2, alpha3)  # (6)
    rdot = (-(K1 / (4 * s["k_m"])) * (r - s["c_r"])
            + r / (K1 * s["k_m"]) * (frobenius_sq(MDy) + frobenius_sq(MDx)))          # [S003 (38)]
    xdot = ca.vertcat(alpha1, alpha2, alpha3, rdot)

    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", 2 * n)
    sx0, xhat0 = est0[:n], est0[n:]
    beta0, _ = quadrature_beta(cols, K1, y0, y0, sx0, N, periodic, N_period)
    x0 = ca.vertcat(xhat0 - beta0, y0, sx0, s["r0"])

    j = list(robot.joint_names)
    return ii_spec("ii_speed", robot, ("s_y", "s_x"),
                   [f"s_x_{q}" for q in j] + [f"qd_hat_{q}" for q in j],
                   (ca.Function("rhs", [x, y, u, p], [xdot]),
                    ca.Function("output", [x, y, u, p], [ca.vertcat(s_x, xhat)]),
                    ca.Function("init", [y0, est0, p], [x0])),
                   pn, p_default, (N, periodic, N_period, wrap), c_r, design, "[s_x; xhat]")
