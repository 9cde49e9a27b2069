"""Serial robots from a standard Denavit-Hartenberg table (revolute joints), symbolic in CasADi.

Frame i is reached by  A_i(q_i) = Rot_z(theta_i + q_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)
(standard DH, Siciliano et al. §2.8.2); its origin lies on the distal joint axis. Link i carries
mass m_i with CoM rc_i^i and inertia I_i (about the CoM) both in frame i. Then

    M(q) = sum_i  m_i Jv_i^T Jv_i + Jw_i^T R_i I_i R_i^T Jw_i        (Siciliano (7.20))
    g(q) = - sum_i m_i Jv_i^T g0                                     (g0: gravity vector in frame 0)

with Jv_i, Jw_i the CoM Jacobians: column j <= i is  z_{j-1} x (p_ci - o_{j-1})  and  z_{j-1}.
C is the Christoffel matrix of the base class (AD of M). Catalog names (docs/papers/experiments.md §11.3, §11.4):

  ``seed004_2r``  planar 2R under gravity of seed 004, Table 1     [S004 Table 1; CODE-CP config_2R.m]
  ``seed004_3r``  spatial 3R elbow robot of seed 004, Table 2       [S004 Table 2; CODE-CP config_3R.m]
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from models.robot import ModelError, RobotModel


class DHRobot(RobotModel):
    """Revolute serial robot from a standard DH table (module docstring).

    Parameters
    ----------
    dh : (n, 4) rows (alpha, d, a, theta_offset)
    masses : (n,) link masses (kg)
    coms : (n, 3) CoM of link i in frame i (m)
    inertias : (n, 3, 3) link inertia about its CoM, in frame i (kg m^2)
    gravity : (3,) gravity acceleration vector in frame 0 (m/s^2)
    """

    def __init__(self, name, dh, masses, coms, inertias, gravity, F=None, dim=3,
                 q_lower=None, q_upper=None):
        self.dh = np.asarray(dh, dtype=float).reshape(-1, 4)
        n = self.dh.shape[0]
        self.masses = np.asarray(masses, dtype=float).reshape(n)
        self.coms = np.asarray(coms, dtype=float).reshape(n, 3)
        self.inertias = np.asarray(inertias, dtype=float).reshape(n, 3, 3)
        self.gravity_vector = np.asarray(gravity, dtype=float).reshape(3)
        if np.any(self.masses <= 0):
            raise ModelError(f"robot {name!r}: masses must be positive, got {self.masses}")
        for i, I in enumerate(self.inertias):
            if not np.allclose(I, I.T) or np.linalg.eigvalsh(I)[0] < 0:
                raise ModelError(f"robot {name!r}: inertia of link {i + 1} is not symmetric PSD")
        self.name, self.n, self.dim = name, n, dim
        self.F = np.zeros((n, n)) if F is None else np.diag(np.asarray(F, dtype=float))
        self.q_lower = np.full(n, -np.pi) if q_lower is None else np.asarray(q_lower, float)
        self.q_upper = np.full(n, np.pi) if q_upper is None else np.asarray(q_upper, float)
        self.v_limit = np.full(n, np.inf)
        self.joint_names = [f"q{i + 1}" for i in range(n)]
        self.source = {"kind": "dh", "name": name, "dh": self.dh.tolist(),
                       "masses": self.masses.tolist(), "coms": self.coms.tolist(),
                       "inertias": self.inertias.tolist(), "gravity": self.gravity_vector.tolist(),
                       "F": np.diag(self.F).tolist()}

    # ------------------------------------------------------------ kinematics
    def frames(self, q):
        """[(R_i, o_i)] for i = 0..n: rotation (3, 3) and origin (3, 1) of DH frame i in
        frame 0 (SX), at the (n, 1) joint angle ``q`` (rad)."""
        R, o = ca.SX.eye(3), ca.SX.zeros(3, 1)
        out = [(R, o)]
        for i, (alpha, d, a, theta) in enumerate(self.dh):
            th = q[i] + theta
            ct, st = ca.cos(th), ca.sin(th)
            ca_, sa = (float(v) if abs(v) > 1e-15 else 0.0 for v in (np.cos(alpha), np.sin(alpha)))
            Ri = ca.blockcat([[ct, -st * ca_, st * sa], [st, ct * ca_, -ct * sa], [0, sa, ca_]])
            pi = ca.vertcat(a * ct, a * st, d)
            o = o + ca.mtimes(R, pi)
            R = ca.mtimes(R, Ri)
            out.append((R, o))
        return out

    def _com_jacobians(self, q):
        fr = self.frames(q)
        res = []
        for i in range(self.n):
            R, o = fr[i + 1]
            pc = o + ca.mtimes(R, ca.DM(self.coms[i]))
            Jv, Jw = ca.SX.zeros(3, self.n), ca.SX.zeros(3, self.n)
            for j in range(i + 1):
                z, oj = fr[j][0][:, 2], fr[j][1]
                Jv[:, j] = ca.cross(z, pc - oj)
                Jw[:, j] = z
            res.append((pc, Jv, Jw, R))
        return res

    def com_positions(self, q):
        """[p_c1; ...; p_cn] in frame 0 at the (n, 1) SX joint angle ``q`` (rad): (3n, 1) SX (m)."""
        return ca.vertcat(*[pc for pc, *_ in self._com_jacobians(q)])

    # ------------------------------------------------------------ dynamics
    def mass_matrix(self, q):
        """M = sum m Jv^T Jv + Jw^T R I R^T Jw  (Siciliano (7.20)) at the (n, 1) SX ``q`` (rad):
        (n, n) SX."""
        M = ca.SX.zeros(self.n, self.n)
        for i, (_, Jv, Jw, R) in enumerate(self._com_jacobians(q)):
            Iw = ca.mtimes([R, ca.DM(self.inertias[i]), R.T])
            M += self.masses[i] * ca.mtimes(Jv.T, Jv) + ca.mtimes([Jw.T, Iw, Jw])
        return ca.simplify(0.5 * (M + M.T))

    def gravity(self, q):
        """g = -sum m Jv^T g0 = dU/dq with U = -sum m g0^T p_c, at the (n, 1) SX ``q`` (rad):
        (n, 1) SX (N m)."""
        g0 = ca.DM(self.gravity_vector)
        g = ca.SX.zeros(self.n, 1)
        for i, (_, Jv, _, _) in enumerate(self._com_jacobians(q)):
            g -= self.masses[i] * ca.mtimes(Jv.T, g0)
        return g


# ------------------------------------------------------------------- seed-004 robots
def _seed004(name, dh, coms, gravity):
    """Seed-004 link data: m = 4 kg (link 1 + motor 3 lumped, A4-3), I = 0.4 I_3 about the CoM."""
    n = len(dh)
    return DHRobot(name, dh, masses=[4.0] * n, coms=coms,               # [S004 Tables 1-2] A4-3
                   inertias=[0.4 * np.eye(3)] * n, gravity=gravity)


def seed004_2r():
    """Planar 2R of seed 004 (docs/papers/experiments.md §11.3): DH [0, 0, 0.4, q1]; [0, 0, 0.4, q2], g0 = [0, -9.81, 0],
    CoM [-0.3, 0, 0] in frame i (0.1 m from joint i, A4-4)."""
    r = _seed004("seed004_2r", [[0, 0, 0.4, 0], [0, 0, 0.4, 0]],
                 coms=[[-0.3, 0, 0]] * 2, gravity=[0, -9.81, 0])
    r.dim = 2
    return r


def seed004_3r():
    """Spatial 3R elbow of seed 004 (docs/papers/experiments.md §11.4): DH [pi/2, 0.4, 0, q1]; [0, 0, 0.4, q2];
    [0, 0, 0.4, q3], g0 = [0, 0, -9.81], CoMs [0, -0.3, 0], [-0.3, 0, 0], [-0.3, 0, 0]."""
    return _seed004("seed004_3r", [[np.pi / 2, 0.4, 0, 0], [0, 0, 0.4, 0], [0, 0, 0.4, 0]],
                    coms=[[0, -0.3, 0], [-0.3, 0, 0], [-0.3, 0, 0]], gravity=[0, 0, -9.81])
