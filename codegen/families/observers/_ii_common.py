"""What the two I&I speed observers share (seed 003 §II-B, docs/papers/seed003.md §4.1 and §5).

Both build an output map beta(y, s_y, s_x) column by column from a target Jacobian whose
columns are ``col(i, q, x)``:

    beta(y, s_y, s_x) = sum_i int_0^{y_i} col(i, [s_y with sigma in place i], s_x) d sigma   [S003 (12)]
    dbeta/dy          = [col(i, [s_y with y_i in place i], s_x)]_i                            [S003 (13)]

The integrals are N-point Gauss-Legendre sums (a generation parameter, see docs/quadrature.md);
dbeta/dy is exact (fundamental theorem of calculus, no quadrature).

Interval reduction (``wrap``): for a joint whose dynamics are 2 pi-periodic in q_i (revolute,
``robot.periodic[i]``), with y_i = 2 pi m + rho, m = floor(y_i / 2 pi + 1/2), |rho| <= pi,

    int_0^{y_i} col_i d sigma = m int_{-pi}^{pi} col_i d sigma + int_0^{rho} col_i d sigma

(the period by the N_period-node trapezoidal rule, [0, rho] by N-node Gauss-Legendre), so the
quadrature error no longer grows with |y_i| (a free-swinging link goes round several times, and
dbeta/ds_y, dbeta/ds_x, AD of the quadrature, then drift from the exact dbeta/dy). m is piecewise
constant, so AD gives the right partials a.e.; dbeta/dy stays col_i at y_i. A column that does
not depend on sigma at all (e.g. column 1 of a serial arm: M and C do not depend on q_1) is
y_i col_i exactly, with no quadrature. The derivatives with
respect to the filter states enter the observer only through the product

    dbeta/ds_y alpha2 + dbeta/ds_x alpha3                                                    [S003 (6)]

so that product is one forward-mode directional derivative of the quadrature (one sweep),
never the two n x n Jacobians (14)-(15); ``beta_jacobians`` gives those when wanted.

Code shape: the columns are one routine col(q, x, k1, e) called with e = e_i (AOV), or one
routine per column (I&I speed; ``column_routines``, symbolic.routine), and each integral one
call of a quadrature routine that loops over its nodes (symbolic.gauss_legendre_routine,
trapezoid_routine); the directional derivative calls the loop's forward derivative. The C holds
each routine and its derivative once whatever N (I&I ur5 at N = 8: 7.0 MB of fully inlined C
at first; codegen.evaluate.bench).
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca

import numpy as np

from ...core.options import InputRanges, QuadratureOptions
from ...core.spec import ObserverSpec
from ...core.symbolic import gauss_legendre_routine, routine, trapezoid_routine, wrap_angle

DEFAULT_N = 16         # Gauss-Legendre nodes per integral (docs/quadrature.md)
WRAP_OPTIONS = ("auto", True, False)


def resolve_wrap(robot, wrap="auto"):
    """Per-joint interval reduction flags (list of n bools) for the generation option ``wrap``:

    "auto"  wrap the joints the robot declares 2 pi-periodic (``robot.periodic``; none if the
            robot does not say), True  wrap every joint (ValueError if the robot declares one
            not periodic, e.g. prismatic), False  no reduction (plain [0, y_i] quadrature);
    or an explicit sequence of n bools (checked against ``robot.periodic`` the same way)."""
    n = robot.n
    declared = getattr(robot, "periodic", None)
    declared = np.zeros(n, bool) if declared is None else np.asarray(declared, dtype=bool).reshape(n)
    if isinstance(wrap, str):
        if wrap != "auto":
            raise ValueError(f"wrap must be 'auto', True, False or n bools, got {wrap!r}")
        return [bool(v) for v in declared]
    if wrap is True or wrap is False:
        flags = np.full(n, bool(wrap))
    else:
        flags = np.asarray(wrap, dtype=bool).reshape(-1)
        if flags.size != n:
            raise ValueError(f"wrap needs {n} flags, got {list(flags)}")
    bad = [robot.joint_names[i] for i in range(n) if flags[i] and not declared[i]]
    if bad:
        raise ValueError(f"wrap: joints {bad} of {robot.name!r} are not declared 2 pi-periodic "
                         f"(robot.periodic = {list(map(bool, declared))})")
    return [bool(v) for v in flags]


@lru_cache(maxsize=32)
def column_routines(robot, column, name, specialise=False):
    """[col_0, ..., col_{n-1}]: col_i(q, v, k1) = column(robot, q, v, k1, e_i), the integrand of
    column i of beta (n-vector), cached per robot and column builder.

    Shared (default): every col_i calls one routine ``name``(q, v, k1, e) with e = e_i, so the C
    holds one column body and one forward derivative whatever n. ``specialise``: one routine
    ``name``i per column with e_i folded in (n bodies, each cheaper to run: the terms that
    vanish along e_i are gone)."""
    n = robot.n
    q, v, k1, e = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("k1"), ca.SX.sym("e", n)
    eye = ca.DM.eye(n)
    if specialise:
        return [routine(f"{name}{i}", [q, v, k1], [column(robot, q, v, k1, eye[:, i])]) for i in range(n)]
    shared = routine(name, [q, v, k1, e], [column(robot, q, v, k1, e)])
    return [ca.Function(f"{name}{i}", [q, v, k1], [shared(q, v, k1, eye[:, i])]) for i in range(n)]


def substitute_entry(v, i, value):
    """[v_0, ..., v_{i-1}, value, v_{i+1}, ...] as an SX column."""
    return ca.vertcat(*[value if j == i else v[j] for j in range(v.numel())])


def quadrature_beta(cols, k1, y, s_y, s_x, N, periodic=None, N_period=None):
    """beta [S003 (12)] by N-node Gauss-Legendre on each [0, y_i] (on [0, rho_i] plus m_i
    periods by the N_period-node trapezoid for the joints flagged in ``periodic``, see the
    module docstring), and the exact dbeta/dy (13). ``cols``: the n column routines
    (``column_routines``); each integral is one call of a quadrature routine (a loop in the C)."""
    n = y.numel()
    periodic = [False] * n if periodic is None else list(periodic)
    N_period = N if N_period is None else N_period
    beta = ca.SX.zeros(n, 1)
    for i, col in enumerate(cols):
        if not col.which_depends("i0", ["o0"], 1, True)[i]:     # constant along sigma: exact
            beta = beta + y[i] * col(s_y, s_x, k1)
        elif periodic[i]:
            m, rho = wrap_angle(y[i])
            beta = (beta + m * trapezoid_routine(col, i, N_period)(s_y, s_x, k1)
                    + gauss_legendre_routine(col, i, N)(rho, s_y, s_x, k1))
        else:
            beta = beta + gauss_legendre_routine(col, i, N)(y[i], s_y, s_x, k1)
    dbeta_dy = ca.horzcat(*[col(substitute_entry(s_y, i, y[i]), s_x, k1) for i, col in enumerate(cols)])
    return beta, dbeta_dy


def beta_directional(beta, s_y, s_x, d_sy, d_sx):
    """dbeta/ds_y d_sy + dbeta/ds_x d_sx by one forward sweep of automatic differentiation."""
    return ca.jtimes(beta, ca.vertcat(s_y, s_x), ca.vertcat(d_sy, d_sx))


def beta_jacobians(beta, s_y, s_x):
    """(dbeta/ds_y, dbeta/ds_x) [S003 (14), (15)] by automatic differentiation of the quadrature."""
    return ca.jacobian(beta, s_y), ca.jacobian(beta, s_x)


def frobenius_sq(A):
    """||A||_F^2 = sum of squared entries (upper bound of the squared spectral norm)."""
    return ca.sumsqr(A)


def designed_bounds(bounds, design, robot, samples=None, refine=True):
    """``bounds`` when given, else ``design(robot, samples=, refine=)`` (design.ii_speed_bounds or
    design.ii_aov_bounds): offline sups sampled at ``samples`` configurations (default 2000 for
    n <= 3 joints, 300 above) and refined locally unless ``refine`` is False."""
    if bounds is not None:
        return bounds
    return design(robot, samples=samples or (2000 if robot.n <= 3 else 300), refine=refine)


def lemma2_names(scalars, a_name, b_name, n):
    """Parameter names of an I&I observer: the scalars, then the Lemma-2 coefficients a_ji
    (``a_name``_j_i, row-major j, i) and b_jim (``b_name``_j_i_m, C order j, i, m)."""
    return (list(scalars) + [f"{a_name}_{j}_{i}" for j in range(n) for i in range(n)]
            + [f"{b_name}_{j}_{i}_{m}" for j in range(n) for i in range(n) for m in range(n)])


def lemma2_values(scalars, a, b):
    """Flat parameter values in the order of ``lemma2_names``: scalars, a (n, n), b (n, n, n)."""
    return list(scalars) + list(np.asarray(a).reshape(-1)) + list(np.asarray(b).reshape(-1))


def split_params(p, n, scalars):
    """(dict of scalars, a (n x n), b list of n (n x n) matrices b[m][j, i]) from the flat p
    laid out as ``lemma2_names``."""
    s = {k: p[i] for i, k in enumerate(scalars)}
    o = len(scalars)
    a = ca.reshape(p[o:o + n * n], n, n).T                              # row-major -> [j, i]
    o += n * n
    flat = p[o:o + n ** 3]                                              # index j n^2 + i n + m
    b = [ca.vertcat(*[ca.horzcat(*[flat[j * n * n + i * n + m] for i in range(n)])
                      for j in range(n)]) for m in range(n)]
    return s, a, b


def lemma2_bound(k1, a, b, x):
    """Deltabar_ji(x) = k1 a_ji + sum_m |x_m| b_jim, entrywise  [S003 Lemma 2, DERIVED]."""
    bound = k1 * a
    for m in range(len(b)):
        bound = bound + ca.fabs(x[m]) * b[m]
    return bound


def filter_symbols(n, n_p):
    """Symbols x (3n+1), y (n), u = tau (n), p (n_p) of an I&I observer and the blocks
    (xi, first filter state, second filter state, r) of x = [xi; .; .; r]."""
    x = ca.SX.sym("x", 3 * n + 1)
    y, u, p = ca.SX.sym("y", n), ca.SX.sym("tau", n), ca.SX.sym("p", n_p)
    return x, y, u, p, (x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n])


def ii_spec(family, robot, filters, est_names, functions, p_names, p_default, quadrature, c_r,
            design, estimate):
    """The ObserverSpec of an I&I family: state [xi; filter a; filter b; r], y = q, u = tau.

    Parameters
    ----------
    family : str
    robot : RobotModel
    filters : (str, str)
        Names of the two n-vector filter states (e.g. ("s_y", "s_x")).
    est_names : list of str
        Names of the 2n estimate slots.
    functions : (casadi.Function, casadi.Function, casadi.Function)
        rhs(x, y, u, p), output(x, y, u, p), init(y0, est0, p).
    p_names, p_default : list of str, sequence of float
        Runtime parameters and their designed defaults.
    quadrature : (int, list of bool, int, object)
        N, per-joint periodic reduction flags, N_period, and the ``wrap`` request as given.
    c_r : float
        Lower bound of the dynamic scaling r (the cross-check draws r in [2 c_r, 2 c_r + 0.02]).
    design : dataclass with ``as_dict``
        The designed bounds.
    estimate : str
        What the estimate is, for the report.
    """
    N, periodic, N_period, wrap = quadrature
    j = list(robot.joint_names)
    rhs, output, init = functions
    return ObserverSpec(
        family=family, robot=robot,
        x_names=[f"xi_{q}" for q in j] + [f"{filters[0]}_{q}" for q in j] + [f"{filters[1]}_{q}" for q in j]
        + ["r"], y_names=[f"q_{q}" for q in j], u_names=[f"tau_{q}" for q in j], p_names=p_names,
        est_names=est_names, p_default=p_default, rhs=rhs, output=output, init=init,
        options=QuadratureOptions(N=N, periodic=periodic, N_period=N_period),
        inputs=ii_inputs(robot.n, c_r),
        design={**design.as_dict(), "quadrature": "gauss-legendre", "period_rule": "trapezoid",
                "wrap": wrap if isinstance(wrap, (str, bool)) else list(map(bool, wrap)),
                "norms": "frobenius", "estimate": estimate})


def ii_inputs(n, c_r):
    """Cross-check input ranges of the I&I observers (data, codegen.core.options.InputRanges):
    configurations from one fixed draw plus 1e-2 rad of noise, so the two samples of a draw
    differ like consecutive 1 kHz measurements rather than by whole turns (a jump of several
    rad in 1 ms drives these stiff filters out of range); u = g(y) + N(0, 1); states from init
    at N(0, 1) estimates with the position filter off y by ~0.05 rad and r in
    [2 c_r, 2 c_r + 0.02]."""
    return InputRanges(y_jitter=1e-2, u="gravity", u_scale=1.0, est_scale=1.0,
                       x_scale=(0.0,) * n + (0.05,) * n + (0.0,) * (n + 1),
                       x_uniform=(("r", 2 * c_r, 2 * c_r + 0.02),))
