"""Reference robots: numbers only (numpy + pinocchio), rebuilt from ``robot.source``.

Every robot gives the rigid model of SPEC §0

    M(q) qdd + C(q, qd) qd + F qd + g(q) = tau          [S000 (1)]

as plain functions of numpy vectors: ``n``, ``M(q)``, ``C(q, v)`` (Christoffel),
``g(q)``, ``F`` (n x n), ``nle(q, v) = C v + g`` and
``forward_dynamics(q, v, tau) = M^{-1}(tau - C v - F v - g)``.

This file never imports CasADi or the symbolic code (DESIGN §1): it is written
from SPEC's equations so that a cross-check against the generated C proves
something.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

# SPEC §11.1, §11.2, §12.3 numbers, kept here so tests can rebuild the seed robots
# without the symbolic catalog.
_SEED000 = dict(m1=10.0, m2=20.0, l1=1.0, l2=1.5)
_SEED002 = dict(m1=2.0, m2=1.0, l1=0.4, l2=0.2)
SEED_SOURCES = {
    "seed000_2r": {
        "kind": "closed_form", "name": "seed000_2r", "model": "planar_2r",
        "params": dict(_SEED000, lc1=0.5, lc2=0.75,
                       I1=10.0 * 1.0 ** 2 / 12, I2=20.0 * 1.5 ** 2 / 12,
                       g0=9.81, F=[0.1, 0.3]),                           # [S000 Table I]
    },
    "seed002_2r": {
        "kind": "closed_form", "name": "seed002_2r", "model": "planar_2r",
        "params": dict(_SEED002, lc1=0.2, lc2=0.1,
                       I1=2.0 * 0.4 ** 2 / 12, I2=1.0 * 0.2 ** 2 / 12,  # [ASSUMPTION] SPEC §11.2
                       g0=9.81, F=[0.0, 0.0]),                           # [S002 §V]
    },
    "seed003_2r_abs": {
        "kind": "closed_form", "name": "seed003_2r_abs", "model": "absolute_2r",
        "params": dict(c1=0.9698, c2=0.1575, c3=0.264, c4=1.74, c5=0.44,
                       gravity_scale=1.0),                               # [S003 Table II], A3-2
    },
}


def reference_robot(source):
    """Build the reference robot described by a ``robot.source`` dict (see
    :func:`_build_reference_robot`); the dict is kept as ``robot.source`` so that observer
    families can read extra plain data a spec adds to it (e.g. seed 002's non-minimal rows)."""
    if isinstance(source, dict) and source.get("kind") in ("elastic", "dh"):
        from . import elastic  # elastic-joint and DH-table robots (seed 004)
        robot = elastic.ElasticRobot(source) if source["kind"] == "elastic" else elastic.DHRobot(source)
    else:
        robot = _build_reference_robot(source)
    robot.source = dict(source)
    return robot


def _build_reference_robot(source):
    """Build the reference robot described by a ``robot.source`` dict.

    Parameters
    ----------
    source : dict
        ``{"kind": "closed_form", "model": "planar_2r" | "absolute_2r", "params": {...}}``
        or ``{"kind": "urdf", "path": ..., "sha256": ..., "locked_joints": {...},
        "snap_tol": ...}``.
    """
    if not isinstance(source, dict) or "kind" not in source:
        raise ValueError(f"robot source must be a dict with a 'kind' key, got {source!r}")
    kind = source["kind"]
    if kind == "closed_form":
        model = source.get("model")
        if model == "planar_2r":
            return Planar2R(source["params"], name=source.get("name", "planar_2r"))
        if model == "absolute_2r":
            return Absolute2R(source["params"], name=source.get("name", "absolute_2r"))
        raise ValueError(f"unknown closed-form model {model!r} (expected 'planar_2r' or 'absolute_2r')")
    if kind == "urdf":
        return UrdfRobot(source["path"], sha256=source.get("sha256"),
                         locked_joints=source.get("locked_joints") or {},
                         snap_tol=source.get("snap_tol", 1e-9))
    raise ValueError(f"unknown robot source kind {kind!r} (expected 'closed_form' or 'urdf')")


class ReferenceRobot:
    """Common numeric interface; subclasses give ``n``, ``F``, ``M``, ``C``, ``g``."""

    name: str
    n: int
    F: np.ndarray
    periodic = None      # (n,) bools: joint i 2 pi-periodic (revolute); None: not declared

    def nle(self, q, v):
        """Non-linear effects C(q, v) v + g(q)."""
        return self.C(q, v) @ v + self.g(q)

    def forward_dynamics(self, q, v, tau):
        """qdd = M(q)^{-1} (tau - C(q, v) v - F v - g(q))  [S000 (1)] (a solve, not an inverse)."""
        q, v, tau = (np.asarray(a, dtype=float) for a in (q, v, tau))
        return np.linalg.solve(self.M(q), tau - self.nle(q, v) - self.F @ v)


class Planar2R(ReferenceRobot):
    """Planar 2R arm in a vertical plane (SPEC §11.1): q1 absolute from the horizontal
    x axis, q2 relative, gravity g0 along -y.

        M = [[a1 + 2 a2 c2, a3 + a2 c2], [a3 + a2 c2, a3]]
        a1 = I1 + m1 lc1^2 + I2 + m2 (l1^2 + lc2^2),  a2 = m2 l1 lc2,  a3 = I2 + m2 lc2^2
        C  = -a2 s2 [[q2', q1' + q2'], [-q1', 0]]
        g  = [(m1 lc1 + m2 l1) g0 c1 + m2 lc2 g0 c12;  m2 lc2 g0 c12]
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
        c2 = np.cos(q[1])
        m12 = self.a3 + self.a2 * c2
        return np.array([[self.a1 + 2 * self.a2 * c2, m12], [m12, self.a3]])   # SPEC §11.1

    def C(self, q, v):
        h = -self.a2 * np.sin(q[1])
        return h * np.array([[v[1], v[0] + v[1]], [-v[0], 0.0]])             # SPEC §11.1

    def dMw_dq(self, q, w):
        """d(M(q) w)/dq (n x n, column j = dM/dq_j w) for a fixed w (closed form)."""
        s2 = np.sin(q[1])
        return np.array([[0.0, -self.a2 * s2 * (2 * w[0] + w[1])], [0.0, -self.a2 * s2 * w[0]]])

    def dCab_dq(self, q, a, b):
        """d(C(q, a) b)/dq (n x n) for fixed a, b (closed form)."""
        dh = -self.a2 * np.cos(q[1])
        return np.array([[0.0, dh * (a[1] * b[0] + (a[0] + a[1]) * b[1])], [0.0, -dh * a[0] * b[0]]])

    def g(self, q):
        p = self.params
        g12 = p["m2"] * p["lc2"] * p["g0"] * np.cos(q[0] + q[1])
        return np.array([(p["m1"] * p["lc1"] + p["m2"] * p["l1"]) * p["g0"] * np.cos(q[0]) + g12, g12])

    def com_positions(self, q):
        """p = [lc1 c1, lc1 s1, l1 c1 + lc2 c12, l1 s1 + lc2 s12]  [S002 (34)], SPEC §3.1."""
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
        """g_o = [0, -g0] (vertical plane, SPEC §11.1)."""
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
    """Two-DoF arm in absolute angles (SPEC §4.2, seed 003), phi = y1 - y2:

        M = [[c1, c3 cos phi], [c3 cos phi, c2]]
        C = [[0, c3 sin phi x2], [-c3 sin phi x1, 0]]     (Christoffel, A3-1)
        G = gravity_scale [c4 cos y1; c5 cos y2]            (A3-2),   F = 0
    """

    n = 2

    def __init__(self, params, name="absolute_2r"):
        self.name = name
        self.c = [float(params[k]) for k in ("c1", "c2", "c3", "c4", "c5")]
        self.gravity_scale = float(params.get("gravity_scale", 1.0))
        self.F = np.zeros((2, 2))
        self.periodic = np.ones(2, dtype=bool)             # absolute angles

    def M(self, q):
        c1, c2, c3 = self.c[:3]
        m12 = c3 * np.cos(q[0] - q[1])
        return np.array([[c1, m12], [m12, c2]])                             # [S003 (56a)]

    def C(self, q, v):
        # physically correct Christoffel matrix, not the printed (56b) [SPEC A3-1]
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
        return self.gravity_scale * np.array([self.c[3] * np.cos(q[0]), self.c[4] * np.cos(q[1])])


# ---------------------------------------------------------------------------- URDF
def file_sha256(path):
    """sha256 of the raw bytes of a file (hex)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def snap(a, tol):
    """Round-off cleanup: |x| < tol -> 0 and |1 - |x|| < tol -> sign(x)."""
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
        self.F = np.diag(np.asarray(self.model.damping, dtype=float))
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
        """Our coordinates (n,) -> pinocchio configuration (nq,)."""
        q = np.asarray(q, dtype=float).reshape(-1)
        q_pin = np.zeros(self.model.nq)
        for j in self.model.joints[1:]:
            self._set_coordinate(j, q_pin, q[j.idx_v])
        return q_pin

    def M(self, q):
        M = self._pin.crba(self.model, self.data, self.pin_q(q))
        return np.triu(M) + np.triu(M, 1).T

    def C(self, q, v):
        return np.array(self._pin.computeCoriolisMatrix(self.model, self.data, self.pin_q(q),
                                                        np.asarray(v, dtype=float)))

    def g(self, q):
        return np.array(self._pin.computeGeneralizedGravity(self.model, self.data, self.pin_q(q)))

    def nle(self, q, v):
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
        """qdd = aba(q, v, tau - F v)."""
        v = np.asarray(v, dtype=float)
        tau = np.asarray(tau, dtype=float)
        return np.array(self._pin.aba(self.model, self.data, self.pin_q(q), v, tau - self.F @ v))


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
        """World CoM of each body moved by a joint, stacked (3n,):  oMi[i] * lever_i
        (per link, not pin.centerOfMass, which is per subtree)."""
        pin = self._pin
        pin.forwardKinematics(self.model, self.data, self.pin_q(q))
        return np.concatenate([self.data.oMi[i].act(self.model.inertias[i].lever)
                               for i in range(1, self.model.njoints)])

    def com_jacobian(self, q):
        """J_p (3n, n): J_c^i = J_lin^i - [r_i]x J_ang^i with the joint Jacobians in
        LOCAL_WORLD_ALIGNED (linear part = velocity of the joint origin) and r_i = oR_i lever_i."""
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
