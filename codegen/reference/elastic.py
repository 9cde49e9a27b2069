"""Reference elastic-joint robots (SPEC §6) in numpy, with exact derivatives by hyper-dual numbers.

Not an observer family (no ``rhs``): the reference families ``ciccarella_germani``, ``tomei``
and the Spong controllers build on it. Never imports CasADi or the symbolic code.

Rigid part, rebuilt from ``source["rigid"]``:
  * ``kind == "dh"``: :class:`DHRobot`, a Newton-Euler recursion on the DH table written with
    generic arithmetic, so it runs on floats and on :class:`HyperDual` arrays. M(q) comes from
    the same recursion (column j = RNEA(q, 0, e_j) without gravity), not from the CoM
    Jacobians of ``models.dh`` -- a second, independent derivation.
  * otherwise (``closed_form``, ``urdf``): ``robots.reference_robot`` (floats only).

Hyper-dual numbers a + b e1 + c e2 + d e1 e2 (e1^2 = e2^2 = 0) give, for an analytic F
evaluated at x + e1 u + e2 w, the exact (no truncation error) F(x), DF[u], DF[w], D^2F[u, w].
This is what the Ciccarella-Germani Q(x) and Spong's F(x) need (SPEC §8.3, §9):

    y3 = -M^{-1}(c + g + K(x1 - x3)) = FD(x1, x2, -K(x1 - x3))          (c includes F q1')
    y4 = D y3 [f(x)]
    dy4/dx_j = D^2 y3 [f, e_j] + D y3 [df/dx_j]
"""
from __future__ import annotations

import numpy as np

from .robots import reference_robot as _rigid_reference_robot


# ============================================================================ hyper-dual arrays
class HyperDual:
    """Array of hyper-dual numbers: parts ``a`` (value), ``b`` (e1), ``c`` (e2), ``d`` (e1 e2)."""

    __array_priority__ = 100

    def __init__(self, a, b=None, c=None, d=None):
        # parts are float arrays; the type test skips np.asarray on the hot path (speed only)
        self.a = a if type(a) is np.ndarray and a.dtype == np.float64 else np.asarray(a, dtype=float)
        z = None
        if b is None or c is None or d is None:
            z = np.zeros(self.a.shape)
        self.b = z if b is None else b if type(b) is np.ndarray else np.asarray(b, dtype=float)
        self.c = z if c is None else c if type(c) is np.ndarray else np.asarray(c, dtype=float)
        self.d = z if d is None else d if type(d) is np.ndarray else np.asarray(d, dtype=float)

    @staticmethod
    def lift(v):
        return v if isinstance(v, HyperDual) else HyperDual(v)

    def parts(self):
        return self.a, self.b, self.c, self.d

    shape = property(lambda self: self.a.shape)
    T = property(lambda self: HyperDual(*(p.T for p in self.parts())))

    def __getitem__(self, k):
        return HyperDual(*(p[k] for p in self.parts()))

    def __neg__(self):
        return HyperDual(*(-p for p in self.parts()))

    def __add__(self, o):
        o = HyperDual.lift(o)
        return HyperDual(*(p + q for p, q in zip(self.parts(), o.parts())))

    __radd__ = __add__

    def __sub__(self, o):
        return self + (-HyperDual.lift(o))

    def __rsub__(self, o):
        return HyperDual.lift(o) - self

    @staticmethod
    def _product(x, y, op):
        return HyperDual(op(x.a, y.a), op(x.a, y.b) + op(x.b, y.a), op(x.a, y.c) + op(x.c, y.a),
                         op(x.a, y.d) + op(x.b, y.c) + op(x.c, y.b) + op(x.d, y.a))

    def __mul__(self, o):
        return HyperDual._product(self, HyperDual.lift(o), np.multiply)

    __rmul__ = __mul__

    def __matmul__(self, o):
        return HyperDual._product(self, HyperDual.lift(o), np.matmul)

    def __rmatmul__(self, o):
        return HyperDual._product(HyperDual.lift(o), self, np.matmul)

    def __truediv__(self, o):
        if isinstance(o, HyperDual):
            raise NotImplementedError("division by a hyper-dual number is not needed here")
        return HyperDual(*(p / o for p in self.parts()))


def _unary(x, f, df, d2f):
    if not isinstance(x, HyperDual):
        return f(x)
    f1, f2 = df(x.a), d2f(x.a)
    return HyperDual(f(x.a), f1 * x.b, f1 * x.c, f1 * x.d + f2 * x.b * x.c)


def sin(x):
    return _unary(x, np.sin, np.cos, lambda a: -np.sin(a))


def cos(x):
    return _unary(x, np.cos, lambda a: -np.sin(a), lambda a: -np.cos(a))


def stack(items, axis=0):
    """np.stack for a mix of floats and hyper-duals."""
    if not any(isinstance(i, HyperDual) for i in items):
        return np.stack([np.asarray(i, dtype=float) for i in items], axis=axis)
    items = [HyperDual.lift(i) for i in items]
    return HyperDual(*(np.stack([getattr(i, k) for i in items], axis=axis) for k in "abcd"))


def cross(u, v):
    """u x v for 3-vectors (floats or hyper-duals)."""
    return stack([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]])


def dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def solve(A, y):
    """A^{-1} y, parts by differentiating A x = y twice."""
    if not isinstance(A, HyperDual) and not isinstance(y, HyperDual):
        return np.linalg.solve(A, y)
    A, y = HyperDual.lift(A), HyperDual.lift(y)
    xa = np.linalg.solve(A.a, y.a)
    xb = np.linalg.solve(A.a, y.b - A.b @ xa)
    xc = np.linalg.solve(A.a, y.c - A.c @ xa)
    xd = np.linalg.solve(A.a, y.d - A.b @ xc - A.c @ xb - A.d @ xa)
    return HyperDual(xa, xb, xc, xd)


def seeded(x, u=None, w=None):
    """x + e1 u + e2 w."""
    z = np.zeros_like(np.asarray(x, dtype=float))
    return HyperDual(x, z if u is None else u, z if w is None else w)


# ============================================================================ DH robot (RNEA)
class DHRobot:
    """Revolute DH robot (SPEC §11.3, §11.4) by the Newton-Euler recursion in frame 0.

    Frame i: A_i = Rot_z(theta_i + q_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i); link i has
    mass m_i, CoM rc_i and inertia I_i (about the CoM) in frame i; gravity g0 in frame 0.
    """

    def __init__(self, source):
        self.name = source.get("name", "dh")
        self.dh = np.asarray(source["dh"], dtype=float)
        self.n = self.dh.shape[0]
        self.m = np.asarray(source["masses"], dtype=float)
        self.rc = np.asarray(source["coms"], dtype=float)
        self.I = np.asarray(source["inertias"], dtype=float)
        self.g0 = np.asarray(source["gravity"], dtype=float)
        self.F = np.diag(np.asarray(source.get("F", np.zeros(self.n)), dtype=float))

    def _frames(self, q):
        R, o = np.eye(3), np.zeros(3)
        out = [(R, o)]
        for i, (alpha, d, a, theta) in enumerate(self.dh):
            ct, st = cos(q[i] + theta), sin(q[i] + theta)
            cal = 0.0 if abs(np.cos(alpha)) < 1e-15 else np.cos(alpha)
            sal = 0.0 if abs(np.sin(alpha)) < 1e-15 else np.sin(alpha)
            Ri = stack([stack([ct, -st * cal, st * sal]), stack([st, ct * cal, -ct * sal]),
                        stack([0.0 * ct, 0.0 * ct + sal, 0.0 * ct + cal])])
            o = o + R @ stack([a * ct, a * st, 0.0 * ct + d])
            R = R @ Ri
            out.append((R, o))
        return out

    def rnea(self, q, v, a, gravity=True):
        """tau = M(q) a + C(q, v) v + g(q)  (Newton-Euler, all vectors in frame 0; no friction)."""
        fr = self._frames(q)
        w, wd = np.zeros(3), np.zeros(3)
        acc = -self.g0 if gravity else np.zeros(3)          # base acceleration trick
        links = []
        for i in range(self.n):
            z = fr[i][0][:, 2]
            R, o = fr[i + 1]
            wd = wd + z * a[i] + cross(w, z * v[i])
            w = w + z * v[i]
            r = o - fr[i][1]
            acc = acc + cross(wd, r) + cross(w, cross(w, r))          # origin of frame i
            rc = R @ self.rc[i]
            ac = acc + cross(wd, rc) + cross(w, cross(w, rc))         # CoM of link i
            Iw = R @ self.I[i] @ R.T
            links.append((z, fr[i][1], o + rc, ac, w, wd, Iw))
        f, mu, tau = np.zeros(3), np.zeros(3), [None] * self.n
        for i in range(self.n - 1, -1, -1):              # mu: moment about o_{i-1} (joint i axis)
            z, o_prev, pc, ac, w, wd, Iw = links[i]
            fi = self.m[i] * ac
            mu = (mu + cross(fr[i + 1][1] - o_prev, f) + cross(pc - o_prev, fi)
                  + Iw @ wd + cross(w, Iw @ w))
            f = f + fi
            tau[i] = dot(z, mu)
        return stack(tau)

    def M(self, q):
        cols = [self.rnea(q, np.zeros(self.n), e, gravity=False) for e in np.eye(self.n)]
        return stack(cols, axis=1)

    def g(self, q):
        z = np.zeros(self.n)
        return self.rnea(q, z, z)

    def nle(self, q, v):
        return self.rnea(q, v, np.zeros(self.n))

    def forward_dynamics(self, q, v, tau):
        """M^{-1}(tau - C v - F v - g)."""
        return solve(self.M(q), tau - self.nle(q, v) - self.F @ v)


def reference_rigid(source):
    """Reference rigid robot of a ``robot.source`` dict (DH here, the others via robots.py)."""
    if source.get("kind") == "dh":
        return DHRobot(source)
    return _rigid_reference_robot(source)


# ============================================================================ elastic robot
class ElasticRobot:
    """Elastic-joint robot x = [q1; q1'; q2; q2'] (SPEC §6) over a reference rigid robot."""

    def __init__(self, source):
        if source.get("kind") != "elastic":
            raise ValueError(f"not an elastic robot source: kind {source.get('kind')!r}")
        self.name = source.get("name", "elastic")
        self.rigid = reference_rigid(source["rigid"])
        self.n = self.rigid.n
        self.nx = 4 * self.n
        self.J = np.diag(np.asarray(source["J"], dtype=float))
        self.K = np.diag(np.asarray(source["K"], dtype=float))
        self.Jinv = np.linalg.inv(self.J)
        self.exact = isinstance(self.rigid, DHRobot)   # hyper-dual derivatives available

    def split(self, x):
        n = self.n
        return x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n:]

    def M(self, q):
        return self.rigid.M(q)

    def y3(self, x):
        """q1'' = FD(x1, x2, -K(x1 - x3))  [S004 (2.8)]; x may be hyper-dual."""
        x1, x2, x3, _ = self.split(x)
        return self.rigid.forward_dynamics(x1, x2, -(self.K @ (x1 - x3)))

    def f(self, x):
        """Drift f(x)  [S004 (2.8)-(2.11)]."""
        x1, x2, x3, x4 = self.split(x)
        return np.concatenate([x2, self.y3(x), x4, self.Jinv @ self.K @ (x1 - x3)])

    def G(self):
        return np.vstack([np.zeros((3 * self.n, self.n)), self.Jinv])

    def xdot(self, x, u):
        return self.f(x) + self.G() @ u

    # --------------------------------------------------- Spong coordinates and derivatives
    def _Dy3(self, x, d):
        """D y3(x)[d] (directional derivative; only the first 3n entries of d matter)."""
        if self.exact:
            return self.y3(seeded(x, d)).b
        return self._Dy3_pin(x, d)

    def _Dy3_pin(self, x, d):
        """D y3 by pinocchio's analytic ABA derivatives (URDF robots): exact first order."""
        rob = self.rigid
        pin = rob._pin
        x1, x2, x3, _ = self.split(x)
        d1, d2, d3, _ = self.split(d)
        tau = -(self.K @ (x1 - x3)) - rob.F @ x2
        pin.computeABADerivatives(rob.model, rob.data, rob.pin_q(x1), x2, tau)
        dq, dv = np.array(rob.data.ddq_dq), np.array(rob.data.ddq_dv)
        Minv = np.array(rob.data.Minv)
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        return dq @ d1 + dv @ d2 + Minv @ (-(self.K @ (d1 - d3)) - rob.F @ d2)

    def y4(self, x):
        """q1''' = D y3 [f(x)] = f4(x1, x2, x3) + M^{-1} K x4  (SPEC §8.3)."""
        return self._Dy3(x, self.f(x))

    def spong_jacobian(self, x, fd_step=1e-5):
        """(Phi_levels, Q_levels): Phi = [x1; x2; y3; y4] (level-major) and dPhi/dx (4n x 4n).

        DH robots: exact by hyper-duals. URDF robots: rows of y4 by central differences of the
        exact (pinocchio first-order) y4, O(fd_step^2) [no second-order ABA derivatives]."""
        n, nx = self.n, self.nx
        fx = self.f(x)
        Q = np.zeros((nx, nx))
        Q[:2 * n, :2 * n] = np.eye(2 * n)
        if self.exact:
            # y3 does not depend on x4: its columns there are 0 (first and second order)
            d2 = np.zeros((n, nx))
            for j in range(3 * n):
                e = np.zeros(nx)
                e[j] = 1.0
                h = self.y3(seeded(x, fx, e))                     # D y3[f], D y3[e_j], D^2 y3[f, e_j]
                Q[2 * n:3 * n, j], d2[:, j] = h.c, h.d
            Dy3 = Q[2 * n:3 * n]
            for j in range(nx):   # d y4/dx_j = D^2 y3[f, e_j] + D y3[df/dx_j], D y3 linear: Dy3 @ .
                e = np.zeros(nx)
                e[j] = 1.0
                df = np.concatenate([e[n:2 * n], Dy3[:, j], e[3 * n:], self.Jinv @ self.K @ (e[:n] - e[2 * n:3 * n])])
                Q[3 * n:, j] = d2[:, j] + Dy3 @ df
        else:
            for j in range(nx):
                e = np.zeros(nx)
                e[j] = 1.0
                Q[2 * n:3 * n, j] = self._Dy3(x, e)
                Q[3 * n:, j] = (self.y4(x + fd_step * e) - self.y4(x - fd_step * e)) / (2 * fd_step)
        x1, x2, _, _ = self.split(x)
        return np.concatenate([x1, x2, self.y3(x), self.y4(x)]), Q

    def spong_F(self, x):
        """F(x) = L_f y4 (SPEC §9): y4' = F(x) + M^{-1} K J^{-1} u."""
        _, Q = self.spong_jacobian(x)
        return Q[3 * self.n:] @ self.f(x)


def reference_elastic(source):
    """ElasticRobot of an elastic ``robot.source`` dict."""
    return ElasticRobot(source)


def reference_observer(spec, dt=1e-3, method="rk4", substeps=1, hold="zoh"):
    """Kept for callers of the first version: the generic ``codegen.reference.reference_observer``
    now dispatches elastic/DH robots and the CG variant itself."""
    from . import reference_observer as generic
    return generic(spec, dt=dt, method=method, substeps=substeps, hold=hold)
