"""Any URDF turned into our own CasADi SX spatial algorithms.

The URDF is parsed by pinocchio (the ``pin`` wheel, which has no ``pinocchio.casadi``); we
read the numeric data of the resulting ``pin.Model`` (joint placements, inertias, joint
axes, parents, gravity, damping, armature) and write the recursive algorithms of rigid-body
dynamics ourselves on CasADi SX:

    rnea(q, v, a)   inverse dynamics with gravity       (Featherstone 2008, Table 5.1)
    crba(q)         joint-space inertia matrix M(q)     (Featherstone Table 6.2)
    aba(q, v, tau)  forward dynamics, articulated body  (Featherstone Table 7.1)
    gravity(q) = rnea(q, 0, 0),  nle(q, v) = rnea(q, v, 0),  com_positions(q)

Conventions. Spatial motion m = (v, w) (linear first, as pinocchio), forces f = (f, n).
A placement (R, p) maps child coordinates to parent ones: x_parent = R x_child + p, so
the motion transform parent -> child is  w' = R^T w,  v' = R^T (v - p x w)
and the force transform child -> parent is  f' = R f,  n' = R n + p x f'  (Featherstone 2.24).

Every joint is re-expressed in a *canonical* body frame whose z axis is the joint axis
(body frame B' = B Q with Q e_z = axis; Q is a signed permutation for axis-aligned joints,
so snapped constants stay exact). Then every motion subspace is the constant 6-vector
S = e_wz (revolute) or e_vz (prismatic), every joint rotation is R_z(q), and all
constant data enters as python floats so that zeros and ones fold away when CasADi
builds the expression graph. Transforms are applied as a constant rotation, a rotation
about z and a cross product on 3-vectors, never as dense 6x6 products.

pinocchio's ``model.armature`` is honoured as pinocchio does (added to diag M, to the
RNEA torque and to the ABA pivot D). Friction F = diag(model.damping) is not part of
these algorithms; ``forward_dynamics`` applies it as aba(q, v, tau - F v).

Size of the generated ABA (``UrdfRobot.fd``): ur5 ~1.0k SX instructions, panda (7 DoF)
~1.8k; after ``gcc -O3`` about 0.2 us and 0.34 us per call on the development VM, where
pinocchio's C++ ``aba`` took about 1.9 us and 2.6 us.
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import math
import pathlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np
import pinocchio as pin

from models.robot import ModelError, RobotModel

__all__ = ["UrdfRobot", "load_urdf", "example_robot_data_dir", "snap", "SpatialTree",
           "rnea", "crba", "aba", "com_positions"]

# pinocchio joint model short names we support: kind ('R' revolute, 'P' prismatic),
# fixed axis (None: read from the joint), continuous (nq = 2 in pinocchio, cos/sin).
_SUPPORTED = {
    "JointModelRX": ("R", (1.0, 0.0, 0.0), False),
    "JointModelRY": ("R", (0.0, 1.0, 0.0), False),
    "JointModelRZ": ("R", (0.0, 0.0, 1.0), False),
    "JointModelRevoluteUnaligned": ("R", None, False),
    "JointModelRUBX": ("R", (1.0, 0.0, 0.0), True),
    "JointModelRUBY": ("R", (0.0, 1.0, 0.0), True),
    "JointModelRUBZ": ("R", (0.0, 0.0, 1.0), True),
    "JointModelRevoluteUnboundedUnaligned": ("R", None, True),
    "JointModelPX": ("P", (1.0, 0.0, 0.0), False),
    "JointModelPY": ("P", (0.0, 1.0, 0.0), False),
    "JointModelPZ": ("P", (0.0, 0.0, 1.0), False),
    "JointModelPrismaticUnaligned": ("P", None, False),
}
_URDF_SUPPORTED = {"revolute", "continuous", "prismatic", "fixed"}
_URDF_KNOWN = _URDF_SUPPORTED | {"floating", "planar"}
_HUGE_LIMIT = 1e4   # a limit beyond this (or non-finite) counts as "no range given"
_ROUND = 8 * np.finfo(float).eps   # round-off of Q^T R Q for unaligned axes, cleaned in E


# =============================================================================================
# locating data
# =============================================================================================
def example_robot_data_dir() -> pathlib.Path:
    """The ``robots`` folder of the installed example-robot-data package.

    Found from the installed distribution's file list (cmeel layout
    ``cmeel.prefix/share/example-robot-data/robots``); no network, no hard-coded path.
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise ModelError("the example-robot-data package is not installed "
                         "(pip install example-robot-data)") from None
    path = pathlib.Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))
    if not path.is_dir():
        for f in dist.files or ():
            parts = pathlib.PurePosixPath(str(f)).parts
            if "example-robot-data" in parts and "robots" in parts:
                k = parts.index("robots")
                path = pathlib.Path(dist.locate_file(pathlib.PurePosixPath(*parts[:k + 1])))
                break
    if not path.is_dir():
        raise ModelError(f"example-robot-data is installed but its robots folder was not found "
                         f"(looked at {path})")
    return path.resolve()


# =============================================================================================
# snapping URDF round-off
# =============================================================================================
def snap(x, tol):
    """Entries with |x| < tol -> 0 and with |1 - |x|| < tol -> +-1, exactly (a copy)."""
    x = np.array(x, dtype=float, copy=True)
    if tol > 0:
        x[np.abs(x) < tol] = 0.0
        near = np.abs(1.0 - np.abs(x)) < tol
        x[near] = np.sign(x[near])
    return x


def _snapped_model(model, tol):
    """Copy of ``model`` with placements, inertias (lever, rotational) and axes snapped."""
    out = model.copy()
    for i in range(1, model.njoints):
        M = model.jointPlacements[i]
        out.jointPlacements[i] = pin.SE3(snap(M.rotation, tol), snap(M.translation, tol))
        Y = model.inertias[i]
        try:
            out.inertias[i] = pin.Inertia(float(Y.mass), snap(Y.lever, tol), snap(Y.inertia, tol))
        except RuntimeError as e:        # pinocchio rejects the snapped rotational inertia
            raise ModelError(
                f"link {_link_names(model).get(i, model.names[i])!r} (moved by joint "
                f"{model.names[i]!r}): rotational inertia about the centre of mass is not "
                f"positive definite after snapping entries below snap_tol={tol} ({e})") from None
        jm = model.joints[i]
        name = jm.shortname()
        if name not in _SUPPORTED or _SUPPORTED[name][1] is not None:
            continue
        raw = _joint_axis(model, i)
        axis = snap(raw, tol)
        if np.array_equal(axis, raw):
            continue
        if name == "JointModelRevoluteUnboundedUnaligned":
            # pin's Python bindings cannot build this joint with a given axis: use RUBX/Y/Z
            # when the snapped axis is one, else keep the raw axis (both models agree).
            k = [j for j in range(3) if axis[j] == 1.0]
            if len(k) != 1 or np.count_nonzero(axis) != 1:
                continue
            new = getattr(pin, "JointModelRUB" + "XYZ"[k[0]])()
        else:
            new = getattr(pin, name)(axis)
        new.setIndexes(i, jm.idx_q, jm.idx_v, jm.idx_vExtended)
        out.joints[i] = new
    return out


def _joint_axis(model, i):
    """Unit axis of a 1-DoF joint, read from its motion subspace S at the neutral q."""
    jm = model.joints[i]
    kind = _SUPPORTED[jm.shortname()][0]
    try:
        return np.array(jm.extract().axis, dtype=float)
    except AttributeError:      # RevoluteUnboundedUnaligned has no axis binding
        jd = jm.createData()
        jm.calc(jd, pin.neutral(model))
        S = np.asarray(jd.S, dtype=float).reshape(6)
        return S[3:].copy() if kind == "R" else S[:3].copy()


# =============================================================================================
# the constant data: a kinematic tree in canonical (joint axis = z) body frames
# =============================================================================================
@dataclass(frozen=True)
class _Body:
    joint: str            # joint name
    link: str             # child link (first body frame of the joint)
    parent: int           # internal index of the parent body, -1 for the fixed base
    kind: str             # 'R' revolute about z, 'P' prismatic along z
    continuous: bool
    E: tuple              # 3x3 constant rotation of the placement (rows, python floats)
    r: tuple              # 3 constant translation of the placement
    mass: float
    h: tuple              # first moment of mass m c about the body origin
    Io: tuple             # 3x3 rotational inertia about the body origin
    com: tuple            # centre of mass c in the canonical body frame
    armature: float


@dataclass(frozen=True)
class SpatialTree:
    """What the recursive algorithms read: bodies in topological order, gravity."""
    bodies: tuple
    gravity: tuple        # linear gravity vector in the base frame

    @property
    def n(self):
        return len(self.bodies)


def _frame_about(axis):
    """Rotation Q (columns u, w, a) with Q e_z = a; a signed permutation when a = +-e_k."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = int(np.argmax(np.abs(a)))
    if abs(abs(a[k]) - 1.0) == 0.0:             # axis-aligned: exact integers
        u = np.zeros(3)
        u[(k + 1) % 3] = 1.0
    else:
        helper = np.zeros(3)
        helper[int(np.argmin(np.abs(a)))] = 1.0
        u = helper - helper.dot(a) * a
        u /= np.linalg.norm(u)
    w = np.cross(a, u)
    return np.column_stack([u, w, a])


def _tup(x):
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        return tuple(float(e) + 0.0 for e in x)      # + 0.0 turns -0.0 into 0.0
    return tuple(tuple(float(e) + 0.0 for e in row) for row in x)


def _joint_kind(model, i):
    jm = model.joints[i]
    short = jm.shortname()
    if short not in _SUPPORTED:
        raise ModelError(
            f"joint {model.names[i]!r} has unsupported type {short} (supported: revolute, "
            f"continuous and prismatic joints about any axis; floating, planar, spherical, "
            f"translation, composite, helical and mimic joints are not)")
    kind, axis, continuous = _SUPPORTED[short]
    if axis is None:
        axis = _joint_axis(model, i)
        if not np.isfinite(axis).all() or abs(np.linalg.norm(axis) - 1.0) > 1e-6:
            raise ModelError(f"joint {model.names[i]!r}: axis {axis} is not a unit vector")
    return kind, np.asarray(axis, dtype=float), continuous


def _link_names(model):
    names = {}
    for f in model.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint not in names and f.parentJoint > 0:
            names[f.parentJoint] = f.name
    return names


def _tree_from_pin(model):
    """Canonical constant data of a (snapped) pin.Model (Featherstone ch. 4 model tree)."""
    links = _link_names(model)
    Q = [np.eye(3)]
    bodies = []
    for i in range(1, model.njoints):
        kind, axis, continuous = _joint_kind(model, i)
        Qi = _frame_about(axis)
        Q.append(Qi)
        lam = model.parents[i]
        M = model.jointPlacements[i]
        E = Q[lam].T @ M.rotation @ Qi            # R_T' = Q_lambda^T R_T Q_i
        r = Q[lam].T @ M.translation               # p_T' = Q_lambda^T p_T
        Y = model.inertias[i]
        m = float(Y.mass)
        c = Qi.T @ Y.lever
        Ic = Qi.T @ Y.inertia @ Qi
        Io = Ic + m * (c.dot(c) * np.eye(3) - np.outer(c, c))   # parallel axis theorem
        bodies.append(_Body(
            joint=model.names[i], link=links.get(i, model.names[i]), parent=lam - 1,
            kind=kind, continuous=continuous, E=_tup(snap(E, _ROUND)), r=_tup(r), mass=m,
            h=_tup(m * c), Io=_tup(0.5 * (Io + Io.T)), com=_tup(c),
            armature=float(model.armature[model.joints[i].idx_v])))
    return SpatialTree(bodies=tuple(bodies), gravity=_tup(model.gravity.linear))


# =============================================================================================
# scalar algebra with folding of python-float zeros and ones
# =============================================================================================
def _z(x):
    if isinstance(x, float):
        return x == 0.0
    return x.is_zero()


def _add(a, b):
    if _z(a):
        return b
    if _z(b):
        return a
    return a + b


def _sub(a, b):
    if _z(b):
        return a
    if _z(a):
        return -b
    return a - b


def _mul(a, b):
    if _z(a) or _z(b):
        return 0.0
    if isinstance(a, float):
        if a == 1.0:
            return b
        if a == -1.0:
            return -b
    if isinstance(b, float):
        if b == 1.0:
            return a
        if b == -1.0:
            return -a
    return a * b


def _dot(a, b):
    """sum_k a_k b_k, skipping zeros and folding unit coefficients into +/-."""
    acc = 0.0
    for x, y in zip(a, b):
        if _z(x) or _z(y):
            continue
        if isinstance(x, float) and x == -1.0:
            acc = _sub(acc, y)
        elif isinstance(y, float) and y == -1.0:
            acc = _sub(acc, x)
        else:
            acc = _add(acc, _mul(x, y))
    return acc


def _cross(a, b):
    return (_sub(_mul(a[1], b[2]), _mul(a[2], b[1])),
            _sub(_mul(a[2], b[0]), _mul(a[0], b[2])),
            _sub(_mul(a[0], b[1]), _mul(a[1], b[0])))


def _vadd(a, b):
    return tuple(_add(x, y) for x, y in zip(a, b))


def _vsub(a, b):
    return tuple(_sub(x, y) for x, y in zip(a, b))


def _cmv(E, u):
    """E u for a constant matrix E (rows of floats)."""
    return tuple(_dot(row, u) for row in E)


def _cmtv(E, u):
    """E^T u for a constant matrix E."""
    return tuple(_dot((E[0][j], E[1][j], E[2][j]), u) for j in range(3))


def _sym(m00, m01, m02, m11, m12, m22):
    """Symmetric 3x3 as nested lists sharing the mirrored entries."""
    return [[m00, m01, m02], [m01, m11, m12], [m02, m12, m22]]


# ------------------------------------------------------------------ rotation about z
class _Rz:
    """Rotation R_z(q): c = cos q, s = sin q and the products s^2, c s, cos 2q, sin 2q.

    The 2x2 (xy) block of R X R^T is written as a correction of X:
    with e = x00 - x11, sigma = x01 + x10 (exact algebra, 4 mul per block)

        u = s^2 e + c s sigma,   x00' = x00 - u,   x11' = x11 + u,
        w = c s e - s^2 sigma,   x01' = x01 + w,   x10' = x10 + w.
    """

    def __init__(self, q):
        self.c = ca.cos(q)
        self.s = ca.sin(q)

    @cached_property
    def ss(self):
        return self.s * self.s

    @cached_property
    def cs(self):
        return self.c * self.s

    @cached_property
    def c2(self):
        return (self.c - self.s) * (self.c + self.s)

    @cached_property
    def s2(self):
        return self.cs + self.cs

    def apply(self, u):
        """R_z u."""
        c, s = self.c, self.s
        return (_sub(_mul(c, u[0]), _mul(s, u[1])), _add(_mul(s, u[0]), _mul(c, u[1])), u[2])

    def apply_T(self, u):
        """R_z^T u."""
        c, s = self.c, self.s
        return (_add(_mul(c, u[0]), _mul(s, u[1])), _sub(_mul(c, u[1]), _mul(s, u[0])), u[2])

    def sym(self, S):
        """R_z S R_z^T for a symmetric 3x3 S (4 mul, 5 add on the xy block)."""
        a, b, d = S[0][0], S[0][1], S[1][1]
        if not (_z(a) and _z(b) and _z(d)):
            e = _sub(a, d)
            u = _add(_mul(self.ss, e), _mul(self.s2, b))
            a, d = _sub(a, u), _add(d, u)
            b = _add(_mul(self.cs, e), _mul(self.c2, b))
        v = self.apply((S[0][2], S[1][2], 0.0))
        return _sym(a, b, v[0], d, v[1], S[2][2])

    def gen(self, B):
        """R_z B R_z^T for a general 3x3 B (4 mul, 8 add on the xy block)."""
        b00, b01, b10, b11 = B[0][0], B[0][1], B[1][0], B[1][1]
        e, sig = _sub(b00, b11), _add(b01, b10)
        if not (_z(e) and _z(sig)):
            u = _add(_mul(self.ss, e), _mul(self.cs, sig))
            w = _sub(_mul(self.cs, e), _mul(self.ss, sig))
            b00, b11, b01, b10 = _sub(b00, u), _add(b11, u), _add(b01, w), _add(b10, w)
        col = self.apply((B[0][2], B[1][2], 0.0))
        row = self.apply((B[2][0], B[2][1], 0.0))
        return [[b00, b01, col[0]], [b10, b11, col[1]], [row[0], row[1], B[2][2]]]


# ------------------------------------------------------------------ constant rotations
def _csym(E, S):
    """E S E^T for constant E and symmetric S (upper triangle only)."""
    T = [[_dot(S[k], E[j]) for j in range(3)] for k in range(3)]          # T = S E^T
    out = [[None] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            out[i][j] = out[j][i] = _dot(E[i], (T[0][j], T[1][j], T[2][j]))
    return out


def _cgen(E, B):
    """E B E^T for constant E and general B."""
    T = [[_dot(B[k], E[j]) for j in range(3)] for k in range(3)]
    return [[_dot(E[i], (T[0][j], T[1][j], T[2][j])) for j in range(3)] for i in range(3)]


def _skew(p):
    return ((0.0, _mul(-1.0, p[2]), p[1]), (p[2], 0.0, _mul(-1.0, p[0])),
            (_mul(-1.0, p[1]), p[0], 0.0))


def _is_identity(E):
    return all(E[i][j] == (1.0 if i == j else 0.0) for i in range(3) for j in range(3))


# ------------------------------------------------------------------ spatial inertias
class _Inertia6:
    """Symmetric 6x6 (articulated) inertia in blocks: f = A v + B w, n = B^T v + C w."""
    __slots__ = ("A", "B", "C")

    def __init__(self, A, B, C):
        self.A, self.B, self.C = A, B, C

    @classmethod
    def rigid(cls, b):
        """Rigid body: A = m 1, B = -[h]x, C = I_o  (Featherstone 2.63)."""
        m, h = b.mass, b.h
        A = _sym(m, 0.0, 0.0, m, 0.0, m)
        B = [[0.0, h[2], -h[1]], [-h[2], 0.0, h[0]], [h[1], -h[0], 0.0]]
        C = [list(row) for row in b.Io]
        return cls(A, B, C)

    def times(self, v, w):
        """Force (A v + B w, B^T v + C w)."""
        f = tuple(_add(_dot(self.A[i], v), _dot(self.B[i], w)) for i in range(3))
        n = tuple(_add(_dot((self.B[0][i], self.B[1][i], self.B[2][i]), v), _dot(self.C[i], w))
                  for i in range(3))
        return f, n

    def column(self, k):
        """Column k of the 6x6 matrix as (f part, n part)."""
        if k < 3:
            return (tuple(self.A[i][k] for i in range(3)), tuple(self.B[k][i] for i in range(3)))
        k -= 3
        return (tuple(self.B[i][k] for i in range(3)), tuple(self.C[i][k] for i in range(3)))

    def add(self, other):
        A = _symmap(self.A, other.A, _add)
        C = _symmap(self.C, other.C, _add)
        B = [[_add(self.B[i][j], other.B[i][j]) for j in range(3)] for i in range(3)]
        return _Inertia6(A, B, C)

    # transforms child -> parent: X^T I X
    def rotate_z(self, rz):
        return _Inertia6(rz.sym(self.A), rz.gen(self.B), rz.sym(self.C))

    def rotate_const(self, E):
        if _is_identity(E):
            return self
        return _Inertia6(_csym(E, self.A), _cgen(E, self.B), _csym(E, self.C))

    def translate(self, p):
        """Shift by p: A' = A, B' = B - A P, C' = C + P B + (P B)^T - P A P, P = [p]x."""
        if all(_z(x) for x in p):
            return self
        P = _skew(p)
        G = [[_dot(self.A[i], (P[0][j], P[1][j], P[2][j])) for j in range(3)]
             for i in range(3)]                                               # A P
        B = [[_sub(self.B[i][j], G[i][j]) for j in range(3)] for i in range(3)]
        K = [[_dot(P[i], (self.B[0][j], self.B[1][j], self.B[2][j])) for j in range(3)]
             for i in range(3)]                                               # P B
        C = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                PAP = _dot(P[i], (G[0][j], G[1][j], G[2][j]))
                C[i][j] = C[j][i] = _sub(_add(self.C[i][j], _add(K[i][j], K[j][i])), PAP)
        return _Inertia6(self.A, B, C)


def _symmap(S, T, op):
    return _sym(op(S[0][0], T[0][0]), op(S[0][1], T[0][1]), op(S[0][2], T[0][2]),
                op(S[1][1], T[1][1]), op(S[1][2], T[1][2]), op(S[2][2], T[2][2]))


class _RigidInertia:
    """Rigid-body (composite) inertia (m, h = m c, I_o) about the body origin."""
    __slots__ = ("m", "h", "Io")

    def __init__(self, m, h, Io):
        self.m, self.h, self.Io = m, h, Io

    def add(self, o):
        return _RigidInertia(self.m + o.m, _vadd(self.h, o.h), _symmap(self.Io, o.Io, _add))

    def rotate_z(self, rz):
        return _RigidInertia(self.m, rz.apply(self.h), rz.sym(self.Io))

    def rotate_const(self, E):
        if _is_identity(E):
            return self
        return _RigidInertia(self.m, _cmv(E, self.h), _csym(E, self.Io))

    def translate(self, p):
        """h' = h + m p, I_o' = I_o - (h p^T + p h^T - 2 h.p 1) - m (p p^T - |p|^2 1)."""
        if all(_z(x) for x in p):
            return self
        h, m = self.h, self.m
        hp = _dot(h, p)
        pp = _dot(p, p)
        Io = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                t = _add(_mul(h[i], p[j]), _mul(p[i], h[j]))
                t = _add(t, _mul(m, _mul(p[i], p[j])))
                if i == j:
                    t = _sub(t, _add(_mul(2.0, hp), _mul(m, pp)))
                Io[i][j] = Io[j][i] = _sub(self.Io[i][j], t)
        return _RigidInertia(m, _vadd(h, tuple(_mul(m, x) for x in p)), Io)


# =============================================================================================
# joint transforms (parent <-> child), applied on 3-vectors
# =============================================================================================
class _JointX:
    """Placement of body i in its parent: constant (E, r) then the joint motion (R_z or z-shift)."""

    def __init__(self, body, qi):
        self.b = body
        if body.kind == "R":
            self.rz = _Rz(qi)
        else:
            self.rz = None
            self.dz = qi

    def motion_in(self, v, w):
        """Parent motion (v, w) expressed in the child:  w' = R^T w,  v' = R^T (v - p x w)."""
        b = self.b
        w_T = _cmtv(b.E, w)
        v_T = _cmtv(b.E, _vsub(v, _cross(b.r, w)))
        if self.rz is not None:
            return self.rz.apply_T(v_T), self.rz.apply_T(w_T)
        d = self.dz                                     # v' = v_T - (d e_z) x w_T
        return (_add(v_T[0], _mul(d, w_T[1])), _sub(v_T[1], _mul(d, w_T[0])), v_T[2]), w_T

    def force_out(self, f, n):
        """Child force (f, n) expressed in the parent:  f' = R f,  n' = R n + p x f'."""
        b = self.b
        if self.rz is not None:
            f, n = self.rz.apply(f), self.rz.apply(n)
        else:
            d = self.dz                                 # n += (d e_z) x f
            n = (_sub(n[0], _mul(d, f[1])), _add(n[1], _mul(d, f[0])), n[2])
        f = _cmv(b.E, f)
        n = _vadd(_cmv(b.E, n), _cross(b.r, f))
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
        return [[_dot(E[i], (RzM[0][j], RzM[1][j], RzM[2][j])) for j in range(3)]
                for i in range(3)]

    def translation(self):
        b = self.b
        if self.rz is None:
            return _vadd(b.r, _cmv(b.E, (0.0, 0.0, self.dz)))
        return b.r


def _split(x, n, what):
    if isinstance(x, (list, tuple)):
        if len(x) != n:
            raise ValueError(f"{what}: expected {n} entries, got {len(x)}")
        return [e if isinstance(e, ca.SX) else float(e) for e in x]
    if x is None:
        return [0.0] * n
    if x.shape != (n, 1) and x.shape != (1, n):
        raise ValueError(f"{what}: expected shape ({n}, 1), got {x.shape}")
    return [x[k] for k in range(n)]


def _column(entries):
    return ca.vertcat(*[ca.SX(e) if isinstance(e, float) else e for e in entries])


def _sub_S(b, f, n):
    """S^T f: the joint component of a force (n_z for revolute, f_z for prismatic)."""
    return n[2] if b.kind == "R" else f[2]


def _add_S(b, v, w, x):
    """(v, w) + S x."""
    if b.kind == "R":
        return v, (w[0], w[1], _add(w[2], x))
    return (v[0], v[1], _add(v[2], x)), w


def _bias_acc(b, v, w, qd):
    """Velocity-product acceleration c = (v, w) x S qd  (Featherstone 7.1, c_J = 0)."""
    if b.kind == "R":        # (v x qd e_z, w x qd e_z)
        return (_mul(v[1], qd), _mul(-1.0, _mul(v[0], qd)), 0.0), \
               (_mul(w[1], qd), _mul(-1.0, _mul(w[0], qd)), 0.0)
    return (_mul(w[1], qd), _mul(-1.0, _mul(w[0], qd)), 0.0), (0.0, 0.0, 0.0)


def _rigid_force(b, v, w):
    """I (v, w) for the rigid body: f = m v - h x w, n = h x v + I_o w."""
    f = _vsub(tuple(_mul(b.mass, x) for x in v), _cross(b.h, w))
    n = _vadd(_cross(b.h, v), _cmv(b.Io, w))
    return f, n


def _cross_force(v, w, f, n):
    """(v, w) x* (f, n) = (w x f, w x n + v x f)  (Featherstone 2.32)."""
    return _cross(w, f), _vadd(_cross(w, n), _cross(v, f))


def _zero3():
    return (0.0, 0.0, 0.0)


def _s_index(b):
    """Index of the motion subspace S in (v, w): 5 = w_z (revolute), 2 = v_z (prismatic)."""
    return 5 if b.kind == "R" else 2


_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


# =============================================================================================
# algorithms
# =============================================================================================
def rnea(tree, q, v=None, a=None, gravity=True):
    """Recursive Newton-Euler inverse dynamics tau = M a + C v + g  (Featherstone Table 5.1).

    Gravity enters as a base acceleration a_0 = -g. ``v``/``a`` None mean zero (exact).
    Returns an (n, 1) SX.
    """
    n = tree.n
    qs, vs, as_ = _split(q, n, "q"), _split(v, n, "v"), _split(a, n, "a")
    Xs = [_JointX(b, qs[i]) for i, b in enumerate(tree.bodies)]
    a0 = (tuple(-g for g in tree.gravity) if gravity else _zero3(), _zero3())
    V, Acc, Fo = [], [], []
    for i, b in enumerate(tree.bodies):
        if b.parent < 0:
            vp, ap = (_zero3(), _zero3()), a0
        else:
            vp, ap = V[b.parent], Acc[b.parent]
        vi = _add_S(b, *Xs[i].motion_in(*vp), vs[i])
        ai = Xs[i].motion_in(*ap)
        ai = _add_S(b, *ai, as_[i])
        cb = _bias_acc(b, *vi, vs[i])
        ai = (_vadd(ai[0], cb[0]), _vadd(ai[1], cb[1]))
        fa = _rigid_force(b, *ai)
        fb = _cross_force(*vi, *_rigid_force(b, *vi))
        V.append(vi)
        Acc.append(ai)
        Fo.append((_vadd(fa[0], fb[0]), _vadd(fa[1], fb[1])))
    tau = [None] * n
    for i in range(n - 1, -1, -1):
        b = tree.bodies[i]
        tau[i] = _add(_sub_S(b, *Fo[i]), _mul(b.armature, as_[i]))
        if b.parent >= 0:
            f, m = Xs[i].force_out(*Fo[i])
            fp = Fo[b.parent]
            Fo[b.parent] = (_vadd(fp[0], f), _vadd(fp[1], m))
    return _column(tau)


def crba(tree, q):
    """Composite Rigid Body Algorithm: M(q)  (Featherstone Table 6.2).

    Composite inertias are kept in 10-parameter rigid form (constant total mass).
    Returns a symmetric (n, n) SX; entries of unrelated branches are structural zeros.
    """
    n = tree.n
    qs = _split(q, n, "q")
    Xs = [_JointX(b, qs[i]) for i, b in enumerate(tree.bodies)]
    Ic = [_RigidInertia(b.mass, b.h, [list(r) for r in b.Io]) for b in tree.bodies]
    for i in range(n - 1, -1, -1):
        b = tree.bodies[i]
        if b.parent >= 0:
            Ic[b.parent] = Ic[b.parent].add(Xs[i].inertia_out(Ic[i]))
    M = ca.SX(n, n)
    for i in range(n - 1, -1, -1):
        b = tree.bodies[i]
        I = Ic[i]
        if b.kind == "R":      # F = I^c e_wz = (-[h]x e_z, I_o e_z)
            f, m = (_mul(-1.0, I.h[1]), I.h[0], 0.0), (I.Io[0][2], I.Io[1][2], I.Io[2][2])
        else:                  # F = I^c e_vz = (m e_z, [h]x e_z)
            f, m = (0.0, 0.0, I.m), (I.h[1], _mul(-1.0, I.h[0]), 0.0)
        M[i, i] = _add(_sub_S(b, f, m), b.armature)
        j = i
        while tree.bodies[j].parent >= 0:
            f, m = Xs[j].force_out(f, m)
            j = tree.bodies[j].parent
            M[i, j] = M[j, i] = _sub_S(tree.bodies[j], f, m)
    return M


def aba(tree, q, v, tau):
    """Articulated Body Algorithm: qdd = M^{-1}(tau - C v - g)  (Featherstone Table 7.1).

    Three passes: velocities and bias terms; articulated inertias I^A and bias forces p^A
    towards the root (U = I^A S, D = S^T U + armature, u = tau - S^T p^A,
    I^a = I^A - U U^T / D, p^a = p^A + I^a c + U u / D); accelerations from a_0 = -g.
    With S a coordinate axis, U is a column of I^A and D one entry; without armature the
    S row and column of I^a are exactly zero and S^T p^a = tau.
    """
    n = tree.n
    qs, vs, ts = _split(q, n, "q"), _split(v, n, "v"), _split(tau, n, "tau")
    bodies = tree.bodies
    Xs = [_JointX(b, qs[i]) for i, b in enumerate(bodies)]
    V, Cb, IA, pA = [], [], [], []
    for i, b in enumerate(bodies):                                  # pass 1
        vp = (_zero3(), _zero3()) if b.parent < 0 else V[b.parent]
        vi = _add_S(b, *Xs[i].motion_in(*vp), vs[i])
        V.append(vi)
        Cb.append(_bias_acc(b, *vi, vs[i]))
        IA.append(_Inertia6.rigid(b))
        pA.append(_cross_force(*vi, *_rigid_force(b, *vi)))
    U, Dinv, u = [None] * n, [None] * n, [None] * n
    for i in range(n - 1, -1, -1):                                  # pass 2
        b = bodies[i]
        I = IA[i]
        ks = _s_index(b)
        Uf, Un = I.column(ks)
        Ui = Uf + Un
        D = _add(Ui[ks], b.armature)
        Di = 2.0 / (D + D) if isinstance(D, ca.SX) else 1.0 / D   # keeps x * Di a product
        ui = _sub(ts[i], _sub_S(b, *pA[i]))
        U[i], Dinv[i], u[i] = Ui, Di, ui
        if b.parent < 0:
            continue
        W = tuple(_mul(x, Di) for x in Ui)
        exact = b.armature == 0.0

        def ent(r, c, val):          # I^a entry (r, c) of the 6x6, r, c in 0..5
            if exact and (r == ks or c == ks):
                return 0.0
            return _sub(val, _mul(W[r], Ui[c]))

        A = _sym(*(ent(r, c, I.A[r][c]) for r, c in _UPPER))
        C = _sym(*(ent(r + 3, c + 3, I.C[r][c]) for r, c in _UPPER))
        B = [[ent(r, c + 3, I.B[r][c]) for c in range(3)] for r in range(3)]
        Ia = _Inertia6(A, B, C)
        cf, cn = Cb[i]
        gf, gn = Ia.times(cf, cn)
        pa = [_add(_add(x, y), _mul(w_, ui))
              for x, y, w_ in zip(pA[i][0] + pA[i][1], gf + gn, W)]
        if exact:
            pa[ks] = ts[i]
        f, m = Xs[i].force_out(tuple(pa[:3]), tuple(pa[3:]))
        pp = pA[b.parent]
        pA[b.parent] = (_vadd(pp[0], f), _vadd(pp[1], m))
        IA[b.parent] = IA[b.parent].add(Xs[i].inertia_out(Ia))
    a0 = (tuple(-g for g in tree.gravity), _zero3())
    Acc, qdd = [None] * n, [None] * n
    for i, b in enumerate(bodies):                                  # pass 3
        ap = a0 if b.parent < 0 else Acc[b.parent]
        av, aw = Xs[i].motion_in(*ap)
        cf, cn = Cb[i]
        av, aw = _vadd(av, cf), _vadd(aw, cn)
        qdd[i] = _mul(Dinv[i], _sub(u[i], _dot(U[i], av + aw)))
        Acc[i] = _add_S(b, av, aw, qdd[i])
    return _column(qdd)


def com_positions(tree, q):
    """World positions of the body centres of mass [p_1; ...; p_n]: (3n, 1) SX.

    Forward kinematics  oR_i = oR_lambda E_i R_z(q_i),  op_i = op_lambda + oR_lambda p_i,
    p_com,i = op_i + oR_i c_i.
    """
    n = tree.n
    qs = _split(q, n, "q")
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    oR, op, out = [], [], []
    for i, b in enumerate(tree.bodies):
        X = _JointX(b, qs[i])
        Rp, pp = (eye, _zero3()) if b.parent < 0 else (oR[b.parent], op[b.parent])
        Rl, pl = X.rotation(), X.translation()
        Ri = [[_dot(Rp[r], (Rl[0][c], Rl[1][c], Rl[2][c])) for c in range(3)] for r in range(3)]
        pi = _vadd(pp, tuple(_dot(Rp[r], pl) for r in range(3)))
        oR.append(Ri)
        op.append(pi)
        out.extend(_vadd(pi, tuple(_dot(Ri[r], b.com) for r in range(3))))
    return _column(out)


# =============================================================================================
# the robot
# =============================================================================================
def _check_bodies(model, model_raw=None):
    """Every body moved by a joint: mass > 0 and inertia about its CoM positive definite.

    ``model_raw`` (the unsnapped model) only adds a hint to the message when snapping is
    what made an inertia singular."""
    links = _link_names(model)
    for i in range(1, model.njoints):
        Y = model.inertias[i]
        link, joint = links.get(i, model.names[i]), model.names[i]
        if not (Y.mass > 0.0) or not math.isfinite(Y.mass):
            raise ModelError(f"link {link!r} (moved by joint {joint!r}) has mass {Y.mass!r}; "
                             f"every body moved by a joint needs a positive mass")
        Ic = np.asarray(Y.inertia)
        if not np.isfinite(Ic).all():
            raise ModelError(f"link {link!r} (moved by joint {joint!r}) has a non-finite inertia")
        lam = np.linalg.eigvalsh(0.5 * (Ic + Ic.T))
        if lam[0] <= 0.0:
            note = ""
            raw = np.asarray((model_raw or model).inertias[i].inertia)
            if model_raw is not None and np.linalg.eigvalsh(0.5 * (raw + raw.T))[0] > 0.0:
                note = " after snapping entries below snap_tol to zero (use a smaller snap_tol)"
            raise ModelError(
                f"link {link!r} (moved by joint {joint!r}) has a rotational inertia about its "
                f"centre of mass that is not positive definite{note} "
                f"(eigenvalues {np.array2string(lam, precision=4)})")


class UrdfRobot(RobotModel):
    """A rigid robot from a pinocchio model, with our own SX recursive algorithms.

    Parameters
    ----------
    model : pin.Model
        The (possibly reduced) model as pinocchio parsed it (kept as ``pin_model_raw``).
    name : str
    source : dict, optional
        JSON-able recipe to rebuild the robot without our symbolic code (``load_urdf`` sets
        ``{"kind": "urdf", "path", "sha256", "locked_joints", "snap_tol"}``).
    snap_tol : float
        Round-off snapping of placements, inertias and axes (see :func:`snap`); the snapped
        copy is ``pin_model``, and it is the model the algorithms use.
    """

    def __init__(self, model, name, source=None, snap_tol=1e-9):
        self.name = str(name)
        self.pin_model_raw = model
        if model.njoints <= 1:
            raise ModelError(f"robot {self.name!r} has no moving joint")
        for i in range(1, model.njoints):
            _joint_kind(model, i)                       # unsupported joint types first
        _check_bodies(model)
        self.pin_model = _snapped_model(model, snap_tol)
        _check_bodies(self.pin_model, model)
        self.tree = _tree_from_pin(self.pin_model)
        pm = self.pin_model
        self.n = self.tree.n
        self.dim = 3
        self.joint_names = [b.joint for b in self.tree.bodies]
        self.link_names = [b.link for b in self.tree.bodies]
        self._periodic = np.array([b.kind == "R" for b in self.tree.bodies])   # revolute/continuous
        self.masses = np.array([b.mass for b in self.tree.bodies])
        self.F = np.diag(np.array(pm.damping, dtype=float))
        self.v_limit = np.array(pm.velocityLimit, dtype=float)
        self._idx_q = [pm.joints[i].idx_q for i in range(1, pm.njoints)]
        lo, up = np.empty(self.n), np.empty(self.n)
        for k, b in enumerate(self.tree.bodies):
            lo[k], up[k] = -math.pi, math.pi
            if b.continuous:
                continue
            l_, u_ = float(pm.lowerPositionLimit[self._idx_q[k]]), float(
                pm.upperPositionLimit[self._idx_q[k]])
            if l_ > u_:
                raise ModelError(f"joint {b.joint!r}: lower limit {l_} > upper limit {u_}")
            if (math.isfinite(l_) and math.isfinite(u_) and max(abs(l_), abs(u_)) <= _HUGE_LIMIT
                    and l_ < u_):
                lo[k], up[k] = l_, u_
        self.q_lower, self.q_upper = lo, up
        self.snap_tol = float(snap_tol)
        self.source = source if source is not None else {
            "kind": "pin_model", "name": self.name, "snap_tol": self.snap_tol}
        self.check_mass_matrix()

    # ------------------------------------------------------------ symbolic algorithms
    def _sx_or_call(self, fun_name, builder, *args):
        if all(isinstance(x, ca.SX) or x is None for x in args):
            return builder(self.tree, *args)
        return getattr(self, fun_name)(*args)

    @cached_property
    def _rnea_fun(self):
        q, v = self._sym()
        a = ca.SX.sym("a", self.n)
        return ca.Function("rnea", [q, v, a], [rnea(self.tree, q, v, a)])

    @cached_property
    def _aba_fun(self):
        q, v = self._sym()
        tau = ca.SX.sym("tau", self.n)
        return ca.Function("aba", [q, v, tau], [aba(self.tree, q, v, tau)])

    def rnea(self, q, v, a):
        """tau = M(q) a + C(q, v) v + g(q)  (RNEA, Featherstone Table 5.1)."""
        return self._sx_or_call("_rnea_fun", rnea, q, v, a)

    def crba(self, q):
        """M(q)  (CRBA, Featherstone Table 6.2)."""
        return self._sx_or_call("M", crba, q)

    def aba(self, q, v, tau):
        """qdd = M^{-1}(tau - C v - g)  (ABA, Featherstone Table 7.1)."""
        return self._sx_or_call("_aba_fun", aba, q, v, tau)

    def mass_matrix(self, q):
        return self.crba(q)

    def gravity(self, q):
        """g(q) = rnea(q, 0, 0)."""
        if isinstance(q, ca.SX):
            return rnea(self.tree, q, None, None)
        return self.g(q)

    def nle(self, q, v):
        """C(q, v) v + g(q) = rnea(q, v, 0)."""
        if isinstance(q, ca.SX) and isinstance(v, ca.SX):
            return rnea(self.tree, q, v, None)
        return self._rnea_fun(q, v, ca.DM.zeros(self.n))

    def forward_dynamics(self, q, v, tau):
        """qdd = aba(q, v, tau - F v)  (viscous friction F from the URDF damping)."""
        if not all(isinstance(x, ca.SX) for x in (q, v, tau)):
            return self.fd(q, v, tau)
        F = np.asarray(self.F, dtype=float)
        vs = _split(v, self.n, "v")
        ts = _split(tau, self.n, "tau")
        t = [_sub(ts[i], _dot(tuple(float(x) for x in F[i]), vs)) for i in range(self.n)]
        return aba(self.tree, q, vs, t)

    def com_positions(self, q):
        """World CoM position of the body moved by each joint, stacked (3n, 1)."""
        if isinstance(q, ca.SX):
            return com_positions(self.tree, q)
        return self.com(q)

    # ------------------------------------------------------------ numeric helpers
    def pin_configuration(self, q):
        """Our angle coordinates -> pinocchio's q (cos, sin for continuous joints)."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (self.n,):
            raise ValueError(f"q: expected {self.n} entries, got {q.size}")
        out = np.zeros(self.pin_model.nq)
        for k, b in enumerate(self.tree.bodies):
            j = self._idx_q[k]
            if b.continuous:
                out[j], out[j + 1] = math.cos(q[k]), math.sin(q[k])
            else:
                out[j] = q[k]
        return out


# =============================================================================================
# loader
# =============================================================================================
def _check_urdf_xml(path, locked):
    """Reject joint types and mimic joints we do not support, naming the joint."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise ModelError(f"{path}: not a valid URDF (XML error: {e})") from None
    if root.tag != "robot":
        raise ModelError(f"{path}: not a URDF (root element <{root.tag}>, expected <robot>)")
    for j in root.iter("joint"):
        name, jtype = j.get("name"), j.get("type")
        if jtype is None:                      # <joint> inside <transmission> etc.
            continue
        if jtype not in _URDF_KNOWN:
            raise ModelError(f"{path}: joint {name!r} has unknown type {jtype!r} "
                             f"(URDF types: {', '.join(sorted(_URDF_KNOWN))})")
        if jtype not in _URDF_SUPPORTED:
            raise ModelError(f"{path}: joint {name!r} has unsupported type {jtype!r} "
                             f"(supported: revolute, continuous, prismatic, fixed)")
        if j.find("mimic") is not None and name not in locked:
            raise ModelError(f"{path}: joint {name!r} is a mimic joint, which is not supported "
                             f"(lock it with locked_joints={{{name!r}: value}})")
    for link in root.iter("link"):
        inertial = link.find("inertial")
        mass = inertial.find("mass") if inertial is not None else None
        if mass is not None:
            try:
                m = float(mass.get("value"))
            except (TypeError, ValueError):
                raise ModelError(f"{path}: link {link.get('name')!r} has an invalid mass "
                                 f"{mass.get('value')!r}") from None
            if not (m >= 0.0):
                raise ModelError(f"{path}: link {link.get('name')!r} has negative mass {m}")


def load_urdf(path, locked_joints=None, name=None, snap_tol=1e-9):
    """Build a :class:`UrdfRobot` from a URDF file.

    Parameters
    ----------
    path : str or path-like
        The URDF; relative paths resolve against the current directory.
    locked_joints : dict, optional
        Joint name -> value (rad or m); these joints are removed with
        ``pin.buildReducedModel`` at that value (the rest of the neutral configuration).
    name : str, optional
        Robot name; the file stem by default.
    snap_tol : float
        Placement, inertia and axis entries within ``snap_tol`` of 0 or +-1 are snapped.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ModelError
        Unsupported joint (floating, planar, unknown type, mimic, ...), a body without
        positive mass or positive-definite inertia, an unknown locked joint, or M(q) singular.
    """
    path = pathlib.Path(path).expanduser().resolve()
    if not path.is_file():
        raise FileNotFoundError(f"URDF file not found: {path}")
    locked = {str(k): float(v) for k, v in (locked_joints or {}).items()}
    data = path.read_bytes()
    _check_urdf_xml(path, locked)
    try:
        model = pin.buildModelFromUrdf(str(path))
    except Exception as e:  # pinocchio raises ValueError/RuntimeError on bad files
        raise ModelError(f"{path}: pinocchio could not parse the URDF: {e}") from None
    if locked:
        ids = []
        q_ref = pin.neutral(model)
        for jn, val in locked.items():
            if not model.existJointName(jn):
                raise ModelError(f"{path}: locked joint {jn!r} is not a moving joint of the URDF "
                                 f"(joints: {', '.join(list(model.names)[1:])})")
            jid = model.getJointId(jn)
            jm = model.joints[jid]
            if jm.nq == 2 and jm.nv == 1:            # continuous: cos, sin
                q_ref[jm.idx_q], q_ref[jm.idx_q + 1] = math.cos(val), math.sin(val)
            elif jm.nq == 1:
                q_ref[jm.idx_q] = val
            else:
                raise ModelError(f"{path}: cannot lock joint {jn!r} of type {jm.shortname()}")
            ids.append(jid)
        model = pin.buildReducedModel(model, sorted(ids), q_ref)
    name = name if name is not None else path.stem
    source = {"kind": "urdf", "name": name, "path": str(path), "sha256": hashlib.sha256(data).hexdigest(),
              "locked_joints": locked, "snap_tol": float(snap_tol)}
    return UrdfRobot(model, name=name, source=source,
                     snap_tol=snap_tol)
