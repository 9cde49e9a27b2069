"""The seed robots given by formulas (docs/papers/experiments.md §11.1, §11.2, docs/papers/seed003.md §4.2).

Catalog names:
  ``seed000_2r``      planar 2R of seed 000, Table I (thin rods, F = diag(0.1, 0.3))   [S000 Table I]
  ``seed002_2r``      planar 2R of seed 002, §V (F = 0)                                  [S002 §V]
  ``seed003_2r_abs``  two-link arm of seed 003 in absolute angles (Table II constants)   [S003 (56), Table II]
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from models.robot import ModelError, RobotModel


class Planar2R(RobotModel):
    """Planar 2R in a vertical plane: q1 absolute from the horizontal x axis, q2 relative,
    gravity g0 along -y (docs/papers/experiments.md §11.1, A0-1 [ASSUMPTION] Siciliano convention).

        M = [[a1 + 2 a2 cos q2, a3 + a2 cos q2], [a3 + a2 cos q2, a3]]
        a1 = I1 + m1 lc1^2 + I2 + m2 (l1^2 + lc2^2),  a2 = m2 l1 lc2,  a3 = I2 + m2 lc2^2
        g  = [(m1 lc1 + m2 l1) g0 cos q1 + m2 lc2 g0 cos(q1+q2);  m2 lc2 g0 cos(q1+q2)]
    """

    def __init__(self, name, m1, m2, l1, l2, lc1, lc2, I1, I2, g0=9.81, F=(0.0, 0.0)):
        p = dict(m1=m1, m2=m2, l1=l1, l2=l2, lc1=lc1, lc2=lc2, I1=I1, I2=I2, g0=g0)
        if min(m1, m2, I1, I2) <= 0:
            raise ModelError(f"robot {name!r}: masses and inertias must be positive, got {p}")
        self.p = p
        self.name, self.n, self.dim = name, 2, 2
        self.F = np.diag(np.asarray(F, dtype=float))
        self.masses = np.array([m1, m2], dtype=float)
        self.q_lower, self.q_upper = np.full(2, -np.pi), np.full(2, np.pi)
        self.v_limit = np.full(2, np.inf)
        self.joint_names = ["q1", "q2"]
        self._periodic = np.ones(2, dtype=bool)          # revolute joints: 2 pi-periodic
        self.source = {"kind": "closed_form", "name": name, "model": "planar_2r",
                       "params": {**{k: float(v) for k, v in p.items()},
                                  "F": [float(f) for f in np.diag(self.F)]}}

    def _a(self):
        p = self.p
        a1 = p["I1"] + p["m1"] * p["lc1"] ** 2 + p["I2"] + p["m2"] * (p["l1"] ** 2 + p["lc2"] ** 2)
        return a1, p["m2"] * p["l1"] * p["lc2"], p["I2"] + p["m2"] * p["lc2"] ** 2

    def mass_matrix(self, q):
        """M(q) = [[a1 + 2 a2 cos q2, a3 + a2 cos q2], [a3 + a2 cos q2, a3]]  (docs/papers/experiments.md §11.1).

        ``q`` is the (2, 1) SX joint angle (rad); returns the (2, 2) SX inertia matrix (kg m^2)."""
        a1, a2, a3 = self._a()
        c2 = ca.cos(q[1])
        return ca.blockcat([[a1 + 2 * a2 * c2, a3 + a2 * c2], [a3 + a2 * c2, a3]])

    def coriolis(self, q, v):
        """C = -a2 sin q2 [[q2', q1' + q2'], [-q1', 0]]  (docs/papers/experiments.md §11.1).

        ``q`` (rad) and ``v`` (rad/s) are (2, 1) SX; returns the (2, 2) SX Christoffel matrix."""
        h = -self._a()[1] * ca.sin(q[1])
        return ca.blockcat([[h * v[1], h * (v[0] + v[1])], [-h * v[0], 0]])

    def gravity(self, q):
        """g(q) = [(m1 lc1 + m2 l1) g0 cos q1 + m2 lc2 g0 cos(q1+q2);  m2 lc2 g0 cos(q1+q2)]
        (docs/papers/experiments.md §11.1).

        ``q`` is the (2, 1) SX joint angle (rad); returns the (2, 1) SX gravity torque (N m)."""
        p = self.p
        c12 = ca.cos(q[0] + q[1])
        return ca.vertcat((p["m1"] * p["lc1"] + p["m2"] * p["l1"]) * p["g0"] * ca.cos(q[0])
                          + p["m2"] * p["lc2"] * p["g0"] * c12,
                          p["m2"] * p["lc2"] * p["g0"] * c12)

    def com_positions(self, q):
        """p = [lc1 c1, lc1 s1, l1 c1 + lc2 c12, l1 s1 + lc2 s12]  [S002 §V, docs/papers/seed002.md §3.1].

        ``q`` is the (2, 1) SX joint angle (rad); returns the (4, 1) SX of planar CoM
        positions (m)."""
        p = self.p
        c1, s1 = ca.cos(q[0]), ca.sin(q[0])
        c12, s12 = ca.cos(q[0] + q[1]), ca.sin(q[0] + q[1])
        return ca.vertcat(p["lc1"] * c1, p["lc1"] * s1,
                          p["l1"] * c1 + p["lc2"] * c12, p["l1"] * s1 + p["lc2"] * s12)


class Absolute2R(RobotModel):
    """Two-link arm in absolute angles (seed 003, docs/papers/seed003.md §4.2), phi = y1 - y2:

        M = [[c1, c3 cos phi], [c3 cos phi, c2]],   G = s [c4 cos y1; c5 cos y2]

    with s = ``gravity_scale`` (1: g absorbed in c4, c5; A3-2 [ASSUMPTION]). C is the
    Christoffel matrix [[0, c3 sin phi x2], [-c3 sin phi x1, 0]] (A3-1, not (56b) as printed).
    The seed gives no link lengths, so CoM positions are not available.
    """

    def __init__(self, name, c1, c2, c3, c4, c5, gravity_scale=1.0):
        self.p = dict(c1=c1, c2=c2, c3=c3, c4=c4, c5=c5, gravity_scale=gravity_scale)
        if c1 * c2 - c3 ** 2 <= 0 or c1 <= 0:
            raise ModelError(f"robot {name!r}: M is not positive definite (c1 c2 <= c3^2)")
        self.name, self.n, self.dim = name, 2, 2
        self.F = np.zeros((2, 2))
        self.masses = np.full(2, np.nan)
        self.q_lower, self.q_upper = np.full(2, -np.pi), np.full(2, np.pi)
        self.v_limit = np.full(2, np.inf)
        self.joint_names = ["y1", "y2"]
        self._periodic = np.ones(2, dtype=bool)          # absolute angles: 2 pi-periodic
        self.source = {"kind": "closed_form", "name": name, "model": "absolute_2r",
                       "params": {k: float(v) for k, v in self.p.items()}}

    def mass_matrix(self, q):
        """M(y) = [[c1, c3 cos phi], [c3 cos phi, c2]], phi = y1 - y2  [S003 (56)].

        ``q`` is the (2, 1) SX of absolute angles (rad); returns a (2, 2) SX."""
        p = self.p
        c = ca.cos(q[0] - q[1])
        return ca.blockcat([[p["c1"], p["c3"] * c], [p["c3"] * c, p["c2"]]])

    def coriolis(self, q, v):
        """Christoffel C = [[0, c3 sin phi x2], [-c3 sin phi x1, 0]], phi = y1 - y2
        (A3-1, not (56b) as printed).

        ``q`` (absolute angles, rad) and ``v`` (rad/s) are (2, 1) SX; returns a (2, 2) SX."""
        s = self.p["c3"] * ca.sin(q[0] - q[1])
        return ca.blockcat([[0, s * v[1]], [-s * v[0], 0]])

    def gravity(self, q):
        """G(y) = s [c4 cos y1; c5 cos y2], s = ``gravity_scale``  [S003 (56c), A3-2].

        ``q`` is the (2, 1) SX of absolute angles (rad); returns a (2, 1) SX."""
        p = self.p
        return p["gravity_scale"] * ca.vertcat(p["c4"] * ca.cos(q[0]), p["c5"] * ca.cos(q[1]))

    def com_positions(self, q):
        """Not available: the seed gives no link lengths, so any ``q`` raises ModelError."""
        raise ModelError(f"robot {self.name!r}: the seed gives no link lengths, so no CoM positions")


def seed000_2r(mass_scale=1.0):
    """[S000 Table I]: m = (10, 20) kg, L = (1, 1.5) m, thin rods (d = L/2, I = m L^2/12),
    F = diag(0.1, 0.3). ``mass_scale`` scales masses and rod inertias (Example 1b, docs/papers/experiments.md §11.1)."""
    m1, m2, l1, l2 = 10.0 * mass_scale, 20.0 * mass_scale, 1.0, 1.5
    name = "seed000_2r" if mass_scale == 1.0 else f"seed000_2r_m{mass_scale:g}"
    return Planar2R(name, m1, m2, l1, l2, l1 / 2, l2 / 2, m1 * l1 ** 2 / 12, m2 * l2 ** 2 / 12,
                    g0=9.81, F=(0.1, 0.3))


def seed002_2r():
    """[S002 §V]: m = (2, 1) kg, l = (0.4, 0.2) m, lc = (0.2, 0.1) m; inertias m l^2/12
    [ASSUMPTION, docs/papers/experiments.md §11.2]; no friction."""
    return Planar2R("seed002_2r", 2.0, 1.0, 0.4, 0.2, 0.2, 0.1, 2.0 * 0.4 ** 2 / 12,
                    1.0 * 0.2 ** 2 / 12, g0=9.81, F=(0.0, 0.0))


def seed003_2r_abs(gravity_scale=1.0):
    """[S003 Table II]: c1..c5 = 0.9698, 0.1575, 0.264, 1.74, 0.44.

    ``gravity_scale`` multiplies G (1: g absorbed in c4, c5; 9.81: the printed (56c), A3-2)."""
    return Absolute2R("seed003_2r_abs", 0.9698, 0.1575, 0.264, 1.74, 0.44, gravity_scale)
