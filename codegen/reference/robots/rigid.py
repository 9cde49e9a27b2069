"""Reference rigid robots given by formulas: numbers only (numpy), from the papers' equations (docs/papers/).

Every reference robot gives the rigid model of docs/papers/seed000.md §0 with joint friction

    M(q) qdd + C(q, qd) qd + tau_f(qd) + g(q) = tau          [S000 (1)]
    tau_f(v) = F v + coulomb tanh(v / w) + offset             (reference/robots/friction.py)

as plain functions of numpy vectors: ``n``, ``M(q)``, ``C(q, v)`` (Christoffel),
``g(q)``, ``F`` (n x n), ``friction_torque(v)``, ``nle(q, v) = C v + g`` and
``forward_dynamics(q, v, tau) = M^{-1}(tau - C v - tau_f(v) - g)``. Angles in rad, torques in N m.
"""
from __future__ import annotations

import numpy as np

from .friction import Friction


class ReferenceRobot(Friction):
    """Common numeric interface of the rigid reference robots  [S000 (1)].

    Subclasses give ``name``, ``n``, ``F`` and the methods below; arrays are float64, angles
    in rad (positions in m for prismatic joints), torques in N m.

    Attributes
    ----------
    n : int
        Degrees of freedom.
    F : (n, n) array
        Viscous friction, N m s/rad.
    coulomb, offset, coulomb_width
        The rest of the friction tau_f (reference/robots/friction.py).
    periodic : (n,) bool array or None
        Joint i is 2 pi-periodic (revolute); None: not declared.

    Methods
    -------
    M(q) -> (n, n)
        Mass matrix, kg m^2.
    C(q, v) -> (n, n)
        Christoffel Coriolis matrix (Mdot = C + C^T, C(q, a) b = C(q, b) a).
    g(q) -> (n,)
        Gravity torque.
    dMw_dq(q, w), dCab_dq(q, a, b) -> (n, n)
        d(M(q) w)/dq and d(C(q, a) b)/dq for fixed w, a, b (closed forms, or pinocchio's
        analytical derivatives), for the I&I references.
    """

    name: str
    n: int
    F: np.ndarray
    periodic = None      # (n,) bools: joint i 2 pi-periodic (revolute); None: not declared

    def nle(self, q, v):
        """Non-linear effects C(q, v) v + g(q) (n,), N m; q (n,) rad, v (n,) rad/s."""
        return self.C(q, v) @ v + self.g(q)

    def forward_dynamics(self, q, v, tau):
        """qdd = M(q)^{-1} (tau - C(q, v) v - tau_f(v) - g(q))  [S000 (1)] (a solve, not an inverse),
        tau_f the friction (``friction_torque``).

        Parameters
        ----------
        q : (n,) array
            rad.
        v : (n,) array
            rad/s.
        tau : (n,) array
            N m.

        Returns
        -------
        (n,) array
            rad/s^2.
        """
        q, v, tau = (np.asarray(a, dtype=float) for a in (q, v, tau))
        return np.linalg.solve(self.M(q), tau - self.nle(q, v) - self.friction_torque(v))


class Planar2R(ReferenceRobot):
    """Planar 2R arm in a vertical plane (docs/papers/experiments.md §11.1): q1 absolute from the horizontal
    x axis, q2 relative, gravity g0 along -y.

        M = [[a1 + 2 a2 c2, a3 + a2 c2], [a3 + a2 c2, a3]]
        a1 = I1 + m1 lc1^2 + I2 + m2 (l1^2 + lc2^2),  a2 = m2 l1 lc2,  a3 = I2 + m2 lc2^2
        C  = -a2 s2 [[q2', q1' + q2'], [-q1', 0]]
        g  = [(m1 lc1 + m2 l1) g0 c1 + m2 lc2 g0 c12;  m2 lc2 g0 c12]

    Parameters
    ----------
    params : dict
        m1, m2 (kg), l1, l2, lc1, lc2 (m), I1, I2 (kg m^2), g0 (m/s^2), F (2 or 2 x 2, optional).
    name : str
    """

    n = 2
    dim = 2

    def __init__(self, params, name="planar_2r"):
        p = {k: float(params[k]) for k in ("m1", "m2", "l1", "l2", "lc1", "lc2", "I1", "I2", "g0")}
        self.name = name
        self.params = p
        F = np.asarray(params.get("F", [0.0, 0.0]), dtype=float)
        self.F = np.diag(F) if F.ndim == 1 else F.reshape(2, 2)
        self.masses = np.array([p["m1"], p["m2"]])
        self.periodic = np.ones(2, dtype=bool)             # revolute joints
        self.inertias = np.array([p["I1"], p["I2"]])
        self.a1 = p["I1"] + p["m1"] * p["lc1"] ** 2 + p["I2"] + p["m2"] * (p["l1"] ** 2 + p["lc2"] ** 2)
        self.a2 = p["m2"] * p["l1"] * p["lc2"]
        self.a3 = p["I2"] + p["m2"] * p["lc2"] ** 2

    def M(self, q):
        """M(q) (2, 2) of the class docstring."""
        c2 = np.cos(q[1])
        m12 = self.a3 + self.a2 * c2
        return np.array([[self.a1 + 2 * self.a2 * c2, m12], [m12, self.a3]])   # docs/papers/experiments.md §11.1

    def C(self, q, v):
        """C(q, v) (2, 2) of the class docstring."""
        h = -self.a2 * np.sin(q[1])
        return h * np.array([[v[1], v[0] + v[1]], [-v[0], 0.0]])             # docs/papers/experiments.md §11.1

    def dMw_dq(self, q, w):
        """d(M(q) w)/dq (n x n, column j = dM/dq_j w) for a fixed w (closed form)."""
        s2 = np.sin(q[1])
        return np.array([[0.0, -self.a2 * s2 * (2 * w[0] + w[1])], [0.0, -self.a2 * s2 * w[0]]])

    def dCab_dq(self, q, a, b):
        """d(C(q, a) b)/dq (n x n) for fixed a, b (closed form)."""
        dh = -self.a2 * np.cos(q[1])
        return np.array([[0.0, dh * (a[1] * b[0] + (a[0] + a[1]) * b[1])], [0.0, -dh * a[0] * b[0]]])

    def g(self, q):
        """g(q) (2,) of the class docstring."""
        p = self.params
        g12 = p["m2"] * p["lc2"] * p["g0"] * np.cos(q[0] + q[1])
        return np.array([(p["m1"] * p["lc1"] + p["m2"] * p["l1"]) * p["g0"] * np.cos(q[0]) + g12, g12])

    def com_positions(self, q):
        """p = [lc1 c1, lc1 s1, l1 c1 + lc2 c12, l1 s1 + lc2 s12]  [S002 (34)], docs/papers/seed002.md §3.1: (4,), m,
        at joint positions ``q`` (2,), rad."""
        p = self.params
        c1, s1, c12, s12 = np.cos(q[0]), np.sin(q[0]), np.cos(q[0] + q[1]), np.sin(q[0] + q[1])
        return np.array([p["lc1"] * c1, p["lc1"] * s1,
                         p["l1"] * c1 + p["lc2"] * c12, p["l1"] * s1 + p["lc2"] * s12])

    def com_jacobian(self, q):
        """J_p = d p / d q  (4 x 2)  [S002 (34)]."""
        p = self.params
        c1, s1, c12, s12 = np.cos(q[0]), np.sin(q[0]), np.cos(q[0] + q[1]), np.sin(q[0] + q[1])
        return np.array([[-p["lc1"] * s1, 0.0],
                         [p["lc1"] * c1, 0.0],
                         [-p["l1"] * s1 - p["lc2"] * s12, -p["lc2"] * s12],
                         [p["l1"] * c1 + p["lc2"] * c12, p["lc2"] * c12]])

    @property
    def gravity_vector(self):
        """g_o = [0, -g0] (vertical plane, docs/papers/experiments.md §11.1)."""
        return np.array([0.0, -self.params["g0"]])

    def com_bias(self, q, v):
        """Jdot_p(q, v) v: CoM accelerations at zero joint acceleration (4,), closed form
        p_1'' = -lc1 v1^2 [c1, s1],  p_2'' = -l1 v1^2 [c1, s1] - lc2 (v1 + v2)^2 [c12, s12]."""
        p = self.params
        c1, s1, c12, s12 = np.cos(q[0]), np.sin(q[0]), np.cos(q[0] + q[1]), np.sin(q[0] + q[1])
        w1, w12 = v[0] ** 2, (v[0] + v[1]) ** 2
        return np.array([-p["lc1"] * w1 * c1, -p["lc1"] * w1 * s1,
                         -p["l1"] * w1 * c1 - p["lc2"] * w12 * c12,
                         -p["l1"] * w1 * s1 - p["lc2"] * w12 * s12])


class Absolute2R(ReferenceRobot):
    """Two-DoF arm in absolute angles (docs/papers/seed003.md §4.2, seed 003), phi = y1 - y2:

        M = [[c1, c3 cos phi], [c3 cos phi, c2]]
        C = [[0, c3 sin phi x2], [-c3 sin phi x1, 0]]     (Christoffel, A3-1)
        G = gravity_scale [c4 cos y1; c5 cos y2]            (A3-2),   F = 0

    Parameters
    ----------
    params : dict
        c1, c2, c3 (kg m^2), c4, c5 (N m), gravity_scale (optional, default 1).
    name : str
    """

    n = 2

    def __init__(self, params, name="absolute_2r"):
        self.name = name
        self.c = [float(params[k]) for k in ("c1", "c2", "c3", "c4", "c5")]
        self.gravity_scale = float(params.get("gravity_scale", 1.0))
        self.F = np.zeros((2, 2))
        self.periodic = np.ones(2, dtype=bool)             # absolute angles

    def M(self, q):
        """M(q) (2, 2)  [S003 (56a)]."""
        c1, c2, c3 = self.c[:3]
        m12 = c3 * np.cos(q[0] - q[1])
        return np.array([[c1, m12], [m12, c2]])                             # [S003 (56a)]

    def C(self, q, v):
        """C(q, v) (2, 2): the Christoffel matrix, not the printed (56b) [docs/papers/ambiguities.md A3-1]."""
        s = self.c[2] * np.sin(q[0] - q[1])
        return np.array([[0.0, s * v[1]], [-s * v[0], 0.0]])

    def dMw_dq(self, q, w):
        """d(M(q) w)/dq (n x n, column j = dM/dq_j w) for a fixed w; dM/dy2 = -dM/dy1."""
        d1 = -self.c[2] * np.sin(q[0] - q[1]) * np.array([w[1], w[0]])
        return np.column_stack([d1, -d1])

    def dCab_dq(self, q, a, b):
        """d(C(q, a) b)/dq (n x n) for fixed a, b; C(q, a) b = c3 sin(phi) [a2 b2; -a1 b1]."""
        d1 = self.c[2] * np.cos(q[0] - q[1]) * np.array([a[1] * b[1], -a[0] * b[0]])
        return np.column_stack([d1, -d1])

    def g(self, q):
        """G(q) (2,) (A3-2)."""
        return self.gravity_scale * np.array([self.c[3] * np.cos(q[0]), self.c[4] * np.cos(q[1])])
