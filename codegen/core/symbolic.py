"""CasADi helpers shared by observer families and the gain design: quadrature, structured
solves, Lie derivatives and a few mechanics helpers.

Self-contained sections; each one only uses casadi and numpy (the mechanics helpers take any
robot with ``n``, ``mass_matrix(q)`` and ``coriolis(q, v)``, e.g. a models.RobotModel).
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np


# ============================================================================ shared routines
def routine(name, inputs, outputs):
    """A Function that stays one routine in generated C (common subexpressions eliminated).

    Calling it on SX makes a call node instead of inlining its body (``never_inline``), so
    CasADi's code generator emits the body once however often it is called, and forward AD
    through the calls emits one forward-derivative routine.

    Parameters
    ----------
    name : str
        Name of the routine (C comment and CasADi name).
    inputs : list of SX or MX
        Pure symbols.
    outputs : list of SX or MX
        Expressions of ``inputs``.

    Returns
    -------
    casadi.Function
    """
    return ca.Function(name, inputs, [ca.cse(o) for o in outputs], {"never_inline": True})


# ============================================================================ quadrature
@lru_cache(maxsize=64)
def gauss_legendre(N):
    """Nodes t_k and weights w_k of the N-point Gauss-Legendre rule on [-1, 1].

    Exact for polynomials of degree <= 2N - 1. Returned as read-only float64 arrays."""
    if int(N) != N or N < 1:
        raise ValueError(f"N (quadrature nodes) must be a positive integer, got {N!r}")
    t, w = np.polynomial.legendre.leggauss(int(N))
    t.setflags(write=False)
    w.setflags(write=False)
    return t, w


def _node_sum(f, i, x, shared, sigma, weights):
    """sum_k weights_k f(x with x_i = sigma_k, *shared) (MX): one serial map over the nodes."""
    K = sigma.numel()
    X = ca.repmat(x, 1, K)
    X[i, :] = ca.reshape(sigma, 1, K)
    body = f.map(f"{f.name()}_map{K}", "serial", K, list(range(1, f.n_in())), [])
    return ca.mtimes(body(X, *shared), weights)


def _line_symbols(f):
    return ca.MX.sym("x", f.sparsity_in(0)), [ca.MX.sym(f"s{j}", f.sparsity_in(j)) for j in range(1, f.n_in())]


@lru_cache(maxsize=256)
def gauss_legendre_routine(f, i, N):
    """Routine (b, x, *shared) -> int_0^b f(x with x_i = sigma, *shared) d sigma by the N-node
    Gauss-Legendre rule, one loop over the nodes in C (CasADi map, serial): the C holds it once
    whatever N, and forward AD through it one loop over f's forward derivative.

        int_0^b g(sigma) d sigma  ~=  sum_k h_k g(sigma_k),  sigma_k = b/2 (1 + t_k),  h_k = b/2 w_k

    with (t_k, w_k) = ``gauss_legendre(N)``: the integrals of beta [S003 (12)].

    Parameters
    ----------
    f : casadi.Function (x, *shared) -> column, the integrand; x (n,) is its first input
    i : int, the entry of x replaced by sigma (0 <= i < n)
    N : int, number of nodes

    Returns
    -------
    casadi.Function (b, x, *shared) -> integral (f's output shape); b (scalar) may be symbolic."""
    b = ca.MX.sym("b")
    x, shared = _line_symbols(f)
    t, w = gauss_legendre(N)
    total = _node_sum(f, i, x, shared, 0.5 * b * (1 + ca.DM(t)), 0.5 * b * ca.DM(w))
    return routine(f"{f.name()}_gauss{N}_{i}", [b, x, *shared], [total])


@lru_cache(maxsize=256)
def trapezoid_routine(f, i, N, period=2 * np.pi, start=-np.pi):
    """Routine (x, *shared) -> int over [start, start + period] of f(x with x_i = sigma, *shared)
    d sigma by the trapezoidal rule with N equispaced nodes, one loop in C (as
    ``gauss_legendre_routine``):

        int f d sigma  ~=  (period / N) sum_k f(start + k period / N),   k = 0 .. N-1.

    For an analytic periodic f it converges geometrically, like exp(-N d) with d the
    half-width of the strip of analyticity: faster than Gauss-Legendre with N nodes on the
    same interval (docs/quadrature.md).

    Parameters
    ----------
    f : casadi.Function (x, *shared) -> column, periodic in x_i; x (n,) is its first input
    i : int, the entry of x replaced by sigma (0 <= i < n)
    N : int, number of nodes (positive)
    period, start : float, length and left end of the interval [rad for a revolute joint]

    Returns
    -------
    casadi.Function (x, *shared) -> integral over the interval (f's output shape)."""
    if int(N) != N or N < 1:
        raise ValueError(f"N (trapezoid nodes) must be a positive integer, got {N!r}")
    N, h = int(N), float(period) / int(N)
    x, shared = _line_symbols(f)
    total = _node_sum(f, i, x, shared, ca.DM([start + k * h for k in range(N)]), ca.DM.ones(N, 1) * h)
    return routine(f"{f.name()}_trapezoid{N}_{i}", [x, *shared], [total])


def wrap_angle(y, period=2 * np.pi):
    """(m, rho) with y = m period + rho, m = floor(y / period + 1/2) an integer (piecewise
    constant: zero derivative a.e.) and rho in [-period/2, period/2). y may be SX."""
    m = ca.floor(y / period + 0.5) if isinstance(y, (ca.SX, ca.MX)) else np.floor(y / period + 0.5)
    return m, y - period * m


# ============================================================================ structured solves
def ldl_solve(M, B):
    """X = M^{-1} B for a symmetric positive-definite M by an unpivoted LDL^T factorisation.

    Written out entry by entry, so an SX M gives ~n^3/6 + n^2 (cols of B) operations and no
    square roots (leaner than a generic symbolic QR solve). Structural zeros of M are kept."""
    n = M.shape[0]
    if M.shape != (n, n) or B.shape[0] != n:
        raise ValueError(f"ldl_solve: M must be square and B have {n} rows, got {M.shape}, {B.shape}")
    L = [[None] * n for _ in range(n)]
    D = [None] * n
    for j in range(n):
        d = M[j, j]
        for k in range(j):
            d = d - L[j][k] * L[j][k] * D[k]
        D[j] = d
        for i in range(j + 1, n):
            s = M[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k] * D[k]
            L[i][j] = s / d
    cols = []
    for c in range(B.shape[1]):
        z = [B[i, c] for i in range(n)]
        for i in range(n):                      # L z = b
            for k in range(i):
                z[i] = z[i] - L[i][k] * z[k]
        z = [z[i] / D[i] for i in range(n)]     # D
        for i in range(n - 1, -1, -1):          # L^T x = z
            for k in range(i + 1, n):
                z[i] = z[i] - L[k][i] * z[k]
        cols.append(ca.vertcat(*z))
    return ca.horzcat(*cols)


def chol_lower(A):
    """Lower-triangular L with A = L L^T (symmetric positive-definite A), entry by entry."""
    n = A.shape[0]
    L = [[0] * n for _ in range(n)]
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d = d - L[j][k] * L[j][k]
        L[j][j] = ca.sqrt(d)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    return ca.vertcat(*[ca.horzcat(*L[i]) for i in range(n)])


def householder_tridiagonal(B):
    """Tridiagonal T = Q^T B Q of a symmetric SX ``B`` (n, n) by n - 2 Householder reflections
    (Golub & Van Loan, Matrix Computations, 4th ed., Algorithm 8.3.1), entry by entry on the lower
    triangle: Q = H_0 H_1 ... H_(n-3), H_k = I - beta_k v_k v_k^T acting on rows k+1..n-1, with
    v_k = x + sign(x_0) ||x|| e_1 of the column below the diagonal x = B_(k+1:, k) (so
    beta_k = 1 / (||x|| (||x|| + |x_0|)), no cancellation). A column already zero (a joint
    decoupled from the rest) gets H_k = I: beta_k = 0, its square root taken of 1, so the
    expression and its derivatives stay finite there.

    Returns
    -------
    (diag (n,) list, sub (n - 1,) list, reflections): T's diagonal and sub-diagonal as SX scalars
    and [(k + 1, v_k list, beta_k)] for ``apply_reflections``."""
    n = B.shape[0]
    A = [[B[i, j] for j in range(i + 1)] for i in range(n)]        # lower triangle, A[i][j], j <= i

    def at(i, j):
        return A[i][j] if j <= i else A[j][i]
    sub, reflections = [], []
    for k in range(n - 2):
        x = [at(i, k) for i in range(k + 1, n)]
        s2 = sum(xi * xi for xi in x[1:]) + x[0] * x[0]
        some = s2 > 0
        norm = ca.sqrt(ca.if_else(some, s2, 1))
        sign = ca.if_else(x[0] >= 0, 1, -1)
        v = [x[0] + sign * norm] + x[1:]
        beta = ca.if_else(some, 1 / (norm * (norm + ca.fabs(x[0]))), 0)
        rows = range(k + 1, n)
        # B22 <- H B22 H = B22 - v w^T - w v^T, w = p - (beta/2) (v^T p) v, p = beta B22 v
        pv = [beta * sum(at(i, j) * v[j - k - 1] for j in rows) for i in rows]
        half = 0.5 * beta * sum(a * b for a, b in zip(v, pv))
        w = [pi - half * vi for pi, vi in zip(pv, v)]
        for i in rows:
            for j in range(k + 1, i + 1):
                A[i][j] = A[i][j] - v[i - k - 1] * w[j - k - 1] - w[i - k - 1] * v[j - k - 1]
        sub.append(ca.if_else(some, -sign * norm, 0))
        reflections.append((k + 1, v, beta))
    if n >= 2:
        sub.append(A[n - 1][n - 2])
    return [A[i][i] for i in range(n)], sub, reflections


def apply_reflections(reflections, u, transpose=False):
    """Q u (or Q^T u with ``transpose``) of ``householder_tridiagonal``'s reflections, u an (n,)
    list of SX scalars: each H_k u = u - beta_k v_k (v_k^T u) on rows k+1.., in turn (Q^T:
    H_0 first)."""
    u = list(u)
    for start, v, beta in (reflections if transpose else reversed(reflections)):
        c = beta * sum(vi * ui for vi, ui in zip(v, u[start:]))
        u[start:] = [ui - c * vi for ui, vi in zip(u[start:], v)]
    return u


def tridiagonal_factors(diag, sub, p):
    """The LDL^T factors of I + p T, T symmetric tridiagonal (``diag`` (n,), ``sub`` (n - 1,)
    lists of SX), I + p T positive definite (T positive semi-definite, p > 0), without pivoting:
    d_0 = 1 + p T_00, l_i = p T_i,i-1 / d_i-1, d_i = 1 + p T_ii - l_i p T_i,i-1 (n divisions).
    Returns (1/d (n,), l (n,) with l[0] None) for ``tridiagonal_solve``."""
    n = len(diag)
    inv, low = [None] * n, [None] * n
    inv[0] = 1 / (1 + p * diag[0])
    for i in range(1, n):
        off = p * sub[i - 1]
        low[i] = off * inv[i - 1]
        inv[i] = 1 / (1 + p * diag[i] - low[i] * off)
    return inv, low


def tridiagonal_solve(inv, low, columns):
    """W = (L D L^T)^-1 U from ``tridiagonal_factors``' inverse pivots ``inv`` (1/d) and multipliers
    ``low`` (l) for each of ``columns`` (the columns of U, each an (n,) list of SX): forward, diagonal
    and backward substitution, 5n operations a column, no division."""
    n = len(inv)
    out = []
    for u in columns:
        z = list(u)
        for i in range(1, n):
            z[i] = z[i] - low[i] * z[i - 1]
        w = [zi * di for zi, di in zip(z, inv)]
        for i in range(n - 2, -1, -1):
            w[i] = w[i] - low[i + 1] * w[i + 1]
        out.append(w)
    return out


# ============================================================================ Lie derivatives and
# observability coordinates (Ciccarella-Germani, Spong; docs/papers/seed004.md §8.1, §9) -- seed-004 section
def lie_derivative(h, x, f, k=1):
    """L_f^k h = d(L_f^{k-1} h)/dx f(x) (k >= 0) by forward-mode AD (jtimes)  [S004 (A.2)]."""
    for _ in range(int(k)):
        h = ca.jtimes(h, x, f)
    return h


def lie_chain(h, x, f, r):
    """[h, L_f h, ..., L_f^r h]: r + 1 column vectors (each L_f^{k+1} h from L_f^k h by one
    jtimes)  [S004 (A.2)]: h SX (m,) output(s) of the state symbols x SX (n,), f SX (n,) the
    drift f(x), r >= 0 the highest order. Returns a list of r + 1 SX (m,)."""
    out = [h]
    for _ in range(int(r)):
        out.append(ca.jtimes(out[-1], x, f))
    return out


def input_lie_derivative(h, x, G):
    """L_G h = dh/dx G(x): the row(s) of the decoupling matrix when h = L_f^{r-1} h_i."""
    return ca.mtimes(ca.jacobian(h, x), G)


def observability_map(outputs, degrees, x, f):
    """Phi(x) = [h_1, ..., L_f^{r1-1} h_1, ..., h_m, ..., L_f^{rm-1} h_m] (channel-major) and the
    list of top derivatives [L_f^{r_i} h_i]  [S004 (3.5)-(3.8)].

    Parameters
    ----------
    outputs : list of m scalar SX, the outputs h_i(x);  degrees : list of m int, the r_i
    x : SX (n,) state symbols;  f : SX (n,) drift f(x)

    Returns
    -------
    (Phi SX (r_1 + ... + r_m,), tops SX (m,) with tops_i = L_f^{r_i} h_i)."""
    if len(outputs) != len(degrees):
        raise ValueError(f"{len(outputs)} outputs but {len(degrees)} relative degrees")
    rows, tops = [], []
    for h, r in zip(outputs, degrees):
        chain = lie_chain(h, x, f, r)
        rows += chain[:r]
        tops.append(chain[r])
    return ca.vertcat(*rows), ca.vertcat(*tops)


def decoupling_matrix(outputs, degrees, x, f, G):
    """U(x) with rows L_G L_f^{r_i - 1} h_i  [S004 (A.8)].

    Parameters
    ----------
    outputs : list of m scalar SX, the outputs h_i(x);  degrees : list of m int, the r_i >= 1
    x : SX (n,) state symbols;  f : SX (n,) drift f(x);  G : SX (n, k) input matrix G(x)

    Returns
    -------
    SX (m, k)"""
    return ca.vertcat(*[input_lie_derivative(lie_derivative(h, x, f, r - 1), x, G)
                        for h, r in zip(outputs, degrees)])


def check_relative_degree(outputs, degrees, x, f, G, states, tol=1e-9):
    """Numerical check of the vector relative degree at sampled ``states`` (rows):
    L_G L_f^k h_i = 0 for k < r_i - 1 and U(x) nonsingular [S004 (A.8)]. Returns the smallest
    singular value of U seen (relative to its largest); raises ValueError naming the failing
    channel.

    Parameters
    ----------
    outputs, degrees, x, f, G : as in ``decoupling_matrix``
    states : array (s, n) or (n,), sample states (rows)
    tol : float, threshold of a nonzero L_G L_f^k h_i and (relative) of sigma_min(U)"""
    worst = np.inf
    lower = [(i, k, ca.Function("lg", [x], [input_lie_derivative(lie_derivative(h, x, f, k), x, G)]))
             for i, (h, r) in enumerate(zip(outputs, degrees)) for k in range(r - 1)]
    U = ca.Function("U", [x], [decoupling_matrix(outputs, degrees, x, f, G)])
    for s in np.atleast_2d(states):
        for i, k, fun in lower:
            v = np.abs(np.array(fun(s))).max(initial=0.0)
            if v > tol:
                raise ValueError(f"output {i}: L_G L_f^{k} h = {v:.3g} != 0, relative degree < {k + 1}")
        sv = np.linalg.svd(np.array(U(s)), compute_uv=False)
        if sv.size == 0 or sv[-1] <= tol * max(sv[0], 1.0):
            raise ValueError(f"decoupling matrix U(x) singular at x = {np.array2string(s, precision=3)}")
        worst = min(worst, sv[-1] / sv[0])
    return worst


def lower_block_structure(Q, row_blocks, col_blocks):
    """True when Q (rows/cols split in the given block sizes) is structurally block lower
    triangular with square diagonal blocks (upper blocks all structural zeros). Q: SX (n, n);
    row_blocks, col_blocks: block sizes of its rows and columns (each summing to n)."""
    if sum(row_blocks) != Q.shape[0] or sum(col_blocks) != Q.shape[1] or row_blocks != col_blocks:
        return False
    r0 = np.cumsum([0] + list(row_blocks))
    for a in range(len(row_blocks)):
        for b in range(a + 1, len(col_blocks)):
            if Q[r0[a]:r0[a + 1], r0[b]:r0[b + 1]].nnz() > 0:
                return False
    return True


def _is_identity(A):
    if not A.is_constant() or A.shape[0] != A.shape[1]:
        return False
    return bool(np.array_equal(np.array(ca.DM(A)), np.eye(A.shape[0])))


def qr_solve_guarded(A, b, rcond_min):
    """x = A^{-1} b by Gram-Schmidt QR and back substitution; x is NaN when the cheap
    conditioning estimate min|R_ii| / max|R_ii| falls below ``rcond_min`` (may be SX)."""
    Qf, R = ca.qr(A)
    z = ca.mtimes(Qf.T, b)
    n = A.shape[0]
    xs = [None] * n
    for i in range(n - 1, -1, -1):
        s = z[i]
        for k in range(i + 1, n):
            s = s - R[i, k] * xs[k]
        xs[i] = s / R[i, i]
    d = [ca.fabs(R[i, i]) for i in range(n)]
    dmin, dmax = d[0], d[0]
    for v in d[1:]:
        dmin, dmax = ca.fmin(dmin, v), ca.fmax(dmax, v)
    ok = dmin >= rcond_min * dmax
    return ca.if_else(ok, ca.vertcat(*xs), ca.SX.nan(n, 1) if isinstance(A, ca.SX) else np.nan)


def block_forward_substitution(Q, v, blocks, rcond_min):
    """w = Q^{-1} v for a block lower-triangular Q (``blocks`` = diagonal block sizes):

        w_a = Q_aa^{-1} (v_a - sum_{b<a} Q_ab w_b)

    structurally-identity pivots are skipped; the others go through ``qr_solve_guarded`` with
    threshold ``rcond_min`` (w is NaN below it): the Q(xhat)^{-1} of [S004 (3.10)].
    Q: SX (n, n); v: SX (n,); returns w SX (n,)."""
    r0 = np.cumsum([0] + list(blocks))
    ws = []
    for a in range(len(blocks)):
        sl = slice(int(r0[a]), int(r0[a + 1]))
        rhs = v[sl]
        for b in range(a):
            Qab = Q[sl, int(r0[b]):int(r0[b + 1])]
            if Qab.nnz():
                rhs = rhs - ca.mtimes(Qab, ws[b])
        Qaa = Q[sl, sl]
        ws.append(rhs if _is_identity(Qaa) else qr_solve_guarded(Qaa, rhs, rcond_min))
    return ca.vertcat(*ws)



def block_forward_substitution_jvp(phi_blocks, x, col_blocks, v_blocks, rcond_min):
    """w = Q^{-1} v for Q = dPhi/dx block lower triangular (Phi split in ``phi_blocks``, x in
    ``col_blocks`` of the same sizes), without forming the off-diagonal blocks:

        w_a = Q_aa^{-1} (v_a - dPhi_a/dx [w_1; ...; w_{a-1}; 0])

    the bracket is one forward-mode directional derivative (jtimes); Q_aa = dPhi_a/dx_a is
    skipped when structurally the identity and otherwise solved by ``qr_solve_guarded``
    [S004 (3.10)].

    Parameters
    ----------
    phi_blocks : list of SX, the blocks Phi_a(x);  x : SX (n,) state symbols
    col_blocks : sequence of int, block sizes of x (summing to n)
    v_blocks : list of SX, the blocks v_a of the right-hand side (sizes ``col_blocks``)
    rcond_min : float or SX, conditioning threshold of each pivot solve (w NaN below it)

    Returns
    -------
    w SX (n,)"""
    c0 = np.cumsum([0] + list(col_blocks))
    ws = []
    for a, (phi, v) in enumerate(zip(phi_blocks, v_blocks)):
        rhs = v
        if a:
            seed = ca.vertcat(*ws, ca.SX.zeros(int(c0[-1] - c0[a]), 1))
            rhs = rhs - ca.jtimes(phi, x, seed)
        xa = x[int(c0[a]):int(c0[a + 1])]
        Qaa = ca.jacobian(phi, xa)
        ws.append(rhs if _is_identity(Qaa) else qr_solve_guarded(Qaa, rhs, rcond_min))
    return ca.vertcat(*ws)


def block_lower_by_dependence(phi_blocks, x, col_blocks):
    """True when block a of Phi does not depend on the x blocks after a (block lower triangular
    dPhi/dx) and every diagonal block is square: the precondition of
    ``block_forward_substitution_jvp`` (phi_blocks, x, col_blocks as there)."""
    if [b.numel() for b in phi_blocks] != list(col_blocks) or sum(col_blocks) != x.numel():
        return False
    c0 = np.cumsum([0] + list(col_blocks))
    return not any(ca.depends_on(phi, x[int(c0[a + 1]):]) for a, phi in enumerate(phi_blocks)
                   if c0[a + 1] < c0[-1])


# ============================================================================ mechanics helpers
def christoffel_column_matrix(robot, q, i):
    """C(q, e_i) (n x n): by the symmetry C(q, x) e_i = C(q, e_i) x [S003 P2] it gives column i
    of C(q, x) for every x at the cost of one Christoffel evaluation. robot: RobotModel (n
    joints); q: SX or DM (n,) configuration [rad or m]; i: the unit direction (0 <= i < n)."""
    e = ca.DM.zeros(robot.n, 1)
    e[i] = 1.0
    return robot.coriolis(q, e)


def christoffel_slices(robot, q):
    """[C(q, e_1) ... C(q, e_n)] (n x n^2): the 3-tensor C_ijk(q) = C(q, e_k)_ij side by side,
    for a robot (RobotModel, n joints) at q (SX or DM (n,), [rad or m])."""
    return ca.horzcat(*[christoffel_column_matrix(robot, q, k) for k in range(robot.n)])


def cholesky_velocity(robot, q):
    """(M, T, T^{-1}) at q: M^{-1} = T T^T with T lower-triangular, T^{-1} = T^T M  [docs/papers/seed003.md §5].

    T^{-1} is the lower-triangular factor of M = T^{-T} T^{-1} (``reversed_cholesky``) and T its
    triangular inverse (``lower_inverse``): no inverse of M, ~n^3/3 operations.

    Parameters
    ----------
    robot : RobotModel (n joints)
    q : SX (n,) configuration [rad or m]

    Returns
    -------
    (M (n, n), T (n, n), T^{-1} (n, n)) as SX; pbar = T^{-1} qd is the Cholesky velocity."""
    Mq = robot.mass_matrix(q)
    Tinv = reversed_cholesky(Mq)
    return Mq, lower_inverse(Tinv), Tinv


def reversed_cholesky(A):
    """Lower-triangular L with A = L^T L (A symmetric positive-definite): the Cholesky factor of
    A with rows and columns in reverse order, J chol_lower(J A J)^T J, J the exchange matrix."""
    n = A.shape[0]
    J = ca.DM(np.fliplr(np.eye(n)))
    return ca.mtimes(ca.mtimes(J, chol_lower(ca.mtimes(ca.mtimes(J, A), J)).T), J)


def lower_inverse(L):
    """L^{-1} of a lower-triangular L with non-zero diagonal (lower-triangular) by forward
    substitution, entry by entry: X_jj = 1/L_jj, X_ij = -sum_{j<=k<i} L_ik X_kj / L_ii."""
    n = L.shape[0]
    X = [[0] * n for _ in range(n)]
    for j in range(n):
        X[j][j] = 1 / L[j, j]
        for i in range(j + 1, n):
            s = 0
            for k in range(j, i):
                s = s - L[i, k] * X[k][j]
            X[i][j] = s / L[i, i]
    return ca.vertcat(*[ca.horzcat(*row) for row in X])


@lru_cache(maxsize=32)
def _skew_function(robot):
    """CasADi Function (q, b) -> S(q, b) of pure symbols (AD needs them), cached per robot."""
    n = robot.n
    q, v = ca.SX.sym("q", n), ca.SX.sym("v", n)
    _, T, Tinv = cholesky_velocity(robot, q)
    Tb = ca.mtimes(T, v)
    S = (-ca.mtimes(Tinv, ca.jtimes(T, q, Tb))
         - ca.mtimes(ca.mtimes(T.T, robot.coriolis(q, Tb)), T))
    return ca.Function("S", [q, v], [S])


def skew_S(robot, q, b):
    """S(q, b) = -T^T M Tdot(b) - T^T C(q, T b) T, Tdot(b) = sum_k dT/dq_k (T b)_k: the
    skew-symmetric Coriolis matrix in Cholesky velocities [DERIVED, docs/papers/seed003.md §5].

    Parameters
    ----------
    robot : RobotModel (n joints)
    q : SX or DM (n,) configuration [rad or m]
    b : SX or DM (n,) Cholesky velocity

    Returns
    -------
    S (n, n), with Cbar(q, a) b = S(q, b) a."""
    return _skew_function(robot)(q, b)
