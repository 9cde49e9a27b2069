"""Contacts on a real-arm plant (codegen.evaluate.sim.real_plant): external forces on chosen links
at known times while the arm's own controller tracks its reference, and the true joint torque
they cause, tau_ext = J_c(q)^T f (J_c the Jacobian of the link's centre of mass, where MuJoCo
applies ``xfrc_applied``).

A contact is (start, end, joint, force): a force (3,) N in the world frame on the child link of
``joint`` (0-based), rising and falling linearly over ``RISE`` seconds. The controller (computed
torque on the true state, ``MujocoPlant.track_at``) does not know it; the log's torque is the
applied one with the plant's sensor noise and offset, as in ``RealPlant.run``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .real_plant import KD, KP, _rng

RISE = 0.005             # s


@dataclass
class Contact:
    """A force ``force`` (3,) N on the child link of joint ``joint`` (0-based) over [start, end] s."""

    start: float
    end: float
    joint: int
    force: tuple

    def level(self, t):
        """The force's share at time t: 0 before, rising over RISE, 1, falling over RISE."""
        return float(np.clip((t - self.start) / RISE, 0, 1) * np.clip((self.end - t) / RISE, 0, 1))


@dataclass
class ContactRun:
    """A run with contacts: instants t (N,), true q, qd, the applied torque tau, the log's q_meas and
    tau_meas (N, n), the true tau_ext (N, n) and the contacts."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    q_meas: np.ndarray
    tau_meas: np.ndarray
    tau_ext: np.ndarray
    contacts: list

    def log(self, joint_names):
        """The user's log as a Recording (no qd) with ``joint_names`` (the robot's, in order)."""
        from ...logs.recording import Recording
        return Recording(t=self.t, q=self.q_meas, tau=self.tau_meas, qd=None, joint_names=list(joint_names))


def _body_of_joint(plant, joint):
    mj, m = plant._mj, plant.model
    names = [mj.mj_id2name(m, mj.mjtObj.mjOBJ_JOINT, i) for i in range(m.njnt)]
    return int(m.jnt_bodyid[names.index(plant.robot.joint_names[joint])])


def contact_run(plant, reference, T, contacts, seed=0, kp=KP, kd=KD):
    """The closed loop of ``plant`` (a RealPlant) on ``reference`` for T s with ``contacts`` (list of
    Contact), on the plant's jittered clock (``plant.instants``), every instant logged; ``seed``
    of the instants and the sensors' noise, ``kp``, ``kd`` the computed-torque gains (1/s^2, 1/s).

    Returns
    -------
    ContactRun
    """
    mj, m, d = plant._mj, plant.model, plant.data
    t = plant.instants(T, seed)
    N, n = len(t), plant.n
    bodies = [_body_of_joint(plant, c.joint) for c in contacts]
    Q, QD, TAU, EXT = (np.zeros((N, n)) for _ in range(4))
    mj.mj_resetData(m, d)
    q_d, qd_d, _ = reference(t[0])
    plant.set_state(q_d, qd_d)
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    for k in range(N):
        q, qd = plant.get_state()
        q_d, qd_d, qdd_d = reference(t[k])
        tau = plant.inverse_dynamics(q, qd, qdd_d + kd * (qd_d - qd) + kp * (q_d - q))
        Q[k], QD[k], TAU[k] = q, qd, tau
        d.xfrc_applied[:] = 0.0
        plant.set_state(q, qd)
        mj.mj_forward(m, d)
        for c, b in zip(contacts, bodies):
            f = c.level(t[k]) * np.asarray(c.force, float)
            if f.any():
                d.xfrc_applied[b, :3] += f
                mj.mj_jacBodyCom(m, d, jacp, jacr, b)
                EXT[k] += jacp[:, plant._vi].T @ f
        if k < N - 1:
            plant.advance(t[k + 1] - t[k], tau)
    d.xfrc_applied[:] = 0.0
    std = plant.torque_noise_std(TAU)
    noise = _rng(seed, "noise").standard_normal(TAU.shape)
    return ContactRun(t=t, q=Q, qd=QD, tau=TAU, q_meas=plant.measure_position(Q, seed),
                      tau_meas=TAU + std * noise + plant.perturbation.torque_offset, tau_ext=EXT,
                      contacts=list(contacts))
