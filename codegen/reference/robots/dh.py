"""Reference DH robots (docs/papers/experiments.md §11.3, §11.4): a Newton-Euler recursion on the DH table.

Written with the generic arithmetic of reference/hyperdual.py, so it runs on floats and on
hyper-dual arrays (exact first and second derivatives). M(q) comes from the same recursion
(column j = RNEA(q, 0, e_j) without gravity), not from the CoM Jacobians of ``models.dh``:
a second, independent derivation of

    M(q) qdd + C(q, qd) qd + tau_f(qd) + g(q) = tau          [S000 (1)]

with the friction tau_f of reference/robots/friction.py.
"""
from __future__ import annotations

import numpy as np

from .friction import Friction
from .hyperdual import cos, cross, dot, sin, solve, stack


class DHRobot(Friction):
    """Revolute DH robot by the Newton-Euler recursion in frame 0.

    Frame i: A_i = Rot_z(theta_i + q_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i); link i has
    mass m_i, CoM rc_i and inertia I_i (about the CoM) in frame i; gravity g0 in frame 0.

    Parameters
    ----------
    source : dict
        ``{"kind": "dh", "name", "dh": (n, 4) rows [alpha (rad), d (m), a (m), theta (rad)],
        "masses": (n,) kg, "coms": (n, 3) m, "inertias": (n, 3, 3) kg m^2, "gravity": (3,) m/s^2,
        "F": (n,) N m s (optional, viscous friction)}``.
    """

    def __init__(self, source):
        self.name = source.get("name", "dh")
        self.dh = np.asarray(source["dh"], dtype=float)
        self.n = self.dh.shape[0]
        self.m = np.asarray(source["masses"], dtype=float)
        self.rc = np.asarray(source["coms"], dtype=float)
        self.I = np.asarray(source["inertias"], dtype=float)
        self.g0 = np.asarray(source["gravity"], dtype=float)
        self.F = np.diag(np.asarray(source.get("F", np.zeros(self.n)), dtype=float))

    def _frames(self, q):
        """[(R_i, o_i)] of frames 0..n in frame 0 (floats or hyper-duals)."""
        R, o = np.eye(3), np.zeros(3)
        out = [(R, o)]
        for i, (alpha, d, a, theta) in enumerate(self.dh):
            ct, st = cos(q[i] + theta), sin(q[i] + theta)
            cal = 0.0 if abs(np.cos(alpha)) < 1e-15 else np.cos(alpha)
            sal = 0.0 if abs(np.sin(alpha)) < 1e-15 else np.sin(alpha)
            Ri = stack([stack([ct, -st * cal, st * sal]), stack([st, ct * cal, -ct * sal]),
                        stack([0.0 * ct, 0.0 * ct + sal, 0.0 * ct + cal])])
            o = o + R @ stack([a * ct, a * st, 0.0 * ct + d])
            R = R @ Ri
            out.append((R, o))
        return out

    def rnea(self, q, v, a, gravity=True):
        """tau = M(q) a + C(q, v) v + g(q) by Newton-Euler, all vectors in frame 0 (no friction).

        Parameters
        ----------
        q, v, a : (n,) arrays or HyperDual
            Joint angles (rad), velocities (rad/s), accelerations (rad/s^2).
        gravity : bool
            Include g(q) (the base accelerates by -g0).

        Returns
        -------
        (n,) array or HyperDual
            Joint torques (N m).
        """
        fr = self._frames(q)
        w, wd = np.zeros(3), np.zeros(3)
        acc = -self.g0 if gravity else np.zeros(3)          # base acceleration trick
        links = []
        for i in range(self.n):
            z = fr[i][0][:, 2]
            R, o = fr[i + 1]
            wd = wd + z * a[i] + cross(w, z * v[i])
            w = w + z * v[i]
            r = o - fr[i][1]
            acc = acc + cross(wd, r) + cross(w, cross(w, r))          # origin of frame i
            rc = R @ self.rc[i]
            ac = acc + cross(wd, rc) + cross(w, cross(w, rc))         # CoM of link i
            Iw = R @ self.I[i] @ R.T
            links.append((z, fr[i][1], o + rc, ac, w, wd, Iw))
        f, mu, tau = np.zeros(3), np.zeros(3), [None] * self.n
        for i in range(self.n - 1, -1, -1):              # mu: moment about o_{i-1} (joint i axis)
            z, o_prev, pc, ac, w, wd, Iw = links[i]
            fi = self.m[i] * ac
            mu = (mu + cross(fr[i + 1][1] - o_prev, f) + cross(pc - o_prev, fi)
                  + Iw @ wd + cross(w, Iw @ w))
            f = f + fi
            tau[i] = dot(z, mu)
        return stack(tau)

    def M(self, q):
        """Mass matrix (n, n), kg m^2: column j = rnea(q, 0, e_j) without gravity."""
        cols = [self.rnea(q, np.zeros(self.n), e, gravity=False) for e in np.eye(self.n)]
        return stack(cols, axis=1)

    def g(self, q):
        """Gravity torque g(q) (n,), N m."""
        z = np.zeros(self.n)
        return self.rnea(q, z, z)

    def nle(self, q, v):
        """Non-linear effects C(q, v) v + g(q) (n,), N m."""
        return self.rnea(q, v, np.zeros(self.n))

    def forward_dynamics(self, q, v, tau):
        """qdd = M(q)^{-1}(tau - C(q, v) v - tau_f(v) - g(q))  [S000 (1)] (n,), rad/s^2, tau_f the
        friction (``friction_torque``); q, v, tau may be hyper-dual."""
        return solve(self.M(q), tau - self.nle(q, v) - self.friction_torque(v))
