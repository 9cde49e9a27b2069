"""Reference Spong feedback-linearising controller (docs/papers/seed004.md §9, docs/papers/experiments.md §12.4) in numpy, on the reference
elastic robot (codegen/reference/robots/elastic.py). Never imports CasADi or the symbolic code.

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

from ._family import bound
from ._law import constant_state, parameters
from ..robots.hyperdual import HyperDual, seeded

rhs, init = constant_state(1)


def require_exact(robot, family):
    """ValueError, naming the law ``family``, unless ``robot`` is elastic over a DH rigid part
    (exact hyper-dual derivatives)."""
    if not getattr(robot, "exact", False):
        raise ValueError(f"{family}: needs an elastic robot over a DH rigid part (exact hyper-dual "
                         f"derivatives); got {getattr(robot, 'name', robot)!r}")


def law_inputs(family, robot, y, p):
    """The checked inputs of a Spong law (docs/papers/experiments.md §12.4).

    Parameters
    ----------
    family : str
        The law's name, for errors.
    robot : reference elastic robot over a DH rigid part (n joints)
    y : (9n,) array
        [x (4n: rad, rad/s); q_d; q_d'; q_d''; q_d'''; q_d''''] (rad, rad/s^k).
    p : (4n + 1,) array

    Returns
    -------
    x : (4n,) array
    ref : list of five (n,) arrays
        q_d and its first four derivatives.
    p : (4n + 1,) float array
    """
    require_exact(robot, family)
    n = robot.n
    y = np.asarray(y, dtype=float)
    return y[:4 * n], [y[(4 + k) * n:(5 + k) * n] for k in range(5)], parameters(family, p, 4 * n + 1)


def spong_y3_y4_F(robot, x, with_F=True):
    """Spong's y3, y4 and F = L_f y4 of an elastic state, exact (docs/papers/seed004.md §9, [DERIVED] above).

    Parameters
    ----------
    robot : reference elastic robot over a DH rigid part (n joints)
    x : (4n,) array
        [q1; q1'; q2; q2'] (rad, rad/s).
    with_F : bool
        Also F (a second hyper-dual evaluation of y3).

    Returns
    -------
    y3, y4 : (n,) arrays
        q1'' (rad/s^2), q1''' (rad/s^3).
    F : (n,) array or None
        rad/s^4; None when not ``with_F``.
    """
    n = robot.n
    x = np.asarray(x, dtype=float)
    y3 = np.asarray(robot.y3(x), dtype=float)
    x1, x2, x3, x4 = robot.split(x)
    f = np.concatenate([x2, y3, x4, robot.Jinv @ robot.K @ (x1 - x3)])
    y4 = robot.y3(seeded(x, f)).b                           # Dy3[f]
    if not with_F:
        return y3, y4, None
    ff = np.concatenate([y3, y4, robot.Jinv @ robot.K @ (x1 - x3), np.zeros(n)])
    h = robot.y3(HyperDual(x, f.copy(), f.copy(), ff))
    return y3, y4, h.d


def sizes(robot):
    """nx = 1 (dummy), ny = 9n, nu = 0, nest = n, for ``robot`` with n joints."""
    n = robot.n
    return {"nx": 1, "ny": 9 * n, "nu": 0, "nest": n}


def configure(robot, options):
    """This law, after checking ``robot`` has exact derivatives; ``options`` declares nothing
    here."""
    require_exact(robot, "spong_fl")
    return bound(__name__)


def output(robot, x, y, u, p):
    """Motor torque u = sat(J K^{-1} M (nu - F))  [S004 (4.5), (4.7)].

    Parameters
    ----------
    robot : reference elastic robot over a DH rigid part (n joints)
    x : (1,) array
        Dummy state (unused).
    y : (9n,) array
        See ``law_inputs``.
    u : (0,) array
    p : (4n + 1,) array
        [Kc (joint-major, 4 per joint); u_max (N m)].

    Returns
    -------
    (n,) array
        Motor torques, N m.
    """
    n = robot.n
    xs, ref, p = law_inputs("spong_fl", robot, y, p)
    Kc, umax = p[:4 * n].reshape(n, 4), float(p[4 * n])
    x1, x2, _, _ = robot.split(xs)
    y3, y4, F = spong_y3_y4_F(robot, xs)
    phi = [x1, x2, y3, y4]
    nu = ref[4].copy()
    for k in range(4):                                  # row of joint i acts on [e_i, e_i', e_i'', e_i''']
        nu = nu + Kc[:, k] * (phi[k] - ref[k])
    M = np.asarray(robot.M(x1), dtype=float)
    ures = robot.J @ np.linalg.solve(robot.K, M @ (nu - F))
    return np.clip(ures, -umax, umax)
