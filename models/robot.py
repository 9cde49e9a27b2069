"""What a robot is: the rigid manipulator model of docs/papers/seed000.md §0 with joint friction.

    M(q) qdd + C(q, qd) qd + tau_f(qd) + g(q) = tau          [S000 (1)]
    tau_f(v) = viscous v + coulomb tanh(v / coulomb_width) + offset   (per joint)

with C the Christoffel Coriolis matrix, so that Mdot = C + C^T and
C(q, a) b = C(q, b) a  [S000 (3)]. ``F = diag(viscous)`` is the viscous matrix of [S000 (1)];
``coulomb`` tanh(v / coulomb_width) is a smooth Coulomb friction and ``offset`` a constant torque
(a torque sensor's offset, an unmodelled torque). Without Coulomb friction and offset, tau_f = F v
and every expression is the one of the viscous model.

A concrete robot (closed form, URDF) subclasses :class:`RobotModel` and gives the
symbolic building blocks ``mass_matrix``, ``gravity`` and ``com_positions``; the
recursive forms (``nle`` by RNEA, ``forward_dynamics`` by ABA) are overridden
where a robot has them. Everything symbolic is CasADi SX; ``M``, ``C``, ``g``
are ``casadi.Function`` objects built from those blocks.
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
from functools import cached_property

import casadi as ca
import numpy as np

from models.algebra import add

# The default width of the smooth sign tanh(v / w) of Coulomb friction (rad/s; m/s on a prismatic
# joint). Why this value (accuracy against stiffness, measured): RobotModel.with_friction, Notes.
DEFAULT_COULOMB_WIDTH = 0.2


class ModelError(ValueError):
    """A robot description we cannot use (unsupported joint, bad inertia, ...)."""


class RobotModel:
    """Base class of every rigid robot.

    Subclasses set, in their ``__init__``:

    ``name``        catalog name or URDF stem
    ``n``           number of joints
    ``F``           (n, n) viscous friction matrix, diagonal (assigning it sets ``viscous``)
    ``dim``         2 for planar robots, 3 for spatial ones (CoM coordinates)
    ``masses``      (n,) mass of each link (the body moved by joint i)
    ``q_lower``, ``q_upper``  (n,) joint ranges used to sample configurations
    ``v_limit``     (n,) joint speed limits (informative)

    and, when the description declares them (a URDF's ``<limit>``), ``_position_limited`` ((n,)
    bools: q_lower, q_upper are the joint's declared limits, not a sampling range) and
    ``_effort_limit`` ((n,) N m or N, inf where not declared): ``position_limited``,
    ``effort_limit``.
    ``joint_names`` list of n names
    ``source``      JSON-able dict saying how to rebuild the robot *without* our
                    symbolic code (the independent reference reads it)

    and, when the description has it, Coulomb friction (``self._set_friction(coulomb=...)``).
    Friction: ``viscous``, ``coulomb``, ``offset`` ((n,) each) and ``coulomb_width`` give

        tau_f(v) = viscous v + coulomb tanh(v / coulomb_width) + offset

    (``friction_torque``, ``tau_f``); ``with_friction`` returns a copy with other values. The
    ``source`` then carries a ``"friction"`` entry (see ``source``).
    """

    name: str
    n: int
    dim: int
    masses: np.ndarray
    q_lower: np.ndarray
    q_upper: np.ndarray
    v_limit: np.ndarray
    joint_names: list

    # cached properties that depend on the friction (dropped by ``with_friction``); a subclass
    # with more of them extends the tuple
    _FRICTION_CACHED = ("fd", "tau_f")

    @property
    def position_limited(self):
        """(n,) bools: joint i's ``q_lower``, ``q_upper`` are limits its description declares (a
        URDF's revolute or prismatic ``<limit lower upper>``), not only the range configurations
        are sampled in (a continuous joint, a closed form, a DH table: none declared)."""
        return np.asarray(getattr(self, "_position_limited", np.zeros(self.n, dtype=bool)), dtype=bool)

    @property
    def effort_limit(self):
        """(n,) the declared effort limits, N m (N on a prismatic joint); inf where none is declared
        (a URDF's ``<limit effort>``, absent or 0: none)."""
        return np.asarray(getattr(self, "_effort_limit", np.full(self.n, np.inf)), dtype=float)

    @property
    def periodic(self):
        """(n,) bools: joint i is 2 pi-periodic, i.e. M(q), C(q, .) and g(q) are 2 pi-periodic in
        q_i (revolute joints). Default: none declared (subclasses that know say so); the I&I
        observers use it to reduce their quadrature intervals (codegen/families/observers/_ii_common)."""
        return np.asarray(getattr(self, "_periodic", np.zeros(self.n, dtype=bool)), dtype=bool)

    # ------------------------------------------------------------ friction
    @property
    def viscous(self):
        """(n,) viscous friction coefficients, N m s/rad (N s/m on a prismatic joint)."""
        return np.array(self.__dict__.get("_viscous", np.zeros(self.n)), dtype=float)

    @property
    def coulomb(self):
        """(n,) Coulomb friction levels, N m (N on a prismatic joint), >= 0."""
        return np.array(self.__dict__.get("_coulomb", np.zeros(self.n)), dtype=float)

    @property
    def offset(self):
        """(n,) constant torque offsets, N m (a torque sensor's offset, an unmodelled torque)."""
        return np.array(self.__dict__.get("_offset", np.zeros(self.n)), dtype=float)

    @property
    def coulomb_width(self):
        """Width w of the smooth sign tanh(v / w) of the Coulomb friction, rad/s (> 0)."""
        return float(self.__dict__.get("_coulomb_width", DEFAULT_COULOMB_WIDTH))

    @property
    def F(self):
        """The (n, n) viscous friction matrix diag(viscous) of [S000 (1)], N m s/rad."""
        return np.diag(self.viscous)

    @F.setter
    def F(self, value):
        """Set ``viscous`` from a diagonal (n, n) ``value`` (ModelError otherwise)."""
        F = np.asarray(value, dtype=float)
        if F.ndim != 2 or F.shape[0] != F.shape[1] or F.shape[0] != self.n:
            raise ModelError(f"robot {self.name!r}: F must be an ({self.n}, {self.n}) matrix, "
                             f"got shape {F.shape}")
        if np.any(F != np.diag(np.diag(F))):
            raise ModelError(f"robot {self.name!r}: F must be diagonal (per-joint viscous friction), "
                             f"got {np.array2string(F, precision=4)}")
        self._set_friction(viscous=np.diag(F))

    def _set_friction(self, viscous=None, coulomb=None, offset=None, width=None):
        """Check and set the friction values given (the others are kept); ModelError naming the
        argument on a wrong shape, a NaN/Inf, a negative viscous or Coulomb coefficient or a
        width that is not a positive number."""
        checked = {}
        for key, value, sign in (("viscous", viscous, True), ("coulomb", coulomb, True),
                                 ("offset", offset, False)):
            if value is None:
                continue
            try:
                a = np.asarray(value, dtype=float) if not isinstance(value, (str, bytes, dict)) else None
            except (TypeError, ValueError):          # ragged, text inside, complex
                a = None
            if a is not None and a.ndim == 0:
                a = np.full(self.n, float(a))
            if a is None or a.shape != (self.n,):
                raise ModelError(f"robot {self.name!r}: {key} must be a number or {self.n} numbers "
                                 f"(one per joint), got {value!r}")
            if not np.all(np.isfinite(a)):
                raise ModelError(f"robot {self.name!r}: {key} must be finite, got {a.tolist()}")
            if sign and np.any(a < 0):
                raise ModelError(f"robot {self.name!r}: {key} must be >= 0 (friction dissipates), "
                                 f"got {a.tolist()}")
            checked[key] = a.copy()
        if width is not None:
            w = float(width) if isinstance(width, (int, float, np.floating, np.integer)) \
                and not isinstance(width, bool) else math.nan
            if not (math.isfinite(w) and w > 0):
                raise ModelError(f"robot {self.name!r}: the Coulomb width (coulomb_width) must be a "
                                 f"positive number (rad/s), got {width!r}")
            self._coulomb_width = w
        for key, a in checked.items():
            setattr(self, "_" + key, a)

    def with_friction(self, viscous=None, coulomb=None, offset=None, width=None):
        """A copy of this robot with other friction (identified or stated values).

            tau_f(v) = viscous v + coulomb tanh(v / width) + offset          (per joint)

        Parameters
        ----------
        viscous : float or (n,) array_like, optional
            Viscous coefficients, N m s/rad, >= 0 (None: keep this robot's).
        coulomb : float or (n,) array_like, optional
            Coulomb friction levels, N m, >= 0 (None: keep).
        offset : float or (n,) array_like, optional
            Constant torques, N m, any sign (None: keep).
        width : float, optional
            Width of the smooth sign, rad/s, > 0 (None: keep; default ``DEFAULT_COULOMB_WIDTH``,
            0.2 rad/s, see Notes).

        Returns
        -------
        RobotModel
            Same class and dynamics otherwise; its ``source`` and ``fingerprint`` carry the
            friction. This robot is not changed.

        Notes
        -----
        The default width ``DEFAULT_COULOMB_WIDTH`` = 0.2 rad/s trades the smooth sign's accuracy
        against stiffness. tanh(v / w) is within 5 % of sign(v) for |v| > 1.83 w (0.37 rad/s)
        and within 1 % for |v| > 2.65 w (0.53 rad/s). At v = 0 the friction is a damper of slope
        d tau_f/dv = viscous + coulomb / w, which the observers integrate explicitly: with m_min
        the smallest eigenvalue of M(q), dt coulomb / (w m_min) must stay inside the step's
        stability region (RK4: 2.785 on the negative real axis), or the stability check of
        ``compile_observer`` refuses the observer (and names the substeps that would do).
        Measured (codegen.discrete.stability.check, reduced_order and extended_state at their
        default gains, dt = 1e-3, ETD-RK4 with first-order hold, the same Coulomb level c on
        every joint): stable at every point with dt c / (w m_min) <= 2.53, refused at every one
        with >= 3.0.
        panda (m_min = 0.0044 kg m^2): stable for c <= 1 N m at w = 0.1 (dt c/(w m_min) = 2.25),
        c <= 2 at w = 0.2, c <= 3 at w = 0.3; ur5 (m_min = 0.016): c <= 2 at w = 0.05 and
        c <= 3 at w >= 0.1 (0.95 at w = 0.2). xarm7's URDF (c = 1 N m, wrist m_min = 1.3e-4,
        no rotor inertia) needs substeps at any width (6 for its viscous damping alone, 33 at
        w = 0.1, 19 at w = 0.2). The Panda's friction identified by Gaz et al. (IEEE RA-L 4(4),
        2019), a logistic of steepness phi2 = 5.1 to 17.1 s/rad, i.e. tanh of width 2/phi2 =
        0.12 to 0.39 rad/s (median 0.22) and levels 0.15 to 0.64 N m, gives 0.34 at w = 0.2.
        So 0.2 rad/s keeps arms of the Panda's and UR5's inertia inside the region at 1 kHz for
        Coulomb levels up to 2 N m (Panda) and beyond 3 N m (UR5), well inside (<= 1.13) up to
        1 N m (Panda) and 3 N m (UR5), and is no smoother than a real Panda's own friction; a
        sharper identified width goes into the side file (or ``width``), with the substeps the
        stability check then asks for.
        """
        new = copy.copy(self)
        for key in self._FRICTION_CACHED:
            new.__dict__.pop(key, None)
        new.__dict__.setdefault("_friction_base", (self.viscous, self.coulomb))
        new._set_friction(viscous=viscous, coulomb=coulomb, offset=offset, width=width)
        return new

    def _nonviscous(self, i, v):
        """coulomb_i tanh(v / w) + offset_i of joint ``i`` at its velocity ``v`` (an SX scalar),
        exact zeros folded (the float 0.0 when both are zero). tanh(x) is written
        1 - 2 / (exp(min(2x, 40)) + 1): glibc's exp costs 60 instructions where its tanh costs 112
        (valgrind), and a step evaluates the friction once per stage (ETD-RK4: 4); from 2x = 40
        on both are 1 in double, and the clamp keeps exp and the derivative finite."""
        c, o = float(self.coulomb[i]), float(self.offset[i])
        e = ca.exp(ca.fmin((2.0 / self.coulomb_width) * v, 40.0))
        term = (c - (2.0 * c) / (e + 1.0)) if c != 0.0 else 0.0
        return add(term, o)

    def friction_torque(self, v):
        """tau_f(v) = viscous v + coulomb tanh(v / coulomb_width) + offset: (n, 1) SX (N m) at the
        (n, 1) SX joint velocity ``v`` (rad/s).

        Without Coulomb friction and offset this is exactly ``mtimes(F, v)``, the viscous model's
        expression."""
        tau = ca.mtimes(ca.DM(self.F), v)
        extra = [self._nonviscous(i, v[i]) for i in range(self.n)]
        if all(isinstance(e, float) and e == 0.0 for e in extra):
            return tau
        return tau + ca.vertcat(*[ca.SX(e) if isinstance(e, float) else e for e in extra])

    @cached_property
    def tau_f(self):
        """The friction torque as a casadi.Function v (n) -> tau_f (n) (``friction_torque``)."""
        v = ca.SX.sym("v", self.n)
        return ca.Function("tau_f", [v], [self.friction_torque(v)], ["v"], ["tau_f"])

    @property
    def source(self):
        """JSON-able recipe of the robot (``models.from_source`` and the independent reference
        rebuild it from this): the description's own dict, plus, when the friction is not the
        viscous one of the description,

            "friction": {"coulomb_width": w (when some coulomb > 0),
                         "viscous": (n,), "coulomb": (n,)  (when they differ from the description's),
                         "offset": (n,)  (when not all zero)}

        in joint order. A robot without Coulomb friction and offset has no such entry."""
        base = self.__dict__.get("_source")
        entry = {}
        visc0, coul0 = self.__dict__.get("_friction_base", (self.viscous, self.coulomb))
        if not np.array_equal(self.viscous, visc0):
            entry["viscous"] = [float(x) for x in self.viscous]
        if not np.array_equal(self.coulomb, coul0):
            entry["coulomb"] = [float(x) for x in self.coulomb]
        if np.any(self.offset != 0.0):
            entry["offset"] = [float(x) for x in self.offset]
        if np.any(self.coulomb != 0.0):
            entry["coulomb_width"] = self.coulomb_width
        if not entry or base is None:
            return base
        return {**base, "friction": entry}

    @source.setter
    def source(self, value):
        """Set the description's own recipe ``value`` (the friction entry is added on reading)."""
        self._source = value

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
        """Christoffel C(q, v) [docs/papers/seed000.md §0], in matrix form

            C = 1/2 (Mdot + J - J^T),   Mdot = sum_i dM/dq_i v_i,   J = d(M(q) v)/dq |_v

        (row k, column j of J - J^T gives dM_ki/dq_j v_i - dM_ij/dq_k v_i)."""
        return self._coriolis_fun(q, v)

    def nle(self, q, v):
        """Non-linear effects C(q, v) v + g(q)."""
        return ca.mtimes(self.coriolis(q, v), v) + self.gravity(q)

    def forward_dynamics(self, q, v, tau):
        """qdd = M(q)^{-1} (tau - C(q, v) v - g(q) - tau_f(v))  [S000 (1)], tau_f the friction
        (``friction_torque``), at (n, 1) SX ``q`` (rad), ``v`` (rad/s), ``tau`` (N m)."""
        rhs = tau - self.nle(q, v) - self.friction_torque(v)
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
        """Hash of what defines the robot (its source, which carries the friction, and F)."""
        blob = json.dumps({"source": self.source, "F": np.asarray(self.F).tolist(),
                           "n": self.n}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    def __repr__(self):
        return f"<{type(self).__name__} {self.name!r} n={self.n}>"
