"""Spatial algebra on 3-vectors for bodies in canonical (joint axis = z) frames.

Conventions. Spatial motion m = (v, w) (linear first, as pinocchio), forces f = (f, n).
A placement (R, p) maps child coordinates to parent ones: x_parent = R x_child + p, so
the motion transform parent -> child is  w' = R^T w,  v' = R^T (v - p x w)
and the force transform child -> parent is  f' = R f,  n' = R n + p x f'  (Featherstone 2.24).

A body's placement in its parent is a constant rotation E and translation r (python
floats, see ``models.tree``) followed by the joint motion: a rotation R_z(q) (revolute)
or a shift q e_z (prismatic). So the motion subspace is the constant S = e_wz or e_vz,
and transforms are applied as a constant rotation, a rotation about z and a cross product
on 3-vectors, never as dense 6x6 products; all scalar work folds constants through
``models.algebra``.
"""
from __future__ import annotations

from functools import cached_property

import casadi as ca

from models.algebra import add, cmtv, cmv, cross, dot, is_zero, mul, sub, sym3, symmap, vadd, vsub

__all__ = ["Rz", "csym", "cgen", "skew", "is_identity", "Inertia6", "RigidInertia", "JointX",
           "s_transpose", "add_s", "bias_acceleration", "rigid_force", "cross_force"]


# ------------------------------------------------------------------ rotation about z
class Rz:
    """Rotation R_z(q): c = cos q, s = sin q and the products s^2, c s, cos 2q, sin 2q.

    The 2x2 (xy) block of R X R^T is written as a correction of X:
    with e = x00 - x11, sigma = x01 + x10 (exact algebra, 4 mul per block)

        u = s^2 e + c s sigma,   x00' = x00 - u,   x11' = x11 + u,
        w = c s e - s^2 sigma,   x01' = x01 + w,   x10' = x10 + w.

    Parameters
    ----------
    q : casadi.SX scalar
        Joint angle (rad).
    """

    def __init__(self, q):
        self.c = ca.cos(q)
        self.s = ca.sin(q)

    @cached_property
    def ss(self):
        """s^2 = sin^2 q."""
        return self.s * self.s

    @cached_property
    def cs(self):
        """c s = cos q sin q."""
        return self.c * self.s

    @cached_property
    def c2(self):
        """cos 2q = (c - s)(c + s)."""
        return (self.c - self.s) * (self.c + self.s)

    @cached_property
    def s2(self):
        """sin 2q = 2 c s."""
        return self.cs + self.cs

    def apply(self, u):
        """R_z u."""
        c, s = self.c, self.s
        return (sub(mul(c, u[0]), mul(s, u[1])), add(mul(s, u[0]), mul(c, u[1])), u[2])

    def apply_T(self, u):
        """R_z^T u."""
        c, s = self.c, self.s
        return (add(mul(c, u[0]), mul(s, u[1])), sub(mul(c, u[1]), mul(s, u[0])), u[2])

    def sym(self, S):
        """R_z S R_z^T for a symmetric 3x3 S (4 mul, 5 add on the xy block)."""
        a, b, d = S[0][0], S[0][1], S[1][1]
        if not (is_zero(a) and is_zero(b) and is_zero(d)):
            e = sub(a, d)
            u = add(mul(self.ss, e), mul(self.s2, b))
            a, d = sub(a, u), add(d, u)
            b = add(mul(self.cs, e), mul(self.c2, b))
        v = self.apply((S[0][2], S[1][2], 0.0))
        return sym3(a, b, v[0], d, v[1], S[2][2])

    def gen(self, B):
        """R_z B R_z^T for a general 3x3 B (4 mul, 8 add on the xy block)."""
        b00, b01, b10, b11 = B[0][0], B[0][1], B[1][0], B[1][1]
        e, sig = sub(b00, b11), add(b01, b10)
        if not (is_zero(e) and is_zero(sig)):
            u = add(mul(self.ss, e), mul(self.cs, sig))
            w = sub(mul(self.cs, e), mul(self.ss, sig))
            b00, b11, b01, b10 = sub(b00, u), add(b11, u), add(b01, w), add(b10, w)
        col = self.apply((B[0][2], B[1][2], 0.0))
        row = self.apply((B[2][0], B[2][1], 0.0))
        return [[b00, b01, col[0]], [b10, b11, col[1]], [row[0], row[1], B[2][2]]]


# ------------------------------------------------------------------ constant rotations
def csym(E, S):
    """E S E^T for constant E and symmetric S (upper triangle only)."""
    T = [[dot(S[k], E[j]) for j in range(3)] for k in range(3)]          # T = S E^T
    out = [[None] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            out[i][j] = out[j][i] = dot(E[i], (T[0][j], T[1][j], T[2][j]))
    return out


def cgen(E, B):
    """E B E^T for constant E and general B."""
    T = [[dot(B[k], E[j]) for j in range(3)] for k in range(3)]
    return [[dot(E[i], (T[0][j], T[1][j], T[2][j])) for j in range(3)] for i in range(3)]


def skew(p):
    """[p]x, the cross-product matrix of p (rows)."""
    return ((0.0, mul(-1.0, p[2]), p[1]), (p[2], 0.0, mul(-1.0, p[0])),
            (mul(-1.0, p[1]), p[0], 0.0))


def is_identity(E):
    """True when the constant rotation E is exactly the identity."""
    return all(E[i][j] == (1.0 if i == j else 0.0) for i in range(3) for j in range(3))


# ------------------------------------------------------------------ spatial inertias
class Inertia6:
    """Symmetric 6x6 (articulated) inertia in blocks: f = A v + B w, n = B^T v + C w.

    Parameters
    ----------
    A, C : 3x3 symmetric nested lists of scalars
        Linear (kg) and rotational (kg m^2) blocks.
    B : 3x3 nested list of scalars
        Coupling block (kg m).
    """
    __slots__ = ("A", "B", "C")

    def __init__(self, A, B, C):
        self.A, self.B, self.C = A, B, C

    @classmethod
    def rigid(cls, b):
        """Rigid body: A = m 1, B = -[h]x, C = I_o  (Featherstone 2.63), from the
        ``models.tree.Body`` ``b`` (its mass, first moment h and inertia I_o about its origin)."""
        m, h = b.mass, b.h
        A = sym3(m, 0.0, 0.0, m, 0.0, m)
        B = [[0.0, h[2], -h[1]], [-h[2], 0.0, h[0]], [h[1], -h[0], 0.0]]
        C = [list(row) for row in b.Io]
        return cls(A, B, C)

    def times(self, v, w):
        """Force (A v + B w, B^T v + C w)."""
        f = tuple(add(dot(self.A[i], v), dot(self.B[i], w)) for i in range(3))
        n = tuple(add(dot((self.B[0][i], self.B[1][i], self.B[2][i]), v), dot(self.C[i], w))
                  for i in range(3))
        return f, n

    def column(self, k):
        """Column k of the 6x6 matrix as (f part, n part)."""
        if k < 3:
            return (tuple(self.A[i][k] for i in range(3)), tuple(self.B[k][i] for i in range(3)))
        k -= 3
        return (tuple(self.B[i][k] for i in range(3)), tuple(self.C[i][k] for i in range(3)))

    def add(self, other):
        """Sum of this inertia and ``other`` (an :class:`Inertia6` in the same frame)."""
        A = symmap(self.A, other.A, add)
        C = symmap(self.C, other.C, add)
        B = [[add(self.B[i][j], other.B[i][j]) for j in range(3)] for i in range(3)]
        return Inertia6(A, B, C)

    # transforms child -> parent: X^T I X
    def rotate_z(self, rz):
        """R_z I R_z^T block by block (``rz`` an :class:`Rz`)."""
        return Inertia6(rz.sym(self.A), rz.gen(self.B), rz.sym(self.C))

    def rotate_const(self, E):
        """E I E^T block by block for a constant rotation E."""
        if is_identity(E):
            return self
        return Inertia6(csym(E, self.A), cgen(E, self.B), csym(E, self.C))

    def translate(self, p):
        """Shift by p: A' = A, B' = B - A P, C' = C + P B + (P B)^T - P A P, P = [p]x."""
        if all(is_zero(x) for x in p):
            return self
        P = skew(p)
        G = [[dot(self.A[i], (P[0][j], P[1][j], P[2][j])) for j in range(3)]
             for i in range(3)]                                               # A P
        B = [[sub(self.B[i][j], G[i][j]) for j in range(3)] for i in range(3)]
        K = [[dot(P[i], (self.B[0][j], self.B[1][j], self.B[2][j])) for j in range(3)]
             for i in range(3)]                                               # P B
        C = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                PAP = dot(P[i], (G[0][j], G[1][j], G[2][j]))
                C[i][j] = C[j][i] = sub(add(self.C[i][j], add(K[i][j], K[j][i])), PAP)
        return Inertia6(self.A, B, C)


class RigidInertia:
    """Rigid-body (composite) inertia (m, h = m c, I_o) about the body origin.

    Parameters
    ----------
    m : float
        Mass (kg); constant, composite bodies only add masses.
    h : 3-tuple of scalars
        First moment of mass m c (kg m).
    Io : 3x3 symmetric nested list of scalars
        Rotational inertia about the body origin (kg m^2).
    """
    __slots__ = ("m", "h", "Io")

    def __init__(self, m, h, Io):
        self.m, self.h, self.Io = m, h, Io

    def add(self, o):
        """Sum of this rigid inertia and ``o`` in the same frame (the composite body)."""
        return RigidInertia(self.m + o.m, vadd(self.h, o.h), symmap(self.Io, o.Io, add))

    def rotate_z(self, rz):
        """h' = R_z h, I_o' = R_z I_o R_z^T (``rz`` an :class:`Rz`)."""
        return RigidInertia(self.m, rz.apply(self.h), rz.sym(self.Io))

    def rotate_const(self, E):
        """h' = E h, I_o' = E I_o E^T for a constant rotation E."""
        if is_identity(E):
            return self
        return RigidInertia(self.m, cmv(E, self.h), csym(E, self.Io))

    def translate(self, p):
        """h' = h + m p, I_o' = I_o - (h p^T + p h^T - 2 h.p 1) - m (p p^T - |p|^2 1)."""
        if all(is_zero(x) for x in p):
            return self
        h, m = self.h, self.m
        hp = dot(h, p)
        pp = dot(p, p)
        Io = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                t = add(mul(h[i], p[j]), mul(p[i], h[j]))
                t = add(t, mul(m, mul(p[i], p[j])))
                if i == j:
                    t = sub(t, add(mul(2.0, hp), mul(m, pp)))
                Io[i][j] = Io[j][i] = sub(self.Io[i][j], t)
        return RigidInertia(m, vadd(h, tuple(mul(m, x) for x in p)), Io)


# ------------------------------------------------------------------ joint transforms
class JointX:
    """Placement of body i in its parent: constant (E, r) then the joint motion (R_z or z-shift).

    Parameters
    ----------
    body : models.tree.Body
        The body (its constant E, r and joint kind).
    qi : casadi.SX scalar or float
        Joint coordinate (rad for revolute, m for prismatic).
    """

    def __init__(self, body, qi):
        self.b = body
        if body.kind == "R":
            self.rz = Rz(qi)
        else:
            self.rz = None
            self.dz = qi

    def motion_in(self, v, w):
        """Parent motion (v, w) expressed in the child:  w' = R^T w,  v' = R^T (v - p x w)."""
        b = self.b
        w_T = cmtv(b.E, w)
        v_T = cmtv(b.E, vsub(v, cross(b.r, w)))
        if self.rz is not None:
            return self.rz.apply_T(v_T), self.rz.apply_T(w_T)
        d = self.dz                                     # v' = v_T - (d e_z) x w_T
        return (add(v_T[0], mul(d, w_T[1])), sub(v_T[1], mul(d, w_T[0])), v_T[2]), w_T

    def force_out(self, f, n):
        """Child force (f, n) expressed in the parent:  f' = R f,  n' = R n + p x f'."""
        b = self.b
        if self.rz is not None:
            f, n = self.rz.apply(f), self.rz.apply(n)
        else:
            d = self.dz                                 # n += (d e_z) x f
            n = (sub(n[0], mul(d, f[1])), add(n[1], mul(d, f[0])), n[2])
        f = cmv(b.E, f)
        n = vadd(cmv(b.E, n), cross(b.r, f))
        return f, n

    def inertia_out(self, I):
        """X^T I X: a child inertia (articulated or rigid) expressed in the parent."""
        if self.rz is not None:
            I = I.rotate_z(self.rz)
        else:
            I = I.translate((0.0, 0.0, self.dz))
        return I.rotate_const(self.b.E).translate(self.b.r)

    def rotation(self):
        """The 3x3 rotation E R_z(q) (rows), for kinematics."""
        E = self.b.E
        if self.rz is None:
            return [list(row) for row in E]
        cols = [self.rz.apply(e) for e in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))]
        RzM = [[cols[j][i] for j in range(3)] for i in range(3)]
        return [[dot(E[i], (RzM[0][j], RzM[1][j], RzM[2][j])) for j in range(3)]
                for i in range(3)]

    def translation(self):
        """The 3-vector r + E (q e_z) (prismatic) or r (revolute), for kinematics."""
        b = self.b
        if self.rz is None:
            return vadd(b.r, cmv(b.E, (0.0, 0.0, self.dz)))
        return b.r


# ------------------------------------------------------------------ motion subspace, rigid bodies
def s_transpose(b, f, n):
    """S^T f: the joint component of a force (f, n) on body ``b`` (n_z for revolute, f_z for
    prismatic)."""
    return n[2] if b.kind == "R" else f[2]


def add_s(b, v, w, x):
    """(v, w) + S x for the joint of body ``b`` (x a scalar joint rate or acceleration)."""
    if b.kind == "R":
        return v, (w[0], w[1], add(w[2], x))
    return (v[0], v[1], add(v[2], x)), w


def bias_acceleration(b, v, w, qd):
    """Velocity-product acceleration c = (v, w) x S qd  (Featherstone 7.1, c_J = 0) of the joint of
    body ``b`` at body velocity (v, w) and joint rate qd."""
    if b.kind == "R":        # (v x qd e_z, w x qd e_z)
        return (mul(v[1], qd), mul(-1.0, mul(v[0], qd)), 0.0), \
               (mul(w[1], qd), mul(-1.0, mul(w[0], qd)), 0.0)
    return (mul(w[1], qd), mul(-1.0, mul(w[0], qd)), 0.0), (0.0, 0.0, 0.0)


def rigid_force(b, v, w):
    """I (v, w) for the rigid body ``b``: f = m v - h x w, n = h x v + I_o w."""
    f = vsub(tuple(mul(b.mass, x) for x in v), cross(b.h, w))
    n = vadd(cross(b.h, v), cmv(b.Io, w))
    return f, n


def cross_force(v, w, f, n):
    """(v, w) x* (f, n) = (w x f, w x n + v x f)  (Featherstone 2.32)."""
    return cross(w, f), vadd(cross(w, n), cross(v, f))
