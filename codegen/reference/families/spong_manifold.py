"""Reference Spong integral-manifold controller (docs/papers/seed004.md §10, docs/papers/experiments.md §12.4) in numpy, on the reference
elastic robot (codegen/reference/robots/elastic.py). Never imports CasADi or the symbolic code.

Static law, dummy state (nx = 1), no input, "estimate" = u. y = [x (4n); q_d .. q_d''''] (9n);
p = [K_P (n); K_D (n); K_f (2 per joint: eta, eta'); u_max]. With mu = K^{-1}, z = K(q1 - q2),
c = C(q1, q1') q1' + tau_f(q1') (Coriolis + friction, reference/robots/friction.py) and g = g(q1):

    u0 = (M + J)(q_d'' + K_P (q_d - q1) + K_D (q_d' - q1')) + c + g        [CODE-CP]
    a2 = -M^{-1}(c + g),  A2 = -(M^{-1} + J^{-1}),  B2 = -J^{-1}
    h0 = -A2^{-1}(a2 + B2 u0)                                               (4.18)
    u_s = u0 + mu B2^{-1} h0''                                              (4.17), (4.19)
    eta = z - h0,  eta' = K(q1' - q2') - h0'
    u_f = B2^{-1}(zeta - A2 eta),  zeta = K_f,eta eta + K_f,eta' eta'       (4.23)
    u = sat_{u_max}(u_s + u_f)

h0 is a function of w = (q1, q1', q_d, q_d', q_d''); along the closed loop w' = (q1', y3, q_d',
q_d'', q_d''') and w'' = (y3, y4, q_d'', q_d''', q_d'''') with y3, y4 the Spong coordinates
of x [CODE-CP]. One hyper-dual evaluation of h0 at w + e1 w' + e2 w' + e1 e2 w'' gives exactly

    h0' = Dh0[w']   (e1 part),    h0'' = D^2 h0[w', w'] + Dh0[w'']   (e1 e2 part).
"""
from __future__ import annotations


import numpy as np

from ..robots import hyperdual as hd
from ._family import bound
from .spong_fl import init, law_inputs, require_exact, rhs, sizes, spong_y3_y4_F  # noqa: F401


def configure(robot, options):
    """This law, after checking ``robot`` has exact derivatives; ``options`` declares nothing
    here."""
    require_exact(robot, "spong_manifold")
    return bound(__name__)


def _h0(robot, q, v, r0, r1, r2, KP, KD):
    """(u0, h0) for floats or hyper-duals (DH rigid part: generic arithmetic)."""
    rigid, J = robot.rigid, robot.J
    n = robot.n
    M = rigid.M(q)
    cg = rigid.nle(q, v) + rigid.friction_torque(v)          # c + g, c including tau_f(q1')
    u0 = (M + J) @ (r2 + (r0 - q) * KP + (r1 - v) * KD) + cg
    Minv = hd.solve(M, np.eye(n))
    A = Minv + robot.Jinv                                    # -A2
    return u0, hd.solve(A, -hd.solve(M, cg) - robot.Jinv @ u0)  # h0 = (-A2)^{-1}(-a2... ) (4.18)


def output(robot, x, y, u, p):
    """Motor torques u = sat(u_s + u_f) (n,), N m  [S004 (4.17)-(4.23)], [CODE-CP].

    ``robot``, ``x`` (dummy state, unused), ``y`` and ``u`` as in reference/spong_fl.py
    ``output``, but p = [K_P (n, 1/s^2); K_D (n, 1/s); K_f (eta, eta' per joint); u_max (N m)]."""
    n = robot.n
    xs, r, p = law_inputs("spong_manifold", robot, y, p)
    KP, KD, Kf, umax = p[:n], p[n:2 * n], p[2 * n:4 * n].reshape(n, 2), float(p[4 * n])
    J, K = robot.J, robot.K
    x1, x2, x3, x4 = robot.split(xs)
    y3, y4, _ = spong_y3_y4_F(robot, xs, with_F=False)

    # w, w', w'' blocks (q1, q1', q_d, q_d', q_d'')
    w = [x1, x2, r[0], r[1], r[2]]
    w1 = [x2, y3, r[1], r[2], r[3]]
    w2 = [y3, y4, r[2], r[3], r[4]]
    args = [hd.HyperDual(np.array(a, dtype=float), np.array(b, dtype=float), np.array(b, dtype=float),
                         np.array(d, dtype=float)) for a, b, d in zip(w, w1, w2)]
    u0h, h = _h0(robot, *args, KP, KD)
    u0, h0, dh0, ddh0 = u0h.a, h.a, h.b, h.d

    us = u0 + np.linalg.solve(K, -(J @ ddh0))                # u0 + mu B2^{-1} h0''
    M = np.asarray(robot.M(x1), dtype=float)
    A2 = -(np.linalg.inv(M) + robot.Jinv)
    eta = K @ (x1 - x3) - h0
    etad = K @ (x2 - x4) - dh0
    zeta = Kf[:, 0] * eta + Kf[:, 1] * etad
    uf = -J @ (zeta - A2 @ eta)                              # B2^{-1}(zeta - A2 eta)
    return np.clip(us + uf, -umax, umax)
