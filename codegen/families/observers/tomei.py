"""Tomei's observer for elastic-joint robots (TAC 35(6), 1990; seed 004 §3.1, docs/papers/seed004.md §7).

Measured: link position and velocity y = [q1; q1'], input u. With e = q - qhat (consistent sign
convention of docs/papers/seed004.md §7, Ka_eff restoring, A4-6):

    M(q1) qhat1'' = -S(q1, q1') qhat1' - tau_f(qhat1') - K(qhat1 - qhat2) - g(q1) + Ka (q1 - qhat1) - v1
    J qhat2''     =  K(qhat1 - qhat2) + u
    z'            = -A z + (q1' - qhat1')
    v1            = -K1 z - K2 (q1' - qhat1')                          [S004 (3.1)-(3.3)]

S is the Christoffel matrix, tau_f the rigid model's friction F v + coulomb tanh(v / w) + offset
(models/robot.py; [S004 (3.1)] has the viscous F qhat1', zero for the seed robots), at the estimate
as F qhat1' is: tau_f is monotone, so the error's friction term still dissipates.
State [qhat1, qhat1', qhat2, qhat2', z] (5n); estimate the first 4n. Gains A, K1, K2, Ka are
diagonal runtime parameters; K1 solves A^T K1 + K1 A = Q_lyap (design.tomei_K1).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..design import tomei_K1
from ...core.spec import ObserverSpec

# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py);
# seed 004's sample time: the default gains need it
EXAMPLES = [{"robot": "seed004_2r", "elastic": True, "dt": 1e-4}]

ROBOT = "elastic"   # needs an ElasticRobot (codegen.pipeline.targets_file checks it before building)


def build(robot, A=2000.0, K2=2000.0, Ka=10000.0, Q_lyap=2000.0, K1=None):
    """Tomei observer (docs/papers/seed004.md §7) for the ElasticRobot ``robot``; gains A, K2, Ka, Q_lyap (each a
    scalar or (n,), > 0) default to the seed's Sim-1 gains, K1 ((n,)) to the solution of the
    Lyapunov equation with A and Q_lyap (0.5 I)."""
    n = robot.n
    d = lambda v: np.broadcast_to(np.asarray(v, dtype=float), (n,)).copy()  # noqa: E731
    A, K2, Ka, Q_lyap = d(A), d(K2), d(Ka), d(Q_lyap)
    if np.any(A <= 0) or np.any(K2 <= 0) or np.any(Ka <= 0) or np.any(Q_lyap <= 0):
        raise ValueError("Tomei gains A, K2, Ka, Q_lyap must be positive (docs/papers/seed004.md §7, Thm 3.1)")
    K1 = d(np.diag(tomei_K1(np.diag(A), np.diag(Q_lyap)))) if K1 is None else d(K1)

    rigid, Kst, J = robot.rigid, ca.DM(robot.K), ca.DM(robot.J)
    x, y, u = ca.SX.sym("x", 5 * n), ca.SX.sym("y", 2 * n), ca.SX.sym("u", n)
    pA, pK1, pK2, pKa = (ca.SX.sym(s, n) for s in ("A", "K1", "K2", "Ka"))
    qh1, vh1, qh2, vh2, z = (x[i * n:(i + 1) * n] for i in range(5))
    q1, v1m = y[:n], y[n:]
    ev = v1m - vh1
    v1 = -pK1 * z - pK2 * ev                                              # [S004 (3.2)]
    rhs1 = (-ca.mtimes(rigid.coriolis(q1, v1m), vh1) - rigid.friction_torque(vh1)
            - ca.mtimes(Kst, qh1 - qh2) - rigid.gravity(q1) + pKa * (q1 - qh1) - v1)   # [S004 (3.1)] A4-6
    acc1 = ca.solve(rigid.mass_matrix(q1), rhs1)
    acc2 = ca.solve(J, ca.mtimes(Kst, qh1 - qh2) + u)
    xdot = ca.vertcat(vh1, acc1, vh2, acc2, -pA * z + ev)                 # [S004 (3.3)]
    p = ca.vertcat(pA, pK1, pK2, pKa)
    y0, est0 = ca.SX.sym("y0", 2 * n), ca.SX.sym("est0", 4 * n)
    j = robot.joint_names
    return ObserverSpec(
        family="tomei", robot=robot,
        x_names=[f"{s}_hat" for s in robot.state_names] + [f"z_{a}" for a in j],
        y_names=[f"q1_{a}" for a in j] + [f"q1d_{a}" for a in j],
        u_names=[f"u_{a}" for a in j],
        p_names=[f"{g}_{a}" for g in ("A", "K1", "K2", "Ka") for a in j],
        est_names=[f"{s}_hat" for s in robot.state_names],
        p_default=np.concatenate([A, K1, K2, Ka]),
        rhs=ca.Function("rhs", [x, y, u, p], [xdot]),
        output=ca.Function("output", [x, y, u, p], [x[:4 * n]]),
        init=ca.Function("init", [y0, est0, p], [ca.vertcat(est0, ca.SX.zeros(n))]),  # filter x0 = 0 [CODE-CP]
        measurement=ca.Function("measurement", [est0], [est0[:2 * n]]),               # y = (q1, q1')
        design={"Q_lyap": Q_lyap.tolist(), "K1_from_lyapunov": K1.tolist()},
    )
