"""Reference elastic-joint robots (docs/papers/seed004.md §6) in numpy, over a reference rigid robot.

Not an observer family (no ``rhs``): the reference families ``ciccarella_germani``, ``tomei``
and the Spong controllers build on it. The rigid part is given (reference/robots.py builds it
from ``source["rigid"]``). Over a DH rigid part (reference/dh.py) derivatives are exact by
hyper-dual numbers (reference/hyperdual.py):

    y3 = -M^{-1}(c + g + K(x1 - x3)) = FD(x1, x2, -K(x1 - x3))          (c includes tau_f(q1'))
    y4 = D y3 [f(x)]
    dy4/dx_j = D^2 y3 [f, e_j] + D y3 [df/dx_j]

over a URDF rigid part, first derivatives come from pinocchio's analytic ABA derivatives.
"""
from __future__ import annotations

import numpy as np

from .dh import DHRobot
from .hyperdual import seeded


class ElasticRobot:
    """Elastic-joint robot x = [q1; q1'; q2; q2'] (docs/papers/seed004.md §6) over a reference rigid robot.

    Parameters
    ----------
    rigid : reference rigid robot
        The link side (reference/dh.py ``DHRobot``, or a reference/rigid.py robot).
    J : (n,) array_like
        Motor inertias, kg m^2.
    K : (n,) array_like
        Joint stiffnesses, N m/rad.
    name : str
    """

    def __init__(self, rigid, J, K, name="elastic"):
        self.name = name
        self.rigid = rigid
        self.n = rigid.n
        self.nx = 4 * self.n
        self.J = np.diag(np.asarray(J, dtype=float))
        self.K = np.diag(np.asarray(K, dtype=float))
        self.Jinv = np.linalg.inv(self.J)
        self.exact = isinstance(rigid, DHRobot)   # hyper-dual derivatives available

    def split(self, x):
        """(x1, x2, x3, x4) = (q1, q1', q2, q2') blocks of n of a state ``x`` (4n,)."""
        n = self.n
        return x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n:]

    def M(self, q):
        """Link mass matrix M(q1) (n, n), kg m^2, at link positions ``q`` (n,), rad."""
        return self.rigid.M(q)

    def y3(self, x):
        """q1'' = FD(x1, x2, -K(x1 - x3))  [S004 (2.8)] (n,), rad/s^2; x may be hyper-dual."""
        x1, x2, x3, _ = self.split(x)
        return self.rigid.forward_dynamics(x1, x2, -(self.K @ (x1 - x3)))

    def f(self, x):
        """Drift f(x) (4n,)  [S004 (2.8)-(2.11)]."""
        x1, x2, x3, x4 = self.split(x)
        return np.concatenate([x2, self.y3(x), x4, self.Jinv @ self.K @ (x1 - x3)])

    def xdot(self, x, u):
        """x' = f(x) + G u with G = [0; 0; 0; J^{-1}]  [S004 (2.8)-(2.11)]; u motor torques (n,), N m."""
        xd = self.f(x)
        xd[3 * self.n:] += self.Jinv @ u
        return xd

    # --------------------------------------------------- Spong coordinates and derivatives
    def _Dy3(self, x, d):
        """D y3(x)[d] (directional derivative; only the first 3n entries of d matter)."""
        if self.exact:
            return self.y3(seeded(x, d)).b
        return self._Dy3_pin(x, d)

    def _Dy3_pin(self, x, d):
        """D y3 by pinocchio's analytic ABA derivatives (URDF robots): exact first order."""
        rob = self.rigid
        if not hasattr(rob, "pin_q"):
            raise ValueError(f"elastic robot {self.name!r}: derivatives of y3 need a DH (hyper-dual) or "
                             f"URDF (pinocchio) rigid part, got {type(rob).__name__}")
        pin = rob._pin
        x1, x2, x3, _ = self.split(x)
        d1, d2, d3, _ = self.split(d)
        tau = -(self.K @ (x1 - x3)) - rob.friction_torque(x2)
        pin.computeABADerivatives(rob.model, rob.data, rob.pin_q(x1), x2, tau)
        dq, dv = np.array(rob.data.ddq_dq), np.array(rob.data.ddq_dv)
        Minv = np.array(rob.data.Minv)
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        # the friction enters through the torque: d tau / d x2 = -d tau_f/dv
        return dq @ d1 + dv @ d2 + Minv @ (-(self.K @ (d1 - d3)) - rob.friction_jacobian(x2) @ d2)

    def y4(self, x):
        """q1''' = D y3 [f(x)] = f4(x1, x2, x3) + M^{-1} K x4  (docs/papers/seed004.md §8.3) (n,), rad/s^3."""
        return self._Dy3(x, self.f(x))

    def spong_jacobian(self, x, fd_step=1e-5):
        """Spong coordinates and their Jacobian (docs/papers/seed004.md §8.3).

        DH robots: exact by hyper-duals. URDF robots: rows of y4 by central differences of the
        exact (pinocchio first-order) y4, O(fd_step^2) [no second-order ABA derivatives].

        Parameters
        ----------
        x : (4n,) array
            Elastic state [q1; q1'; q2; q2'] (rad, rad/s).
        fd_step : float
            Central-difference step of the URDF rows of dy4/dx.

        Returns
        -------
        Phi : (4n,) array
            [x1; x2; y3; y4] (level-major).
        Q : (4n, 4n) array
            dPhi/dx.
        """
        n, nx = self.n, self.nx
        fx = self.f(x)
        Q = np.zeros((nx, nx))
        Q[:2 * n, :2 * n] = np.eye(2 * n)
        E = np.eye(nx)
        if self.exact:
            # y3 does not depend on x4: its columns there are 0 (first and second order)
            d2 = np.zeros((n, nx))
            for j in range(3 * n):
                h = self.y3(seeded(x, fx, E[j]))                  # D y3[f], D y3[e_j], D^2 y3[f, e_j]
                Q[2 * n:3 * n, j], d2[:, j] = h.c, h.d
            Dy3 = Q[2 * n:3 * n]
            for j, e in enumerate(E):   # d y4/dx_j = D^2 y3[f, e_j] + D y3[df/dx_j], D y3 linear
                df = np.concatenate([e[n:2 * n], Dy3[:, j], e[3 * n:], self.Jinv @ self.K @ (e[:n] - e[2 * n:3 * n])])
                Q[3 * n:, j] = d2[:, j] + Dy3 @ df
        else:
            for j, e in enumerate(E):
                Q[2 * n:3 * n, j] = self._Dy3(x, e)
                Q[3 * n:, j] = (self.y4(x + fd_step * e) - self.y4(x - fd_step * e)) / (2 * fd_step)
        x1, x2, _, _ = self.split(x)
        return np.concatenate([x1, x2, self.y3(x), self.y4(x)]), Q

    def spong_F(self, x):
        """F(x) = L_f y4 (docs/papers/seed004.md §9), the drift of y4' = F(x) + M^{-1} K J^{-1} u (n,), rad/s^4."""
        _, Q = self.spong_jacobian(x)
        return Q[3 * self.n:] @ self.f(x)
