"""An independent plant: the same URDF simulated by MuJoCo (PyPI ``mujoco``), not by our model.

Import. The URDF of ``robot.source`` is copied with its visuals, collisions, transmissions and
gazebo tags removed (MuJoCo cannot read .dae meshes and we need no geometry), locked joints
turned into fixed joints at their value (the joint's origin times its motion there: a rotation
about the axis, or a translation along it), and a
``<mujoco><compiler inertiafromgeom="false" .../></mujoco>`` element added, so MuJoCo keeps
the URDF's inertials, joints, limits and damping and fuses fixed links like pinocchio does.
Contacts are disabled (there are no geoms). ``MujocoPlant.mass_matrix`` and ``bias`` (mj_fullM,
qfrc_bias) equal pinocchio's crba and nle to round-off (tests/test_mujoco.py).

Integration. MuJoCo's own fixed-step RK4 (``mjINT_RK4``) with ``timestep`` (1e-4 s) sub-steps;
the torque of sample k is applied as ``qfrc_applied`` over [t_k, t_k+1] (zero-order hold).
``track_at`` runs the same loop at arbitrary (jittered) instants: each interval h is integrated
exactly by floor(h / timestep) full steps and one shortened step of the remainder (``advance``).

Closed loop. Computed-torque tracking of q_d(t) with MuJoCo's own inverse dynamics
(``mj_inverse``, which includes its joint damping) on the true state at each sample:

    tau_k = ID_mujoco(q_k, qd_k, qdd_d + KD (qd_d - qd_k) + KP (q_d - q_k))

so the loop never evaluates our model. Model mismatch: every body's ``body_mass`` and
``body_inertia`` of the plant are multiplied by (1 + mismatch); the observers keep the nominal
model (a uniform scaling: M, C, g of the plant are (1 + mismatch) times the nominal ones).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ...logs.recording import Recording

KP, KD = 400.0, 40.0          # computed-torque gains: critically damped, 20 rad/s
TIMESTEP = 1e-4               # MuJoCo step (s)


def _mujoco():
    try:
        import mujoco
    except ImportError:  # pragma: no cover
        raise ImportError("the MuJoCo plant needs the optional package mujoco: "
                          "pip install 'observer-codegen[mujoco]'", name="mujoco") from None
    return mujoco


def mujoco_urdf(path, locked_joints=None):
    """The URDF text MuJoCo loads (see the module docstring): no geometry, locked joints fixed.

    Parameters
    ----------
    path : path-like
        URDF file.
    locked_joints : dict, optional
        Joint name -> value (rad or m): the joint becomes a fixed joint whose origin is the
        joint's origin followed by its motion at that value (``_locked_origin``).

    Returns
    -------
    str
    """
    root = ET.parse(Path(path)).getroot()
    locked = {k: float(v) for k, v in (locked_joints or {}).items()}
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for e in link.findall(tag):
                link.remove(e)
    for tag in ("transmission", "gazebo", "mujoco"):
        for e in root.findall(tag):
            root.remove(e)
    joints = {j.get("name"): j for j in root.iter("joint")}
    for name in locked:
        if name not in joints:
            raise ValueError(f"locked_joints: {name!r} is not a joint of {path}")
        j = joints[name]
        _locked_origin(j, locked[name])
        j.set("type", "fixed")
        for tag in ("limit", "axis", "dynamics", "mimic", "safety_controller", "calibration"):
            for e in j.findall(tag):
                j.remove(e)
    compiler = ET.SubElement(ET.SubElement(root, "mujoco"), "compiler")
    compiler.attrib.update(discardvisual="true", fusestatic="true", inertiafromgeom="false",
                           balanceinertia="false", angle="radian")
    return ET.tostring(root, encoding="unicode")


def _locked_origin(joint, value):
    """Set the <origin> of the URDF ``joint`` element to T_origin T_motion(value): a rotation by
    ``value`` rad about its axis (revolute, continuous) or a translation by ``value`` m along it
    (prismatic); the child's pose with the joint held there."""
    from scipy.spatial.transform import Rotation
    if value == 0.0:
        return
    kind = joint.get("type")
    if kind not in ("revolute", "continuous", "prismatic"):
        raise ValueError(f"locked_joints: {joint.get('name')!r} is a {kind} joint; only revolute, "
                         "continuous and prismatic joints are locked")
    origin = joint.find("origin")
    if origin is None:
        origin = ET.SubElement(joint, "origin")
    xyz = np.array([float(v) for v in (origin.get("xyz") or "0 0 0").split()])
    R = Rotation.from_euler("xyz", [float(v) for v in (origin.get("rpy") or "0 0 0").split()])
    axis = joint.find("axis")
    a = np.array([float(v) for v in (axis.get("xyz") if axis is not None else "1 0 0").split()])
    a = a / np.linalg.norm(a)
    if kind == "prismatic":
        xyz = xyz + R.apply(a * value)
    else:
        R = R * Rotation.from_rotvec(a * value)
    origin.set("xyz", " ".join(repr(float(v)) for v in xyz))
    origin.set("rpy", " ".join(repr(float(v)) for v in R.as_euler("xyz")))


class MujocoPlant:
    """A robot of our catalog (or any URDF RobotModel) simulated by MuJoCo.

    Parameters
    ----------
    robot : models.RobotModel
        A URDF robot (``robot.source["kind"] == "urdf"``); its joints are matched by name.
    mismatch : float
        Relative error of the plant's masses and inertias (0.1: all 10 % heavier), > -1.
    timestep : float
        MuJoCo's RK4 step (s).
    urdf_text : str, optional
        The URDF text MuJoCo loads instead of ``mujoco_urdf(robot.source["path"], ...)`` (e.g. a
        perturbed copy, codegen.evaluate.sim.real_plant); it must have the robot's joints.
    """

    def __init__(self, robot, mismatch=0.0, timestep=TIMESTEP, urdf_text=None):
        mj = _mujoco()
        src = getattr(robot, "source", {}) or {}
        if src.get("kind") != "urdf":
            raise ValueError(f"robot: the MuJoCo plant needs a URDF robot, got source kind "
                             f"{src.get('kind')!r} for {getattr(robot, 'name', robot)!r}")
        if not (np.isfinite(mismatch) and mismatch > -1):
            raise ValueError(f"mismatch must be a finite number > -1, got {mismatch!r}")
        if not (np.isfinite(timestep) and timestep > 0):
            raise ValueError(f"timestep must be a positive number of seconds, got {timestep!r}")
        self.robot, self.n, self.mismatch = robot, robot.n, float(mismatch)
        if urdf_text is None:
            urdf_text = mujoco_urdf(src["path"], src.get("locked_joints"))
        self.model = mj.MjModel.from_xml_string(urdf_text)
        m = self.model
        m.opt.timestep = float(timestep)
        m.opt.integrator = mj.mjtIntegrator.mjINT_RK4
        m.opt.disableflags |= int(mj.mjtDisableBit.mjDSBL_CONTACT)
        names = [mj.mj_id2name(m, mj.mjtObj.mjOBJ_JOINT, i) for i in range(m.njnt)]
        if sorted(names) != sorted(robot.joint_names) or m.nq != m.nv or m.nv != robot.n:
            raise ValueError(f"robot: MuJoCo's joints {names} do not match the model's "
                             f"{robot.joint_names}")
        self._qi = np.array([m.jnt_qposadr[names.index(j)] for j in robot.joint_names])
        self._vi = np.array([m.jnt_dofadr[names.index(j)] for j in robot.joint_names])
        m.body_mass[1:] *= 1.0 + self.mismatch
        m.body_inertia[1:] *= 1.0 + self.mismatch
        self.data = mj.MjData(m)
        mj.mj_setConst(m, self.data)
        self._mj = mj

    # ------------------------------------------------------------ state and dynamics
    def set_state(self, q, qd):
        """Put the plant at (q, qd) in our joint order."""
        self.data.qpos[self._qi] = q
        self.data.qvel[self._vi] = qd

    def get_state(self):
        """(q, qd) in our joint order (copies)."""
        return self.data.qpos[self._qi].copy(), self.data.qvel[self._vi].copy()

    def mass_matrix(self, q):
        """M(q) (n x n) from MuJoCo (mj_fullM), our joint order."""
        self.set_state(q, np.zeros(self.n))
        self._mj.mj_forward(self.model, self.data)
        M = np.zeros((self.model.nv, self.model.nv))
        self._mj.mj_fullM(self.model, self.data, M)
        return M[np.ix_(self._vi, self._vi)]

    def bias(self, q, qd):
        """C(q, qd) qd + g(q) from MuJoCo (qfrc_bias), our joint order."""
        self.set_state(q, qd)
        self._mj.mj_forward(self.model, self.data)
        return self.data.qfrc_bias[self._vi].copy()

    def inverse_dynamics(self, q, qd, qdd):
        """Torque giving acceleration qdd at (q, qd) (mj_inverse; includes joint damping)."""
        d = self.data
        self.set_state(q, qd)
        d.qacc[self._vi] = qdd
        self._mj.mj_inverse(self.model, d)
        return d.qfrc_inverse[self._vi].copy()

    # ------------------------------------------------------------ closed loop
    def track(self, reference, T, dt=1e-3, kp=KP, kd=KD):
        """Computed-torque tracking of ``reference`` for T seconds, sampled every dt.

        Parameters
        ----------
        reference : callable
            t -> (q_d, qd_d, qdd_d), each (n,); the plant starts at (q_d(0), qd_d(0)).
        T, dt : float
            Length and sample time (s); dt must be a multiple of the MuJoCo timestep.
        kp, kd : float
            Computed-torque gains (1/s^2, 1/s).

        Returns
        -------
        codegen.logs.recording.Recording
            True q (unquantised; see codegen.evaluate.sim.sensors), true qd, applied tau.
        """
        sub = int(round(dt / self.model.opt.timestep))
        if sub < 1 or abs(sub * self.model.opt.timestep - dt) > 1e-12 * dt:
            raise ValueError(f"dt = {dt!r} must be a multiple of the MuJoCo timestep "
                             f"{self.model.opt.timestep:g} s")
        N = int(round(T / dt)) + 1
        t = np.arange(N) * dt
        Q, QD, TAU = np.empty((N, self.n)), np.empty((N, self.n)), np.empty((N, self.n))
        mj, m, d = self._mj, self.model, self.data
        mj.mj_resetData(m, d)
        q_d, qd_d, _ = reference(0.0)
        self.set_state(q_d, qd_d)
        for k in range(N):
            q, qd = self.get_state()
            q_d, qd_d, qdd_d = reference(t[k])
            tau = self.inverse_dynamics(q, qd, qdd_d + kd * (qd_d - qd) + kp * (q_d - q))
            Q[k], QD[k], TAU[k] = q, qd, tau
            if k < N - 1:
                d.qfrc_applied[:] = 0.0
                d.qfrc_applied[self._vi] = tau
                mj.mj_step(m, d, nstep=sub)
        return Recording(t=t, q=Q, tau=TAU, qd=QD, joint_names=list(self.robot.joint_names))

    def advance(self, h, tau=None):
        """Integrate the plant over h seconds with the applied torque held: floor(h / timestep)
        RK4 steps of ``timestep``, then one step of the remainder (none if it is below 1e-9
        timestep), so the state lands exactly at t + h.

        Parameters
        ----------
        h : float
            Interval (s), > 0.
        tau : (n,) array, optional
            Torque to apply (our joint order); default: keep the one applied.
        """
        mj, m, d = self._mj, self.model, self.data
        ts = m.opt.timestep
        if not (np.isfinite(h) and h > 0):
            raise ValueError(f"h must be a positive number of seconds, got {h!r}")
        if tau is not None:
            tau = np.asarray(tau, dtype=float)
            if tau.shape != (self.n,) or not np.all(np.isfinite(tau)):
                raise ValueError(f"tau must be {self.n} finite torques, got shape {tau.shape}")
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[self._vi] = tau
        full = int(np.floor(h / ts + 1e-9))
        rest = h - full * ts
        if full:
            mj.mj_step(m, d, nstep=full)
        if rest > 1e-9 * ts:
            m.opt.timestep = rest
            try:
                mj.mj_step(m, d)
            finally:
                m.opt.timestep = ts

    def track_at(self, reference, t, kp=KP, kd=KD):
        """Computed-torque tracking of ``reference`` with the controller running at the instants
        ``t`` (any increasing times, e.g. jittered): tau_k as in the module docstring from the
        true state at t_k, held over [t_k, t_k+1] and integrated exactly (``advance``).

        Parameters
        ----------
        reference : callable
            t -> (q_d, qd_d, qdd_d), each (n,); the plant starts at (q_d(t_0), qd_d(t_0)).
        t : (N,) array
            Increasing controller instants (s), N >= 2.
        kp, kd : float
            Computed-torque gains (1/s^2, 1/s).

        Returns
        -------
        codegen.logs.recording.Recording
            At the instants t (not uniform in general): true q, true qd, applied tau.
        """
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or len(t) < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ValueError("t must be an increasing 1-D array of at least 2 finite instants (s)")
        N = len(t)
        Q, QD, TAU = np.empty((N, self.n)), np.empty((N, self.n)), np.empty((N, self.n))
        mj, m, d = self._mj, self.model, self.data
        mj.mj_resetData(m, d)
        q_d, qd_d, _ = reference(t[0])
        self.set_state(q_d, qd_d)
        for k in range(N):
            q, qd = self.get_state()
            q_d, qd_d, qdd_d = reference(t[k])
            tau = self.inverse_dynamics(q, qd, qdd_d + kd * (qd_d - qd) + kp * (q_d - q))
            Q[k], QD[k], TAU[k] = q, qd, tau
            if k < N - 1:
                self.advance(t[k + 1] - t[k], tau)
        return Recording(t=t, q=Q, tau=TAU, qd=QD, joint_names=list(self.robot.joint_names))


def sinusoids(robot, f_min=0.15, f_max=0.35, amplitude=0.6, seed=0):
    """q_d,i(t) = c_i + a_i sin(2 pi f_i t + phi_i), f_i evenly spread over [f_min, f_max] Hz,
    c_i the middle of joint i's range, a_i = min(amplitude, 0.4 x range) (rad), random phases
    drawn with ``seed`` (c_i = 0 for a joint without finite limits); n and the ranges from
    ``robot`` (q_lower, q_upper).

    Returns
    -------
    callable
        t -> (q_d, qd_d, qdd_d).
    """
    rng = np.random.default_rng(seed)
    lo, hi = robot.q_lower, robot.q_upper
    c = np.where(np.isfinite(lo + hi), 0.5 * (lo + hi), 0.0)     # a continuous joint: about 0
    a = np.minimum(amplitude, 0.4 * (hi - lo))
    w = 2 * np.pi * np.linspace(f_min, f_max, robot.n)
    phi = rng.uniform(0, 2 * np.pi, robot.n)

    def reference(t):
        s, co = np.sin(w * t + phi), np.cos(w * t + phi)
        return c + a * s, a * w * co, -a * w * w * s
    return reference
