"""Elastic-joint robot (Spong 1987 assumptions), docs/papers/seed004.md §6, seed 004.

    M(q1) q1'' + c(q1, q1') + g(q1) + K (q1 - q2) = 0                  [S004 (2.6)]
    J q2'' - K (q1 - q2) = u                                            [S004 (2.7)]

with q1 the link and q2 the motor positions (after the gear), J = diag(rg^2 Izz) and K the
diagonal joint stiffness. State x = [x1; x2; x3; x4] = [q1; q1'; q2; q2'] (4n):

    x' = f(x) + G(x) u,   f = [x2; FD(x1, x2, -K(x1 - x3)); x4; J^-1 K (x1 - x3)],
    G = [0; 0; 0; J^-1]                                                 [S004 (2.8)-(2.11)]

FD is the rigid robot's forward dynamics, so c(q1, q1') here is C(q1, q1') q1' + tau_f(q1') (the
rigid model's friction tau_f(v) = F v + coulomb tanh(v / w) + offset, models/robot.py; zero for
the seed robots) [DERIVED].

``ElasticRobot.n`` is the number of JOINTS (as for a rigid robot); the state has ``nx = 4 n``.
It duck-types what ObserverSpec/emit need: ``name``, ``n``, ``fingerprint``, ``source``.
"""
from __future__ import annotations

import hashlib
import json
from functools import cached_property

import casadi as ca
import numpy as np

from models.robot import ModelError


def _diag(value, n, what):
    a = np.asarray(value, dtype=float)
    a = np.full(n, float(a)) if a.ndim == 0 else (np.diag(a) if a.ndim == 2 else a)
    if a.shape != (n,) or np.any(a <= 0):
        raise ModelError(f"{what} must be positive (scalar, ({n},) or diagonal ({n},{n})), got {value!r}")
    return a


class ElasticRobot:
    """A rigid RobotModel plus motor inertias J and joint stiffness K (module docstring).

    Parameters
    ----------
    rigid : models.RobotModel
    J, K : scalar, (n,) or diagonal (n, n) motor inertias (kg m^2) and stiffness (N m/rad)
    """

    def __init__(self, rigid, J, K, name=None):
        self.rigid = rigid
        self.n = rigid.n
        self.nx = 4 * self.n
        self.J = np.diag(_diag(J, self.n, "J"))
        self.K = np.diag(_diag(K, self.n, "K"))
        self.name = name or f"{rigid.name}_elastic"
        self.joint_names = list(rigid.joint_names)
        self.q_lower, self.q_upper = np.asarray(rigid.q_lower), np.asarray(rigid.q_upper)
        # the link side's declared limits (models/robot.py), the motor torque bound by the joint's effort
        self.position_limited = getattr(rigid, "position_limited", np.zeros(self.n, dtype=bool))
        self.effort_limit = getattr(rigid, "effort_limit", np.full(self.n, np.inf))
        j = self.joint_names
        self.state_names = ([f"q1_{a}" for a in j] + [f"q1d_{a}" for a in j]
                            + [f"q2_{a}" for a in j] + [f"q2d_{a}" for a in j])
        self.source = {"kind": "elastic", "name": self.name, "rigid": rigid.source,
                       "J": np.diag(self.J).tolist(), "K": np.diag(self.K).tolist()}

    @property
    def fingerprint(self):
        blob = json.dumps({"source": self.source, "F": np.asarray(self.rigid.F).tolist()},
                          sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    def __repr__(self):
        return f"<ElasticRobot {self.name!r} n={self.n} nx={self.nx}>"

    def with_friction(self, viscous=None, coulomb=None, offset=None, width=None):
        """This elastic robot on ``rigid.with_friction(viscous, coulomb, offset, width)`` (the link
        side's friction, models/robot.py ``RobotModel.with_friction``; None keeps a value), same
        J, K and name."""
        rigid = self.rigid.with_friction(viscous=viscous, coulomb=coulomb, offset=offset, width=width)
        return ElasticRobot(rigid, np.diag(self.J), np.diag(self.K), name=self.name)

    # ------------------------------------------------------------ symbolic blocks
    def split(self, x):
        """(x1, x2, x3, x4) = (q1, q1', q2, q2') of a (4n, 1) state ``x``, each (n, 1)."""
        n = self.n
        return x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n:]

    def elastic_torque(self, x):
        """tau_el = K (q1 - q2) of the (4n, 1) state ``x``: (n, 1) (N m)."""
        x1, _, x3, _ = self.split(x)
        return ca.mtimes(ca.DM(self.K), x1 - x3)

    def drift(self, x):
        """f(x) of x' = f(x) + G(x) u  [S004 (2.8)-(2.11)]."""
        x1, x2, x3, x4 = self.split(x)
        tau = self.elastic_torque(x)
        return ca.vertcat(x2, self.rigid.forward_dynamics(x1, x2, -tau),
                          x4, ca.mtimes(ca.DM(np.linalg.inv(self.J)), tau))

    def input_matrix(self, x=None):
        """G = [0; 0; 0; J^-1] (constant), (4n, n)  [S004 (2.8)]; ``x`` is accepted for the
        x' = f(x) + G(x) u signature and ignored."""
        n = self.n
        return ca.vertcat(ca.DM.zeros(3 * n, n), ca.DM(np.linalg.inv(self.J)))

    def dynamics(self, x, u):
        """x' = f(x) + G u."""
        return self.drift(x) + ca.mtimes(self.input_matrix(x), u)

    def link_positions(self, x):
        """The link positions q1 = x1 of the (4n, 1) state ``x``: (n, 1) (rad)."""
        return self.split(x)[0]

    def motor_positions(self, x):
        """The motor positions q2 = x3 of the (4n, 1) state ``x``: (n, 1) (rad, after the gear)."""
        return self.split(x)[2]

    # ------------------------------------------------------------ functions
    @cached_property
    def f(self):
        """The drift f(x) as a casadi.Function x (4n) -> f (4n)  [S004 (2.8)-(2.11)]."""
        x = ca.SX.sym("x", self.nx)
        return ca.Function("f", [x], [self.drift(x)], ["x"], ["f"])

    @cached_property
    def xdot(self):
        """The dynamics x' = f(x) + G u as a casadi.Function (x (4n), u (n, N m)) -> xdot (4n)."""
        x, u = ca.SX.sym("x", self.nx), ca.SX.sym("u", self.n)
        return ca.Function("xdot", [x, u], [self.dynamics(x, u)], ["x", "u"], ["xdot"])

    # ------------------------------------------------------------ numeric helpers
    def sample_states(self, count, seed=0, speed=1.0, deflection=0.05):
        """Random states for checks, q1 in the joint ranges and q2 = q1 + deflection noise.

        Parameters
        ----------
        count : int
            Number of states.
        seed : int
            Seed of ``numpy.random.default_rng``.
        speed : float
            Standard deviation of the link and motor velocities (rad/s).
        deflection : float
            Standard deviation of q2 - q1 (rad).

        Returns
        -------
        numpy.ndarray, shape (count, 4n)
        """
        rng = np.random.default_rng(seed)
        q1 = rng.uniform(self.q_lower, self.q_upper, size=(count, self.n))
        q2 = q1 + deflection * rng.normal(size=q1.shape)
        return np.hstack([q1, speed * rng.normal(size=q1.shape), q2, speed * rng.normal(size=q1.shape)])
