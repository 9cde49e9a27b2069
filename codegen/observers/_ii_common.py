"""What the two I&I speed observers share (seed 003 §II-B, SPEC §4.1 and §5).

Both build an output map beta(y, s_y, s_x) column by column from a target Jacobian whose
columns are ``col(i, q, x)``:

    beta(y, s_y, s_x) = sum_i int_0^{y_i} col(i, [s_y with sigma in place i], s_x) d sigma   [S003 (12)]
    dbeta/dy          = [col(i, [s_y with y_i in place i], s_x)]_i                            [S003 (13)]

The integrals are N-point Gauss-Legendre sums (a generation parameter, see docs/quadrature.md);
dbeta/dy is exact (fundamental theorem of calculus, no quadrature). The derivatives with
respect to the filter states enter the observer only through the product

    dbeta/ds_y alpha2 + dbeta/ds_x alpha3                                                    [S003 (6)]

so that product is one forward-mode directional derivative of the quadrature (one sweep),
never the two n x n Jacobians (14)-(15); ``beta_jacobians`` gives those when wanted.
"""
from __future__ import annotations

import casadi as ca

from ..symbolic import integrate

DEFAULT_N = 16         # Gauss-Legendre nodes per integral (docs/quadrature.md)


def substitute_entry(v, i, value):
    """[v_0, ..., v_{i-1}, value, v_{i+1}, ...] as an SX column."""
    return ca.vertcat(*[value if j == i else v[j] for j in range(v.numel())])


def quadrature_beta(col, y, s_y, s_x, N):
    """beta [S003 (12)] by N-node Gauss-Legendre on each [0, y_i], and the exact dbeta/dy (13)."""
    n = y.numel()
    beta = ca.SX.zeros(n, 1)
    for i in range(n):
        beta = beta + integrate(lambda s, i=i: col(i, substitute_entry(s_y, i, s), s_x), y[i], N)
    dbeta_dy = ca.horzcat(*[col(i, substitute_entry(s_y, i, y[i]), s_x) for i in range(n)])
    return beta, dbeta_dy


def beta_directional(beta, s_y, s_x, d_sy, d_sx):
    """dbeta/ds_y d_sy + dbeta/ds_x d_sx by one forward sweep of automatic differentiation."""
    return ca.jtimes(beta, ca.vertcat(s_y, s_x), ca.vertcat(d_sy, d_sx))


def beta_jacobians(beta, s_y, s_x):
    """(dbeta/ds_y, dbeta/ds_x) [S003 (14), (15)] by automatic differentiation of the quadrature."""
    return ca.jacobian(beta, s_y), ca.jacobian(beta, s_x)


def christoffel_column_matrix(robot, q, i):
    """C(q, e_i) (n x n): by the symmetry C(q, x) e_i = C(q, e_i) x [S003 P2] it gives column i
    of C(q, x) for every x at the cost of one Christoffel evaluation."""
    e = ca.DM.zeros(robot.n, 1)
    e[i] = 1.0
    return robot.coriolis(q, e)


def frobenius_sq(A):
    """||A||_F^2 = sum of squared entries (upper bound of the squared spectral norm)."""
    return ca.sumsqr(A)


def names(robot):
    """Joint-suffixed name lists used by both families."""
    return list(robot.joint_names)
