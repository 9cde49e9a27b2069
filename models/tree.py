"""The constant kinematic tree the recursive algorithms read, built from a pin.Model.

Every joint is re-expressed in a *canonical* body frame whose z axis is the joint axis
(body frame B' = B Q with Q e_z = axis; Q is a signed permutation for axis-aligned joints,
so snapped constants stay exact). Then every motion subspace is the constant 6-vector
S = e_wz (revolute) or e_vz (prismatic), every joint rotation is R_z(q), and all
constant data enters as python floats so that zeros and ones fold away when CasADi
builds the expression graph (``models.algebra``).

URDF files carry round-off (1e-12 instead of 0, cos(pi/2) in rotations); :func:`snap`
and :func:`snapped_model` clean it before the tree is built, so the folding sees exact
zeros and ones.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from models.robot import ModelError

__all__ = ["Body", "SpatialTree", "snap", "snapped_model", "joint_kind", "link_names",
           "tree_from_pin"]

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
_ROUND = 8 * np.finfo(float).eps   # round-off of Q^T R Q for unaligned axes, cleaned in E


# =============================================================================================
# snapping URDF round-off
# =============================================================================================
def snap(x, tol):
    """Entries with |x| < tol -> 0 and with |1 - |x|| < tol -> +-1, exactly (a copy).

    Parameters
    ----------
    x : array_like
    tol : float
        Snapping tolerance; 0 or less leaves ``x`` unchanged.

    Returns
    -------
    numpy.ndarray of x's shape
    """
    x = np.array(x, dtype=float, copy=True)
    if tol > 0:
        x[np.abs(x) < tol] = 0.0
        near = np.abs(1.0 - np.abs(x)) < tol
        x[near] = np.sign(x[near])
    return x


def snapped_model(model, tol):
    """Copy of ``model`` with placements, inertias (lever, rotational) and axes snapped.

    Parameters
    ----------
    model : pin.Model
        Left untouched.
    tol : float
        Tolerance of :func:`snap`.

    Returns
    -------
    pin.Model

    Raises
    ------
    ModelError
        pinocchio rejects a snapped rotational inertia.
    """
    out = model.copy()
    for i in range(1, model.njoints):
        M = model.jointPlacements[i]
        out.jointPlacements[i] = pin.SE3(snap(M.rotation, tol), snap(M.translation, tol))
        Y = model.inertias[i]
        try:
            out.inertias[i] = pin.Inertia(float(Y.mass), snap(Y.lever, tol), snap(Y.inertia, tol))
        except RuntimeError as e:        # pinocchio rejects the snapped rotational inertia
            raise ModelError(
                f"link {link_names(model).get(i, model.names[i])!r} (moved by joint "
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
class Body:
    """One body of the tree, the one moved by ``joint``, in its canonical frame (SI units)."""
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
        """Number of bodies (= joints)."""
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


def joint_kind(model, i):
    """(kind 'R' or 'P', unit axis (3,), continuous) of joint i of ``model``.

    Raises ModelError naming the joint when its type is not supported or its axis is not
    a unit vector.
    """
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


def link_names(model):
    """Joint index -> name of the first body frame (the URDF child link) it moves, for the
    pin.Model ``model``: a dict."""
    names = {}
    for f in model.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint not in names and f.parentJoint > 0:
            names[f.parentJoint] = f.name
    return names


def tree_from_pin(model):
    """Canonical constant data of a (snapped) pin.Model (Featherstone ch. 4 model tree).

    Parameters
    ----------
    model : pin.Model
        1-DoF revolute/prismatic joints only (see :func:`joint_kind`), usually the output
        of :func:`snapped_model`.

    Returns
    -------
    SpatialTree
        Placements E = Q_lambda^T R Q_i, r = Q_lambda^T p; inertias about the body origin
        (parallel axis theorem) in the canonical frame; gravity in the base frame.
    """
    links = link_names(model)
    Q = [np.eye(3)]
    bodies = []
    for i in range(1, model.njoints):
        kind, axis, continuous = joint_kind(model, i)
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
        bodies.append(Body(
            joint=model.names[i], link=links.get(i, model.names[i]), parent=lam - 1,
            kind=kind, continuous=continuous, E=_tup(snap(E, _ROUND)), r=_tup(r), mass=m,
            h=_tup(m * c), Io=_tup(0.5 * (Io + Io.T)), com=_tup(c),
            armature=float(model.armature[model.joints[i].idx_v])))
    return SpatialTree(bodies=tuple(bodies), gravity=_tup(model.gravity.linear))
