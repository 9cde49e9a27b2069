"""Composite Rigid Body Algorithm (CRBA): the joint-space inertia matrix on the spatial tree."""
from __future__ import annotations

import casadi as ca

from models.algebra import add, mul, split
from models.spatial import JointX, RigidInertia, s_transpose

__all__ = ["crba"]


def crba(tree, q):
    """Composite Rigid Body Algorithm: M(q)  (Featherstone Table 6.2).

    Composite inertias I^c_lambda += X_i^T I^c_i X_i towards the root, kept in 10-parameter
    rigid form (constant total mass); then F = I^c_i S, M_ii = S^T F + armature_i and
    M_ij = S_j^T F carried up the chain of ancestors j.

    Parameters
    ----------
    tree : models.tree.SpatialTree
        Bodies: placements, joint kinds, inertias, armatures.
    q : casadi.SX (n, 1) or sequence of n scalars
        Joint positions (rad or m).

    Returns
    -------
    casadi.SX (n, n)
        Symmetric M(q) (kg m^2, kg, kg m); entries of unrelated branches are structural
        zeros.
    """
    n = tree.n
    qs = split(q, n, "q")
    Xs = [JointX(b, qs[i]) for i, b in enumerate(tree.bodies)]
    Ic = [RigidInertia(b.mass, b.h, [list(r) for r in b.Io]) for b in tree.bodies]
    for i in range(n - 1, -1, -1):
        b = tree.bodies[i]
        if b.parent >= 0:
            Ic[b.parent] = Ic[b.parent].add(Xs[i].inertia_out(Ic[i]))
    M = ca.SX(n, n)
    for i in range(n - 1, -1, -1):
        b = tree.bodies[i]
        I = Ic[i]
        if b.kind == "R":      # F = I^c e_wz = (-[h]x e_z, I_o e_z)
            f, m = (mul(-1.0, I.h[1]), I.h[0], 0.0), (I.Io[0][2], I.Io[1][2], I.Io[2][2])
        else:                  # F = I^c e_vz = (m e_z, [h]x e_z)
            f, m = (0.0, 0.0, I.m), (I.h[1], mul(-1.0, I.h[0]), 0.0)
        M[i, i] = add(s_transpose(b, f, m), b.armature)
        j = i
        while tree.bodies[j].parent >= 0:
            f, m = Xs[j].force_out(f, m)
            j = tree.bodies[j].parent
            M[i, j] = M[j, i] = s_transpose(tree.bodies[j], f, m)
    return M
