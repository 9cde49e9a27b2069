"""Recursive Newton-Euler Algorithm (RNEA): inverse dynamics on the spatial tree."""
from __future__ import annotations

from models.algebra import add, column, mul, split, vadd, zero3
from models.spatial import JointX, add_s, bias_acceleration, cross_force, rigid_force, s_transpose

__all__ = ["rnea"]


def rnea(tree, q, v=None, a=None, gravity=True):
    """Recursive Newton-Euler inverse dynamics tau = M a + C v + g  (Featherstone Table 5.1).

    Forward pass: body velocities v_i = X_i v_lambda + S qd_i and accelerations
    a_i = X_i a_lambda + S qdd_i + v_i x S qd_i, forces f_i = I_i a_i + v_i x* I_i v_i;
    backward pass: tau_i = S^T f_i + armature_i qdd_i, f_lambda += X_i^* f_i.
    Gravity enters as a base acceleration a_0 = -g.

    Parameters
    ----------
    tree : models.tree.SpatialTree
        Bodies: placements, joint kinds, inertias, armatures; gravity.
    q : casadi.SX (n, 1) or sequence of n scalars
        Joint positions (rad or m).
    v, a : casadi.SX (n, 1), sequence of n scalars, or None
        Joint velocities and accelerations; None means zero (exact, no terms built).
    gravity : bool
        False leaves gravity out (a_0 = 0).

    Returns
    -------
    casadi.SX (n, 1)
        Joint torques/forces (N m or N).
    """
    n = tree.n
    qs, vs, as_ = split(q, n, "q"), split(v, n, "v"), split(a, n, "a")
    Xs = [JointX(b, qs[i]) for i, b in enumerate(tree.bodies)]
    a0 = (tuple(-g for g in tree.gravity) if gravity else zero3(), zero3())
    V, Acc, Fo = [], [], []
    for i, b in enumerate(tree.bodies):
        if b.parent < 0:
            vp, ap = (zero3(), zero3()), a0
        else:
            vp, ap = V[b.parent], Acc[b.parent]
        vi = add_s(b, *Xs[i].motion_in(*vp), vs[i])
        ai = Xs[i].motion_in(*ap)
        ai = add_s(b, *ai, as_[i])
        cb = bias_acceleration(b, *vi, vs[i])
        ai = (vadd(ai[0], cb[0]), vadd(ai[1], cb[1]))
        fa = rigid_force(b, *ai)
        fb = cross_force(*vi, *rigid_force(b, *vi))
        V.append(vi)
        Acc.append(ai)
        Fo.append((vadd(fa[0], fb[0]), vadd(fa[1], fb[1])))
    tau = [None] * n
    for i in range(n - 1, -1, -1):
        b = tree.bodies[i]
        tau[i] = add(s_transpose(b, *Fo[i]), mul(b.armature, as_[i]))
        if b.parent >= 0:
            f, m = Xs[i].force_out(*Fo[i])
            fp = Fo[b.parent]
            Fo[b.parent] = (vadd(fp[0], f), vadd(fp[1], m))
    return column(tau)
