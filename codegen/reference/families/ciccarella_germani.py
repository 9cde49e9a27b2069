"""Reference Ciccarella-Germani observer O1-O4 (docs/papers/seed004.md §8) in numpy, on reference/elastic.py.

    xhat' = f(xhat) + G u + Q(xhat)^{-1} Kg (y - H(xhat))                 [S004 (3.10)]

Q is assembled in the channel-major order of docs/papers/seed004.md §8 (per joint [q, q', q'', q'''] for O1/O2,
docs/papers/seed004.md §8.3 closed forms, derivatives exact by hyper-duals) or written out as the constant
matrix of the linear Phi (O3, O4; docs/papers/seed004.md §8.4), and solved by a plain LU (np.linalg.solve)
-- not the block forward substitution of the generated code.

Parameters: one gain per row of Phi (channel-major), then ``rcond_min`` (unused here: the
reference has no conditioning guard). The variant is the spec's declared option
(codegen.core.options.VariantOptions), bound by ``configure``.
"""
from __future__ import annotations

import numpy as np

from ._family import bound

VARIANTS = ("O1", "O2", "O3", "O4")


def configure(robot, options):
    """This family bound to the variant the spec declares.

    Parameters
    ----------
    robot : reference elastic robot
    options : codegen.core.options.VariantOptions

    Returns
    -------
    family bound to ``variant``
    """
    variant = getattr(options, "variant", None)
    if variant not in VARIANTS:
        raise ValueError(f"options: unknown Ciccarella-Germani variant {variant!r} (one of {VARIANTS})")
    return bound(__name__, variant=variant)


def _phi_Q(robot, variant, x):
    """(Phi, Q) channel-major for the variant at x."""
    n = robot.n
    K, JK = robot.K, robot.Jinv @ robot.K
    Z, I = np.zeros((n, n)), np.eye(n)
    if variant in ("O1", "O2"):
        phi_l, Q_l = robot.spong_jacobian(x)                   # level-major [x1; x2; y3; y4]
        perm = [l * n + i for i in range(n) for l in range(4)]  # -> per joint [q, q', q'', q''']
        return phi_l[perm], Q_l[perm]
    x1, x2, x3, x4 = robot.split(x)
    if variant == "O4":                                        # Phi1 = [x3, x4, J^-1K(x1-x3), J^-1K(x2-x4)]
        Q_l = np.block([[Z, Z, I, Z], [Z, Z, Z, I], [JK, Z, -JK, Z], [Z, JK, Z, -JK]])
        perm = [l * n + i for i in range(n) for l in range(4)]
    else:                                                      # O3: [x3_i, x4_i]_i, [tau_i, tau_i']_i
        Q_l = np.block([[Z, Z, I, Z], [Z, Z, Z, I], [K, Z, -K, Z], [Z, K, Z, -K]])
        perm = ([l * n + i for i in range(n) for l in range(2)]
                + [(2 + l) * n + i for i in range(n) for l in range(2)])
    return (Q_l @ x)[perm], Q_l[perm]


def _H_and_rows(robot, variant, x):
    """(H(x), row_error) of the variant (docs/papers/seed004.md §8.4)."""
    n = robot.n
    x1, x2, x3, _ = robot.split(x)
    if variant == "O1":
        return x1, [i for i in range(n) for _ in range(4)]
    if variant == "O4":
        return x3, [i for i in range(n) for _ in range(4)]
    if variant == "O2":
        return np.ravel(np.column_stack([x1, x2])), [2 * i + (l > 0) for i in range(n) for l in range(4)]
    return np.concatenate([x3, robot.K @ (x1 - x3)]), [i for i in range(2 * n) for _ in range(2)]


def rhs(robot, x, y, u, p, variant):
    """xhat' = f(xhat) + G u + Q(xhat)^{-1} Kg (y - H(xhat))  [S004 (3.10)].

    Parameters
    ----------
    robot : reference elastic robot (n joints)
    x : (4n,) array
        xhat = [q1; q1'; q2; q2'] (rad, rad/s).
    y : (n,) or (2n,) array
        The variant's measurement H(x) (docs/papers/seed004.md §8.4): O1 q1, O2 [q1_i, q1'_i]_i, O3 [q2; tau_el],
        O4 q2.
    u : (n,) array
        Motor torques, N m.
    p : (4n + 1,) array
        Kg (one gain per row of Phi, channel-major), rcond_min (unused).
    variant : {"O1", "O2", "O3", "O4"}

    Returns
    -------
    (4n,) array
    """
    H, row_error = _H_and_rows(robot, variant, x)
    e = y - H
    v = p[:robot.nx] * e[row_error]
    _, Q = _phi_Q(robot, variant, x)
    return robot.xdot(x, u) + np.linalg.solve(Q, v)


def output(robot, x, y, u, p):
    """est = xhat (4n,): the state ``x`` itself; ``robot``, ``y``, ``u``, ``p`` as in ``rhs``
    (unused)."""
    return np.array(x, dtype=float)


def init(robot, y0, est0, p):
    """xhat(0) = est0 (4n,) [CODE-CP]; ``robot``, y0 (as ``rhs``'s y) and ``p`` are not read."""
    return np.array(est0, dtype=float)


def sizes(robot, variant):
    """{"nx": 4n, "ny": n (O1, O4) or 2n (O2, O3), "nu": n, "nest": 4n} for ``robot`` (n joints)
    and ``variant`` (docs/papers/seed004.md §8.4)."""
    n = robot.n
    ny = {"O1": n, "O4": n, "O2": 2 * n, "O3": 2 * n}[variant]
    return {"nx": 4 * n, "ny": ny, "nu": n, "nest": 4 * n}
