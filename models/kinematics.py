"""Forward kinematics on the spatial tree: centres of mass in the world frame."""
from __future__ import annotations

from models.algebra import column, dot, split, vadd, zero3
from models.spatial import JointX

__all__ = ["com_positions"]


def com_positions(tree, q):
    """World positions of the body centres of mass [p_1; ...; p_n]: (3n, 1) SX.

    Forward kinematics (Featherstone §4.1, composition of the joint placements)
    oR_i = oR_lambda E_i R_z(q_i),  op_i = op_lambda + oR_lambda p_i,
    p_com,i = op_i + oR_i c_i.

    Parameters
    ----------
    tree : models.tree.SpatialTree
        Bodies: placements, joint kinds, centres of mass.
    q : casadi.SX (n, 1) or sequence of n scalars
        Joint positions (rad or m).

    Returns
    -------
    casadi.SX (3n, 1)
        Centre of mass of each body moved by a joint (m), stacked in joint order.
    """
    n = tree.n
    qs = split(q, n, "q")
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    oR, op, out = [], [], []
    for i, b in enumerate(tree.bodies):
        X = JointX(b, qs[i])
        Rp, pp = (eye, zero3()) if b.parent < 0 else (oR[b.parent], op[b.parent])
        Rl, pl = X.rotation(), X.translation()
        Ri = [[dot(Rp[r], (Rl[0][c], Rl[1][c], Rl[2][c])) for c in range(3)] for r in range(3)]
        pi = vadd(pp, tuple(dot(Rp[r], pl) for r in range(3)))
        oR.append(Ri)
        op.append(pi)
        out.extend(vadd(pi, tuple(dot(Ri[r], b.com) for r in range(3))))
    return column(out)
