"""Articulated Body Algorithm (ABA): forward dynamics on the spatial tree."""
from __future__ import annotations

import casadi as ca

from models.algebra import add, column, dot, mul, split, sub, sym3, vadd, zero3
from models.spatial import (Inertia6, JointX, add_s, bias_acceleration, cross_force, rigid_force,
                            s_transpose)

__all__ = ["aba"]


def _s_index(b):
    """Index of the motion subspace S in (v, w): 5 = w_z (revolute), 2 = v_z (prismatic)."""
    return 5 if b.kind == "R" else 2


_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))   # upper triangle of a 3x3


def aba(tree, q, v, tau):
    """Articulated Body Algorithm: qdd = M^{-1}(tau - C v - g)  (Featherstone Table 7.1).

    Three passes: velocities and bias terms; articulated inertias I^A and bias forces p^A
    towards the root (U = I^A S, D = S^T U + armature, u = tau - S^T p^A,
    I^a = I^A - U U^T / D, p^a = p^A + I^a c + U u / D); accelerations from a_0 = -g.
    With S a coordinate axis, U is a column of I^A and D one entry; without armature the
    S row and column of I^a are exactly zero and S^T p^a = tau.

    Parameters
    ----------
    tree : models.tree.SpatialTree
        Bodies: placements, joint kinds, inertias, armatures; gravity.
    q, v : casadi.SX (n, 1) or sequence of n scalars
        Joint positions (rad or m) and velocities (rad/s or m/s); ``v`` None means zero.
    tau : casadi.SX (n, 1) or sequence of n scalars
        Joint torques/forces (N m or N); None means zero. Friction is not included.

    Returns
    -------
    casadi.SX (n, 1)
        Joint accelerations qdd (rad/s^2 or m/s^2).
    """
    n = tree.n
    qs, vs, ts = split(q, n, "q"), split(v, n, "v"), split(tau, n, "tau")
    bodies = tree.bodies
    Xs = [JointX(b, qs[i]) for i, b in enumerate(bodies)]
    V, Cb, IA, pA = [], [], [], []
    for i, b in enumerate(bodies):                                  # pass 1
        vp = (zero3(), zero3()) if b.parent < 0 else V[b.parent]
        vi = add_s(b, *Xs[i].motion_in(*vp), vs[i])
        V.append(vi)
        Cb.append(bias_acceleration(b, *vi, vs[i]))
        IA.append(Inertia6.rigid(b))
        pA.append(cross_force(*vi, *rigid_force(b, *vi)))
    U, Dinv, u = [None] * n, [None] * n, [None] * n
    for i in range(n - 1, -1, -1):                                  # pass 2
        b = bodies[i]
        I = IA[i]
        ks = _s_index(b)
        Uf, Un = I.column(ks)
        Ui = Uf + Un
        D = add(Ui[ks], b.armature)
        Di = 2.0 / (D + D) if isinstance(D, ca.SX) else 1.0 / D   # keeps x * Di a product
        ui = sub(ts[i], s_transpose(b, *pA[i]))
        U[i], Dinv[i], u[i] = Ui, Di, ui
        if b.parent < 0:
            continue
        W = tuple(mul(x, Di) for x in Ui)
        exact = b.armature == 0.0

        def ent(r, c, val):          # I^a entry (r, c) of the 6x6, r, c in 0..5
            if exact and (r == ks or c == ks):
                return 0.0
            return sub(val, mul(W[r], Ui[c]))

        A = sym3(*(ent(r, c, I.A[r][c]) for r, c in _UPPER))
        C = sym3(*(ent(r + 3, c + 3, I.C[r][c]) for r, c in _UPPER))
        B = [[ent(r, c + 3, I.B[r][c]) for c in range(3)] for r in range(3)]
        Ia = Inertia6(A, B, C)
        cf, cn = Cb[i]
        gf, gn = Ia.times(cf, cn)
        pa = [add(add(x, y), mul(w_, ui))
              for x, y, w_ in zip(pA[i][0] + pA[i][1], gf + gn, W)]
        if exact:
            pa[ks] = ts[i]
        f, m = Xs[i].force_out(tuple(pa[:3]), tuple(pa[3:]))
        pp = pA[b.parent]
        pA[b.parent] = (vadd(pp[0], f), vadd(pp[1], m))
        IA[b.parent] = IA[b.parent].add(Xs[i].inertia_out(Ia))
    a0 = (tuple(-g for g in tree.gravity), zero3())
    Acc, qdd = [None] * n, [None] * n
    for i, b in enumerate(bodies):                                  # pass 3
        ap = a0 if b.parent < 0 else Acc[b.parent]
        av, aw = Xs[i].motion_in(*ap)
        cf, cn = Cb[i]
        av, aw = vadd(av, cf), vadd(aw, cn)
        qdd[i] = mul(Dinv[i], sub(u[i], dot(U[i], av + aw)))
        Acc[i] = add_s(b, av, aw, qdd[i])
    return column(qdd)
