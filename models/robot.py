"""What a robot is: the rigid manipulator model of SPEC §0.

    M(q) qdd + C(q, qd) qd + F qd + g(q) = tau          [S000 (1)]

with C the Christoffel Coriolis matrix, so that Mdot = C + C^T and
C(q, a) b = C(q, b) a  [S000 (3)].

A concrete robot (closed form, URDF) subclasses :class:`RobotModel` and gives the
symbolic building blocks ``mass_matrix``, ``gravity`` and ``com_positions``; the
recursive forms (``nle`` by RNEA, ``forward_dynamics`` by ABA) are overridden
where a robot has them. Everything symbolic is CasADi SX; ``M``, ``C``, ``g``
are ``casadi.Function`` objects built from those blocks.
"""
from __future__ import annotations

import hashlib
import json
from functools import cached_property

import casadi as ca
import numpy as np


class ModelError(ValueError):
    """A robot description we cannot use (unsupported joint, bad inertia, ...)."""


class RobotModel:
    """Base class of every rigid robot.

    Subclasses set, in their ``__init__``:

    ``name``        catalog name or URDF stem
    ``n``           number of joints
    ``F``           (n, n) viscous friction matrix
    ``dim``         2 for planar robots, 3 for spatial ones (CoM coordinates)
    ``masses``      (n,) mass of each link (the body moved by joint i)
    ``q_lower``, ``q_upper``  (n,) joint ranges used to sample configurations
    ``v_limit``     (n,) joint speed limits (informative)
    ``joint_names`` list of n names
    ``source``      JSON-able dict saying how to rebuild the robot *without* our
                    symbolic code (the independent reference reads it)
    """

    name: str
    n: int
    F: np.ndarray
    dim: int
    masses: np.ndarray
    q_lower: np.ndarray
    q_upper: np.ndarray
    v_limit: np.ndarray
    joint_names: list
    source: dict

    @property
    def periodic(self):
        """(n,) bools: joint i is 2 pi-periodic, i.e. M(q), C(q, .) and g(q) are 2 pi-periodic in
        q_i (revolute joints). Default: none declared (subclasses that know say so); the I&I
        observers use it to reduce their quadrature intervals (codegen/families/observers/_ii_common)."""
        return np.asarray(getattr(self, "_periodic", np.zeros(self.n, dtype=bool)), dtype=bool)

    # ------------------------------------------------------------ symbolic blocks
    def mass_matrix(self, q):
        """M(q): (n, n) SX."""
        raise NotImplementedError

    def gravity(self, q):
        """g(q): (n, 1) SX."""
        raise NotImplementedError

    def com_positions(self, q):
        """Link centre-of-mass positions [p_1; ...; p_n]: (dim*n, 1) SX (m)  [S002 (8)].

        ``q`` is the (n, 1) SX joint position."""
        raise NotImplementedError

    def coriolis(self, q, v):
        """Christoffel C(q, v) [SPEC §0], in matrix form

            C = 1/2 (Mdot + J - J^T),   Mdot = sum_i dM/dq_i v_i,   J = d(M(q) v)/dq |_v

        (row k, column j of J - J^T gives dM_ki/dq_j v_i - dM_ij/dq_k v_i)."""
        return self._coriolis_fun(q, v)

    def nle(self, q, v):
        """Non-linear effects C(q, v) v + g(q)."""
        return ca.mtimes(self.coriolis(q, v), v) + self.gravity(q)

    def forward_dynamics(self, q, v, tau):
        """qdd = M(q)^{-1} (tau - C(q, v) v - F v - g(q))  [S000 (1)]."""
        rhs = tau - self.nle(q, v) - ca.mtimes(ca.DM(self.F), v)
        return ca.solve(self.mass_matrix(q), rhs)

    def com_jacobian(self, q):
        """J_p(q) = d p / d q: (dim*n, n) SX  [S002 (8)]."""
        return self._com_jacobian_fun(q)

    # ------------------------------------------------------------ functions
    def _sym(self):
        return ca.SX.sym("q", self.n), ca.SX.sym("v", self.n)

    @cached_property
    def _coriolis_fun(self):
        q, v = self._sym()
        Mq = self.mass_matrix(q)
        Mdot = ca.jtimes(Mq, q, v)
        J = ca.jacobian(ca.mtimes(Mq, v), q)
        return ca.Function("C", [q, v], [0.5 * (Mdot + J - J.T)])

    @cached_property
    def _com_jacobian_fun(self):
        q, _ = self._sym()
        return ca.Function("Jp", [q], [ca.jacobian(self.com_positions(q), q)])

    @cached_property
    def M(self):
        """M as a casadi.Function q (n) -> M (n, n)  [S000 (1)]."""
        q, _ = self._sym()
        return ca.Function("M", [q], [self.mass_matrix(q)], ["q"], ["M"])

    @cached_property
    def C(self):
        """The Christoffel Coriolis matrix as a casadi.Function (q (n), v (n)) -> C (n, n)
        [S000 (1), (3)]."""
        q, v = self._sym()
        return ca.Function("C", [q, v], [self.coriolis(q, v)], ["q", "v"], ["C"])

    @cached_property
    def g(self):
        """The gravity torque as a casadi.Function q (n) -> g (n)  [S000 (1)]."""
        q, _ = self._sym()
        return ca.Function("g", [q], [self.gravity(q)], ["q"], ["g"])

    @cached_property
    def com(self):
        """CoM positions as a casadi.Function q (n) -> p (dim*n)  [S002 (8)]."""
        q, _ = self._sym()
        return ca.Function("com", [q], [self.com_positions(q)], ["q"], ["p"])

    @cached_property
    def Jcom(self):
        """CoM Jacobian as a casadi.Function q (n) -> Jp (dim*n, n)  [S002 (8)]."""
        q, _ = self._sym()
        return ca.Function("Jcom", [q], [self.com_jacobian(q)], ["q"], ["Jp"])

    @cached_property
    def fd(self):
        """Forward dynamics as a Function (q, v, tau) -> qdd."""
        q, v = self._sym()
        tau = ca.SX.sym("tau", self.n)
        return ca.Function("fd", [q, v, tau], [self.forward_dynamics(q, v, tau)],
                           ["q", "v", "tau"], ["qdd"])

    # ------------------------------------------------------------ numeric helpers
    def sample_configurations(self, count, seed=0):
        """`count` configurations drawn uniformly in [q_lower, q_upper], shape (count, n); ``seed``
        seeds ``numpy.random.default_rng``."""
        rng = np.random.default_rng(seed)
        return rng.uniform(self.q_lower, self.q_upper, size=(count, self.n))

    def check_mass_matrix(self, count=64, seed=0):
        """Raise ModelError if M(q) is not symmetric positive definite at one of ``count``
        configurations sampled with ``seed`` (:meth:`sample_configurations`)."""
        for q in self.sample_configurations(count, seed):
            Mq = np.array(self.M(q))
            try:
                np.linalg.cholesky(0.5 * (Mq + Mq.T))
            except np.linalg.LinAlgError:
                raise ModelError(
                    f"robot {self.name!r}: M(q) is singular or not positive definite at "
                    f"q = {np.array2string(q, precision=4)}") from None

    @property
    def fingerprint(self):
        """Hash of what defines the robot (its source, friction and ranges)."""
        blob = json.dumps({"source": self.source, "F": np.asarray(self.F).tolist(),
                           "n": self.n}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    def __repr__(self):
        return f"<{type(self).__name__} {self.name!r} n={self.n}>"
