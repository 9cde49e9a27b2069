"""Reference URDF robots through pinocchio's own algorithms (crba, nle, aba, Coriolis).

The same interface as reference/rigid.py (docs/papers/seed000.md §0, [S000 (1)]); pinocchio, not our symbolic
spatial algebra, so a cross-check of the generated C against it compares two implementations.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from .rigid import ReferenceRobot


def file_sha256(path):
    """sha256 (hex str) of the raw bytes of the file at ``path`` (str or Path)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def snap(a, tol):
    """Round-off cleanup of an array: |x| < tol -> 0 and |1 - |x|| < tol -> sign(x).

    Parameters
    ----------
    a : array_like
    tol : float

    Returns
    -------
    ndarray
        A copy, the shape of ``a``.
    """
    a = np.array(a, dtype=float, copy=True)
    a[np.abs(a) < tol] = 0.0
    near_one = np.abs(1.0 - np.abs(a)) < tol
    a[near_one] = np.sign(a[near_one])
    return a


class UrdfRobot(ReferenceRobot):
    """A URDF robot through pinocchio's own algorithms (crba, nle, aba, Coriolis).

    Our coordinates: one per degree of freedom (angle for revolute and continuous
    joints, position for prismatic ones). Continuous joints are (cos, sin) in
    pinocchio (nq = 2), converted by :meth:`pin_q`.

    Parameters
    ----------
    path : str or Path
        The URDF file.
    sha256 : str or None
        Expected sha256 of the file (ValueError if it changed).
    locked_joints : dict
        Joint name -> value (rad or m) of joints fixed in a reduced model.
    snap_tol : float
        Round-off snapped in joint placements and inertias (``snap``); 0: none.
    """

    def __init__(self, path, sha256=None, locked_joints=None, snap_tol=1e-9):
        import pinocchio as pin

        self._pin = pin
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"URDF file not found: {path}")
        digest = file_sha256(path)
        if sha256 is not None and digest != sha256:
            raise ValueError(f"URDF {path} has sha256 {digest}, the robot source expects {sha256}: "
                             "the file changed since the model was built")
        self.path = str(path)
        self.name = path.stem
        full = pin.buildModelFromUrdf(self.path)
        locked_joints = dict(locked_joints or {})
        if locked_joints:
            ids = []
            for jname in locked_joints:
                if not full.existJointName(jname):
                    raise ValueError(f"locked joint {jname!r} not in {path.name}; joints: {list(full.names)[1:]}")
                ids.append(full.getJointId(jname))
            q_ref = pin.neutral(full)
            for jname, value in locked_joints.items():
                self._set_coordinate(full.joints[full.getJointId(jname)], q_ref, float(value))
            model = pin.buildReducedModel(self._unique_frames(full), sorted(ids), q_ref)
        else:
            model = full
        self.model = self._snapped(model, float(snap_tol or 0.0))
        self.data = self.model.createData()
        self.n = self.model.nv
        self.joint_names = list(self.model.names)[1:]
        for j in self.model.joints[1:]:
            if j.nv != 1 or j.nq not in (1, 2):
                raise ValueError(f"joint {j.shortname()} (nq={j.nq}, nv={j.nv}) is not supported: "
                                 "only 1-DoF revolute, continuous and prismatic joints")
        self.F = np.diag(np.asarray(self.model.damping, dtype=float))     # <dynamics damping>
        self.coulomb = np.asarray(self.model.friction, dtype=float).copy()  # <dynamics friction>
        # revolute (JointModelR*, RevoluteUnaligned, RevoluteUnbounded*: continuous) joints are
        # 2 pi-periodic; prismatic ones (JointModelP*, PrismaticUnaligned) are not
        self.periodic = np.array([j.shortname().startswith(("JointModelR", "JointModelRevolute"))
                                  for j in self.model.joints[1:]])

    def _unique_frames(self, model):
        """A copy of ``model`` whose link and fixed-joint frames are named by index: reducing
        must go by joint, and pinocchio looks frames up by name (a link named like a joint,
        "gripper", fails with "Several frames match"). This reference reads no frame."""
        model = model.copy()
        for i, f in enumerate(model.frames):
            if i > 0 and f.type != self._pin.FrameType.JOINT:
                f.name = f"frame {i}"
                model.frames[i] = f
        return model

    @staticmethod
    def _set_coordinate(joint, q_pin, value):
        if joint.nq == 2:
            q_pin[joint.idx_q:joint.idx_q + 2] = [np.cos(value), np.sin(value)]
        else:
            q_pin[joint.idx_q] = value

    def _snapped(self, model, tol):
        """Copy of ``model`` with round-off snapped in joint placements and inertias
        (lever and rotational inertia; the mass is kept)."""
        pin = self._pin
        model = model.copy()
        if tol <= 0.0:
            return model
        for i in range(1, model.njoints):
            M = model.jointPlacements[i]
            model.jointPlacements[i] = pin.SE3(snap(M.rotation, tol), snap(M.translation, tol))
            Y = model.inertias[i]
            model.inertias[i] = pin.Inertia(Y.mass, snap(Y.lever, tol), snap(Y.inertia, tol))
        return model

    def pin_q(self, q):
        """Our coordinates ``q`` (n,) -> pinocchio configuration (nq,) (cos, sin for continuous
        joints)."""
        q = np.asarray(q, dtype=float).reshape(-1)
        q_pin = np.zeros(self.model.nq)
        for j in self.model.joints[1:]:
            self._set_coordinate(j, q_pin, q[j.idx_v])
        return q_pin

    def M(self, q):
        """M(q) (n, n), kg m^2, by pinocchio's crba (symmetrised)."""
        M = self._pin.crba(self.model, self.data, self.pin_q(q))
        return np.triu(M) + np.triu(M, 1).T

    def C(self, q, v):
        """Christoffel C(q, v) (n, n) by pinocchio's computeCoriolisMatrix."""
        return np.array(self._pin.computeCoriolisMatrix(self.model, self.data, self.pin_q(q),
                                                        np.asarray(v, dtype=float)))

    def g(self, q):
        """g(q) (n,), N m, by pinocchio's computeGeneralizedGravity."""
        return np.array(self._pin.computeGeneralizedGravity(self.model, self.data, self.pin_q(q)))

    def nle(self, q, v):
        """C(q, v) v + g(q) (n,), N m, by pinocchio's nonLinearEffects."""
        return np.array(self._pin.nonLinearEffects(self.model, self.data, self.pin_q(q),
                                                   np.asarray(v, dtype=float)))

    def _drnea_dq(self, q, v, a):
        """d rnea(q, v, a)/dq by pinocchio's analytical derivatives (tangent coordinates)."""
        return np.array(self._pin.computeRNEADerivatives(
            self.model, self.data, self.pin_q(q), np.asarray(v, dtype=float),
            np.asarray(a, dtype=float))[0])

    def dMw_dq(self, q, w):
        """d(M(q) w)/dq (n x n) for fixed w: d rnea(q, 0, w)/dq - d rnea(q, 0, 0)/dq (exact)."""
        z = np.zeros(self.n)
        return self._drnea_dq(q, z, w) - self._drnea_dq(q, z, z)

    def dCab_dq(self, q, a, b):
        """d(C(q, a) b)/dq (n x n) for fixed a, b, C the Christoffel matrix: by polarisation of
        the symmetric form C(q, a) b = [c(a + b) - c(a - b)]/4 with c(v) = C(q, v) v, whose
        q-derivative is d rnea(q, v, 0)/dq minus gravity's (cancels in the difference)."""
        a, b, z = np.asarray(a, float), np.asarray(b, float), np.zeros(self.n)
        return 0.25 * (self._drnea_dq(q, a + b, z) - self._drnea_dq(q, a - b, z))

    def forward_dynamics(self, q, v, tau):
        """qdd = aba(q, v, tau - tau_f(v))  [S000 (1)] (n,), rad/s^2, tau_f the friction
        (``friction_torque``); q, v, tau as ReferenceRobot's."""
        v = np.asarray(v, dtype=float)
        tau = np.asarray(tau, dtype=float)
        return np.array(self._pin.aba(self.model, self.data, self.pin_q(q), v,
                                      tau - self.friction_torque(v)))

    # ------------------------------------------------------------ link CoM kinematics (seed 002)
    dim = 3

    @property
    def masses(self):
        """(n,) mass of the body moved by each joint."""
        return np.array([self.model.inertias[i].mass for i in range(1, self.model.njoints)])

    @property
    def gravity_vector(self):
        """g_o (3,), pinocchio's model gravity."""
        return np.array(self.model.gravity.linear, dtype=float)

    def com_positions(self, q):
        """World CoM of each body moved by a joint, stacked (3n,), m, at joint positions ``q`` (n,):
        oMi[i] * lever_i (per link, not pin.centerOfMass, which is per subtree)."""
        pin = self._pin
        pin.forwardKinematics(self.model, self.data, self.pin_q(q))
        return np.concatenate([self.data.oMi[i].act(self.model.inertias[i].lever)
                               for i in range(1, self.model.njoints)])

    def com_jacobian(self, q):
        """J_p (3n, n) at joint positions ``q`` (n,): J_c^i = J_lin^i - [r_i]x J_ang^i with the
        joint Jacobians in LOCAL_WORLD_ALIGNED (linear part = velocity of the joint origin) and
        r_i = oR_i lever_i."""
        pin = self._pin
        qp = self.pin_q(q)
        pin.computeJointJacobians(self.model, self.data, qp)
        rows = []
        for i in range(1, self.model.njoints):
            J = pin.getJointJacobian(self.model, self.data, i, pin.LOCAL_WORLD_ALIGNED)
            r = self.data.oMi[i].rotation @ self.model.inertias[i].lever
            rows.append(J[:3] - np.cross(r[:, None], J[3:], axis=0))   # v + w x r = v - r x w
        return np.vstack(rows)

    def com_bias(self, q, v):
        """Jdot_p(q, v) v (3n,): classical CoM accelerations at zero joint acceleration,
        a_c = a_o + alpha x r + w x (w x r) with the classical acceleration a_o of the joint
        origin, alpha and w the body's angular acceleration and velocity (world axes)."""
        pin = self._pin
        v = np.asarray(v, dtype=float)
        pin.forwardKinematics(self.model, self.data, self.pin_q(q), v, np.zeros(self.n))
        out = []
        for i in range(1, self.model.njoints):
            a_o = pin.getClassicalAcceleration(self.model, self.data, i, pin.LOCAL_WORLD_ALIGNED).linear
            al = pin.getAcceleration(self.model, self.data, i, pin.LOCAL_WORLD_ALIGNED).angular
            w = pin.getVelocity(self.model, self.data, i, pin.LOCAL_WORLD_ALIGNED).angular
            r = self.data.oMi[i].rotation @ self.model.inertias[i].lever
            out.append(a_o + np.cross(al, r) + np.cross(w, np.cross(w, r)))
        return np.concatenate(out)
