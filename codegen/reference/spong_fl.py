"""Reference Spong feedback-linearising controller (SPEC §9, §12.4) in numpy, on the reference
elastic robot (codegen/reference/elastic.py). Never imports CasADi or the symbolic code.

A static law with a 1-slot dummy state (nx = 1, never changes), no input; its "estimate" is the
motor torque u. Measurement y = [x (4n); q_d; q_d'; q_d''; q_d'''; q_d''''] (9n);
p = [Kc (4 per joint, joint-major: Kc0_j, Kc1_j, Kc2_j, Kc3_j); u_max].

    Phi(x) = [y1; y2; y3; y4] = [q1; q1'; q1''; q1'''],  y4' = F(x) + M^{-1} K J^{-1} u
    nu = q_d'''' + K_c (Phi - y_d)                                         [S004 (4.7)]
    u  = sat_{u_max}( J K^{-1} M(q1) (nu - F(x)) )                         [S004 (4.5)], §12.4

y3, y4 and F = L_f y4 are exact (hyper-dual numbers on the Newton-Euler DH recursion of
ElasticRobot); robots without exact derivatives are refused. F in one hyper-dual evaluation:
with y4 = Dy3[f] and y3 independent of x4,

    F = L_f y4 = D^2 y3[f, f] + Dy3[Df f],   Df f = [y3; y4; J^{-1}K(x1 - x3); *]  (= x'' blocks)

the e1 e2 part of y3(x + e1 f + e2 f + e1 e2 Df f)  [DERIVED; equals ElasticRobot.spong_F,
which forms dPhi/dx column by column, checked in tests/test_controllers.py].
"""
from __future__ import annotations

import numpy as np

from . import elastic as E


def require_exact(robot, family):
    if not getattr(robot, "exact", False):
        raise ValueError(f"{family}: needs an elastic robot over a DH rigid part (exact hyper-dual "
                         f"derivatives); got {getattr(robot, 'name', robot)!r}")


def split_measurement(robot, y):
    """(x, [q_d, q_d', q_d'', q_d''', q_d'''']) of a 9n measurement."""
    n = robot.n
    y = np.asarray(y, dtype=float)
    return y[:4 * n], [y[(4 + k) * n:(5 + k) * n] for k in range(5)]


def spong_y3_y4_F(robot, x, with_F=True):
    """(y3, y4, F) of the elastic state x, exact (two hyper-dual evaluations of y3; F None
    and one evaluation when not with_F)."""
    n = robot.n
    x = np.asarray(x, dtype=float)
    y3 = np.asarray(robot.y3(x), dtype=float)
    x1, x2, x3, x4 = robot.split(x)
    f = np.concatenate([x2, y3, x4, robot.Jinv @ robot.K @ (x1 - x3)])
    y4 = robot.y3(E.seeded(x, f)).b                         # Dy3[f]
    if not with_F:
        return y3, y4, None
    ff = np.concatenate([y3, y4, robot.Jinv @ robot.K @ (x1 - x3), np.zeros(n)])
    h = robot.y3(E.HyperDual(x, f.copy(), f.copy(), ff))
    return y3, y4, h.d


def rhs(robot, x, y, u, p):
    return np.zeros(1)


def init(robot, y0, est0, p):
    return np.zeros(1)


def sizes(robot):
    n = robot.n
    return {"nx": 1, "ny": 9 * n, "nu": 0, "nest": n}


def configure(robot, options):
    require_exact(robot, "spong_fl")
    return _THIS


def output(robot, x, y, u, p):
    n = robot.n
    require_exact(robot, "spong_fl")
    if len(p) != 4 * n + 1:
        raise ValueError(f"spong_fl: expected {4 * n + 1} parameters, got {len(p)}")
    xs, ref = split_measurement(robot, y)
    Kc, umax = np.asarray(p[:4 * n], dtype=float).reshape(n, 4), float(p[4 * n])
    x1, x2, _, _ = robot.split(xs)
    y3, y4, F = spong_y3_y4_F(robot, xs)
    phi = [x1, x2, y3, y4]
    nu = ref[4].copy()
    for k in range(4):                                  # row of joint i acts on [e_i, e_i', e_i'', e_i''']
        nu = nu + Kc[:, k] * (phi[k] - ref[k])
    M = np.asarray(robot.M(x1), dtype=float)
    ures = robot.J @ np.linalg.solve(robot.K, M @ (nu - F))
    return np.clip(ures, -umax, umax)


_THIS = __import__("sys").modules[__name__]
