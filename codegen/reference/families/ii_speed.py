"""I&I speed observer of Arbo, Grotli & Gravdahl (seed 003), numpy + pin, from docs/papers/seed003.md §4.1.

    H(q, x)  = M(q)^{-1}(k1 I - C(q, x))                                    [S003 (11)], A3-1
    beta     = sum_i int_0^{y_i} H_i(z_i(sigma), s_x) d sigma,  z_i = s_y with sigma at i   (12)
    dbeta/dy = [H_i(z_i(y_i), s_x)]_i                                                  (13)
    dbeta/ds_y,j = sum_{i != j} int_0^{y_i} dH_i/dq_j (z_i(sigma), s_x) d sigma        (14)
    dbeta/ds_x   = sum_i int_0^{y_i} -M^{-1} C(z_i(sigma), e_i) d sigma                (15)
    dH_i/dq_j = -M^{-1} (dM/dq_j H_i + d(C(q, x) e_i)/dq_j)    (d M^{-1} = -M^{-1} dM M^{-1})

The integrals are N-node Gauss-Legendre sums (numpy leggauss); the q-derivatives come from the
reference robot's exact dMw_dq / dCab_dq (closed forms, or pinocchio's analytical RNEA
derivatives), never from finite differences. The rest (alpha1..3, r', psi1, psi2 with Frobenius
norms, est = [s_x; xhat], init) follows the module docstring of the symbolic family, written
again here from docs/papers/seed003.md §4.1:

    xhat = xi + beta; e_y = s_y - y; e_x = s_x - xhat
    M Delta_x = C(y, e_x); M Delta_y = k1 I - C(y, s_x) - M dbeta/dy
    Deltabar_y,ji = k1 a_ji + sum_m |s_x,m| b_jim
    psi1 = k2 + r^2/2 + r^2 k_M^2/(k1 k_m) ||Deltabar_y||_F^2                           (53)
    psi2 = k3 + r^2/2 ||dbeta/dy||_F^2 + r^2 k_M^2/(k1 k_m) deltabar_x^2               (54)
    s_y' = xhat - psi1 e_y;  s_x' = FD(y, xhat, u) - psi2 e_x                           (44),(45)
    xi'  = FD - dbeta/dy xhat - dbeta/ds_y s_y' - dbeta/ds_x s_x'                       (6)
    r'   = -(k1/(4 k_m))(r - c_r) + r/(k1 k_m)(||M Delta_y||_F^2 + ||M Delta_x||_F^2)  (38)

Parameters p = [k1, k2, k3, c_r, k_m, k_M, deltabar_x, r0, a (n^2, row-major j,i),
b (n^3, C order j,i,m)].
"""
from __future__ import annotations

import numpy as np

from ._family import bound

SCALARS = ("k1", "k2", "k3", "c_r", "k_m", "k_M", "deltabar_x", "r0")
DEFAULT_N = 16


def quadrature_nodes(N):
    """(t, w): N Gauss-Legendre nodes and weights on [-1, 1] (numpy leggauss), (N,) each."""
    return np.polynomial.legendre.leggauss(int(N))


def params(p, n, scalars=SCALARS):
    """The flat parameter vector of an I&I observer, split (module docstring).

    Parameters
    ----------
    p : (len(scalars) + n^2 + n^3,) array
    n : int
        Joints.
    scalars : tuple of str
        Names of the leading scalars.

    Returns
    -------
    s : dict
        The scalars by name.
    a : (n, n) array
        Row-major (j, i).
    b : (n, n, n) array
        C order (j, i, m).
    """
    s = dict(zip(scalars, p[:len(scalars)]))
    o = len(scalars)
    a = np.asarray(p[o:o + n * n]).reshape(n, n)
    b = np.asarray(p[o + n * n:o + n * n + n ** 3]).reshape(n, n, n)
    return s, a, b


def h_column(robot, q, x, k1, i):
    """H_i(q, x) = M(q)^{-1}(k1 e_i - C(q, x) e_i)  [S003 (11)], A3-1.

    Parameters
    ----------
    robot : reference robot (n joints)
    q : (n,) array
        rad.
    x : (n,) array
        Velocity estimate s_x, rad/s.
    k1 : float
        1/s.
    i : int
        Column.

    Returns
    -------
    (n,) array
    """
    rhs = -robot.C(q, x)[:, i]
    rhs[i] += k1
    return np.linalg.solve(robot.M(q), rhs)


def h_column_derivatives(robot, q, x, k1, i):
    """H_i and its exact derivatives, dH_i/dq_j = -M^{-1}(dM/dq_j H_i + d(C(q, x) e_i)/dq_j).

    Parameters
    ----------
    robot, q, x, k1, i
        As in ``h_column``; the robot gives ``dMw_dq`` and ``dCab_dq``.

    Returns
    -------
    Hi : (n,) array
    dq : (n, n) array
        dH_i/dq.
    dx : (n, n) array
        dH_i/dx.
    """
    Mq = robot.M(q)
    e = np.zeros(robot.n)
    e[i] = 1.0
    Hi = np.linalg.solve(Mq, k1 * e - robot.C(q, x) @ e)
    dq = -np.linalg.solve(Mq, robot.dMw_dq(q, Hi) + robot.dCab_dq(q, x, e))
    dx = -np.linalg.solve(Mq, robot.C(q, e))            # C(q, x) e_i = C(q, e_i) x
    return Hi, dq, dx


def column_nodes(yi, N, periodic=False, N_period=None):
    """Quadrature of int_0^{yi} f ~= sum_k h_k f(sigma_k) (docs/papers/seed003.md §4.1, docs/quadrature.md).

    N-node Gauss-Legendre on [0, yi]; for a 2 pi-periodic joint, with yi = 2 pi m + rho
    (m = floor(yi/2pi + 1/2)), m times the N_period-node trapezoid over [-pi, pi) plus
    Gauss-Legendre on [0, rho].

    Parameters
    ----------
    yi : float
        Upper limit, rad.
    N : int
        Gauss-Legendre nodes.
    periodic : bool
        Reduce the interval modulo 2 pi.
    N_period : int or None
        Trapezoid nodes per whole period (None: N).

    Returns
    -------
    list of (sigma_k, h_k)
        Nodes (rad) and weights (rad).
    """
    t, w = quadrature_nodes(N)
    if not periodic:
        return list(zip(0.5 * yi * (1.0 + t), 0.5 * yi * w))
    m = np.floor(yi / (2 * np.pi) + 0.5)
    rho = yi - 2 * np.pi * m
    nodes = list(zip(0.5 * rho * (1.0 + t), 0.5 * rho * w))
    if m != 0:
        Np = int(N_period or N)
        nodes += [(-np.pi + 2 * np.pi * k / Np, m * 2 * np.pi / Np) for k in range(Np)]
    return nodes


def beta_and_derivatives(robot, y, s_y, s_x, k1, N, derivatives=True, periodic=None, N_period=None):
    """beta and its derivatives by quadrature  [S003 (12)-(15)].

    Parameters
    ----------
    robot : reference robot (n joints)
    y : (n,) array
        Measured q, rad.
    s_y : (n,) array
        Position filter, rad.
    s_x : (n,) array
        Velocity filter, rad/s.
    k1 : float
        1/s.
    N : int
        Gauss-Legendre nodes per integral.
    derivatives : bool
        Also dbeta/ds_y and dbeta/ds_x (zeros otherwise).
    periodic : sequence of n bools or None
        The joints whose interval is reduced modulo 2 pi (``column_nodes``).
    N_period : int or None

    Returns
    -------
    beta : (n,) array
    dbdy, dbdsy, dbdsx : (n, n) arrays
        dbeta/dy (13), dbeta/ds_y (14), dbeta/ds_x (15).
    """
    n = robot.n
    periodic = [False] * n if periodic is None else periodic
    beta = np.zeros(n)
    dsy, dsx = np.zeros((n, n)), np.zeros((n, n))
    dy = np.zeros((n, n))
    for i in range(n):
        z = np.array(s_y, dtype=float)
        for sk, h in column_nodes(y[i], N, periodic[i], N_period):
            z[i] = sk
            if derivatives:
                Hi, dq, dx = h_column_derivatives(robot, z, s_x, k1, i)
                dq[:, i] = 0.0                          # z_i(sigma) does not depend on s_y,i
                dsy += h * dq
                dsx += h * dx
            else:
                Hi = h_column(robot, z, s_x, k1, i)
            beta += h * Hi
        z[i] = y[i]
        dy[:, i] = h_column(robot, z, s_x, k1, i)
    return beta, dy, dsy, dsx


def _split(x, n):
    return x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n]


def rhs(robot, x, y, u, p, N=None, periodic=None, N_period=None):
    """[xi'; s_y'; s_x'; r']  [S003 (6), (38), (44), (45)] (module docstring).

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (3n + 1,) array
        [xi (rad/s); s_y (rad); s_x (rad/s); r].
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m.
    p : (8 + n^2 + n^3,) array
        See ``params``.
    N, periodic, N_period
        The quadrature (``beta_and_derivatives``; N None: DEFAULT_N).

    Returns
    -------
    (3n + 1,) array
    """
    n = robot.n
    N = N or DEFAULT_N
    s, a, b = params(p, n)
    k1 = s["k1"]
    xi, s_y, s_x, r = _split(x, n)
    beta, dbdy, dsy, dsx = beta_and_derivatives(robot, y, s_y, s_x, k1, N, True, periodic, N_period)
    xhat = xi + beta
    e_y, e_x = s_y - y, s_x - xhat
    fd = robot.forward_dynamics(y, xhat, u)
    My = robot.M(y)
    MDx = robot.C(y, e_x)
    MDy = k1 * np.eye(n) - robot.C(y, s_x) - My @ dbdy
    dbar_y = k1 * a + np.einsum("jim,m->ji", b, np.abs(s_x))
    g = r ** 2 * s["k_M"] ** 2 / (k1 * s["k_m"])
    psi1 = s["k2"] + r ** 2 / 2 + g * np.sum(dbar_y ** 2)
    psi2 = s["k3"] + r ** 2 / 2 * np.sum(dbdy ** 2) + g * s["deltabar_x"] ** 2
    alpha2 = xhat - psi1 * e_y
    alpha3 = fd - psi2 * e_x
    alpha1 = fd - dbdy @ xhat - dsy @ alpha2 - dsx @ alpha3
    rdot = -(k1 / (4 * s["k_m"])) * (r - s["c_r"]) + r / (k1 * s["k_m"]) * (np.sum(MDy ** 2) + np.sum(MDx ** 2))
    return np.concatenate([alpha1, alpha2, alpha3, [rdot]])


def output(robot, x, y, u, p, N=None, periodic=None, N_period=None):
    """est = [s_x; xhat = xi + beta] (2n,), rad/s, of the state ``x``; ``robot``, ``y``, ``u``,
    ``p`` and the quadrature ``N``, ``periodic``, ``N_period`` as in ``rhs``."""
    n = robot.n
    xi, s_y, s_x, _ = _split(x, n)
    beta, *_ = beta_and_derivatives(robot, y, s_y, s_x, params(p, n)[0]["k1"], N or DEFAULT_N,
                                    False, periodic, N_period)
    return np.concatenate([s_x, xi + beta])


def init(robot, y0, est0, p, N=None, periodic=None, N_period=None):
    """x(0) = [est0[n:] - beta(y0, y0, s_x); y0; s_x = est0[:n]; r0] (3n + 1,); y0 (n,) rad,
    est0 (2n,) rad/s; ``robot``, ``p`` (k1, r0 read from it) and the quadrature ``N``,
    ``periodic``, ``N_period`` as in ``rhs``."""
    n = robot.n
    s = params(p, n)[0]
    sx0, xhat0 = est0[:n], est0[n:]
    beta, *_ = beta_and_derivatives(robot, y0, y0, sx0, s["k1"], N or DEFAULT_N, False, periodic,
                                   N_period)
    return np.concatenate([xhat0 - beta, y0, sx0, [s["r0"]]])


def sizes(robot):
    """{"nx": 3n + 1, "ny": n, "nu": n, "nest": 2n} for ``robot`` with n joints."""
    n = robot.n
    return {"nx": 3 * n + 1, "ny": n, "nu": n, "nest": 2 * n}


def check_periodic(robot, periodic):
    """The spec's per-joint interval reduction, checked against this reference robot's own
    ``periodic`` flags (pinocchio joint types / closed forms).

    Parameters
    ----------
    robot : reference robot (n joints)
    periodic : sequence of n bools

    Returns
    -------
    list of n bools

    Raises
    ------
    ValueError
        If the spec reduces a joint the reference robot does not know to be 2 pi-periodic.
    """
    declared = getattr(robot, "periodic", None)
    declared = np.zeros(robot.n, bool) if declared is None else np.asarray(declared, dtype=bool)
    flags = np.asarray(periodic, dtype=bool).reshape(-1)
    if flags.shape != (robot.n,):
        raise ValueError(f"periodic: expected {robot.n} flags, got {list(flags)}")
    if np.any(flags & ~declared):
        raise ValueError(f"periodic {list(flags)}: the reference robot has non-periodic joints {list(declared)}")
    return [bool(v) for v in flags]


def quadrature(robot, options):
    """The spec's quadrature as keyword options of rhs, output and init.

    Parameters
    ----------
    robot : reference robot
    options : codegen.core.options.QuadratureOptions

    Returns
    -------
    dict
        N, periodic (checked by ``check_periodic``), N_period.
    """
    return dict(N=options.N, periodic=check_periodic(robot, options.periodic), N_period=options.N_period)


def configure(robot, options):
    """This family bound to the spec's quadrature (see ``quadrature``): ``options`` a
    codegen.core.options.QuadratureOptions, its periodic joints checked against ``robot``."""
    return bound(__name__, **quadrature(robot, options))
