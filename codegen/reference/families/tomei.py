"""Reference Tomei observer (docs/papers/seed004.md §7) in numpy; same equations as codegen/families/observers/tomei.py,
written from docs/papers/seed004.md §7 on the reference elastic robot (S(q1, q1') qhat1' by polarisation of the
Newton-Euler c(q, v) = C(q, v) v, see christoffel_times).

    M(q1) qhat1'' = -S(q1,q1') qhat1' - tau_f(qhat1') - K(qhat1 - qhat2) - g(q1) + Ka(q1 - qhat1) - v1
    J qhat2'' = K(qhat1 - qhat2) + u,   z' = -A z + (q1' - qhat1'),   v1 = -K1 z - K2 (q1' - qhat1')

x = [qhat1, qhat1', qhat2, qhat2', z] (n each; rad, rad/s), y = [q1 (rad); q1' (rad/s)],
u = motor torque (n, N m), p = [A (1/s), K1, K2, Ka (n each)], est = x[:4n].
"""
from __future__ import annotations

import numpy as np


def christoffel_times(rigid, q, v, w):
    """C(q, v) w for the Christoffel C, without forming C on a rigid part that has none.

    With c(q, a) = C(q, a) a (Newton-Euler with zero acceleration, gravity removed) and the
    symmetry C(q, a) b = C(q, b) a [docs/papers/seed000.md §0]:

        C(q, v) w = 1/2 [c(q, v + w) - c(q, v) - c(q, w)]   (polarisation)  [DERIVED]

    Parameters
    ----------
    rigid : reference rigid robot (n joints)
    q : (n,) array
        rad.
    v, w : (n,) arrays
        rad/s.

    Returns
    -------
    (n,) array
        N m.
    """
    if hasattr(rigid, "C"):
        return rigid.C(q, v) @ w
    z = np.zeros_like(q)
    c = lambda a: rigid.nle(q, a) - rigid.nle(q, z)           # noqa: E731
    return 0.5 * (c(v + w) - c(v) - c(w))


def rhs(robot, x, y, u, p):
    """x' of the Tomei observer (docs/papers/seed004.md §7, module docstring).

    Parameters
    ----------
    robot : reference elastic robot (n joints)
    x : (5n,) array
        [qhat1; qhat1'; qhat2; qhat2'; z].
    y : (2n,) array
        [q1 (rad); q1' (rad/s)].
    u : (n,) array
        Motor torques, N m.
    p : (4n,) array
        [A; K1; K2; Ka].

    Returns
    -------
    (5n,) array
    """
    n = robot.n
    qh1, vh1, qh2, vh2, z = (x[i * n:(i + 1) * n] for i in range(5))
    q1, v1m = y[:n], y[n:]
    A, K1, K2, Ka = (p[i * n:(i + 1) * n] for i in range(4))
    rigid, K = robot.rigid, robot.K
    ev = v1m - vh1
    v1 = -K1 * z - K2 * ev
    rhs1 = (-christoffel_times(rigid, q1, v1m, vh1) - rigid.friction_torque(vh1) - K @ (qh1 - qh2)
            - rigid.g(q1) + Ka * (q1 - qh1) - v1)
    acc1 = np.linalg.solve(robot.M(q1), rhs1)
    acc2 = robot.Jinv @ (K @ (qh1 - qh2) + u)
    return np.concatenate([vh1, acc1, vh2, acc2, -A * z + ev])


def output(robot, x, y, u, p):
    """est = [qhat1; qhat1'; qhat2; qhat2'] (4n,), the first 4n entries of the state ``x``;
    ``robot``, ``y``, ``u``, ``p`` as in ``rhs`` (unused)."""
    return np.array(x[:4 * robot.n], dtype=float)


def init(robot, y0, est0, p):
    """x(0) = [est0 (4n); 0 (n)]: the filter starts at rest [CODE-CP]; est0 as ``output``'s
    result, ``robot`` and ``p`` as in ``rhs``, ``y0`` unused."""
    return np.concatenate([est0, np.zeros(robot.n)])


def sizes(robot):
    """{"nx": 5n, "ny": 2n, "nu": n, "nest": 4n} for ``robot`` with n joints."""
    n = robot.n
    return {"nx": 5 * n, "ny": 2 * n, "nu": n, "nest": 4 * n}
