"""A URDF robot as pinocchio sees it (``_Arm``: the reduced model, each body's primary link, the
parameter scales) and the joint torque regressor of

    tau = Y(q, qd, qdd) pi + diag(qd) f_v + diag(tanh(qd / w)) f_c + f_o            (1)

with its base parameters (the combinations any log can determine: QR with column pivoting)."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .parametrisation import (COM_MARGIN, MASS_FLOOR, MASS_FLOOR_TOTAL, RHO, RHO_LENGTH, LinkBounds,
                              _link_inertial, project)

DEFAULT_COULOMB_WIDTH = 0.05    # rad/s, for a robot model without coulomb_width (models' have one)
INERTIAL = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
FRICTION = ("viscous", "coulomb", "offset")
STRUCTURAL_TOL = 1e-8           # |R_kk| / |R_00| below this: a structurally dependent column


def base_parameters(W, tol=STRUCTURAL_TOL):
    """Base parameters of a regressor by QR with column pivoting: W P = Q R, rank r the number
    of |R_kk| > tol |R_00|; then W[:, dep] = W[:, indep] K and W x = W[:, indep] beta with

        beta = x[indep] + K x[dep]                                                  (2)

    Parameters
    ----------
    W : (rows, p) array
        Stacked regressor (columns scaled alike, so that ``tol`` compares like with like).
    tol : float
        Relative rank tolerance.

    Returns
    -------
    indep : (r,) int array
        Columns whose parameters lead a base combination.
    dep : (p - r,) int array
    K : (r, p - r) array
    """
    from scipy.linalg import qr, solve_triangular
    _, R, P = qr(W, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    r = int(np.sum(d > tol * d[0])) if d.size and d[0] > 0 else 0
    K = solve_triangular(R[:r, :r], R[:r, r:]) if r else np.zeros((0, W.shape[1]))
    K[np.abs(K) < 1e-10] = 0.0
    return np.sort(P[:r]) if r else P[:0], P[r:], _reorder(P[:r], K)


def _reorder(indep, K):
    """Rows of K in increasing order of ``indep``."""
    return K[np.argsort(indep)] if len(indep) else K


def _tri(M):
    """An upper triangular R with R^T R = M^T M (same singular values and right singular
    vectors, k x k): the Cholesky factor of the Gram matrix (a tall M's columns are scaled, its
    condition number small); where that is singular in double precision (a column no row
    excites) of the Gram matrix plus 1e-13 x its mean diagonal, QR where even that fails."""
    if M.shape[0] <= M.shape[1]:
        return M
    G = M.T @ M
    try:
        return np.linalg.cholesky(G).T
    except np.linalg.LinAlgError:
        pass
    try:
        return np.linalg.cholesky(G + 1e-13 * np.trace(G) / len(G) * np.eye(len(G))).T
    except np.linalg.LinAlgError:
        return np.linalg.qr(M, mode="r")


class _Arm:
    """A URDF robot's pinocchio model (locked joints removed, as the reference rebuilds it from
    ``robot.source``), its URDF tree, each body's primary link and the parameter scales."""

    def effect(self, noise):
        """(p,) the torque one unit of each scaled parameter makes on the robot's working range
        (RMS), in units of each joint's torque scale or its torque ``noise`` (n,), whichever is
        larger, the largest over the joints: std x effect is the torque uncertainty a parameter
        leaves, and a joint whose rigid-body torque is below its sensor's noise (a wrist roll)
        is not asked to be known better than that noise."""
        unit = np.maximum(self.torque_scale, noise)
        return (self.effect_joint * (self.torque_scale / unit)[:, None]).max(axis=0)

    def __init__(self, robot, coulomb_width=None):
        import pinocchio as pin

        from codegen.reference.robots.urdf import UrdfRobot
        self.pin = pin
        src = getattr(robot, "source", None)
        if not isinstance(src, dict) or src.get("kind") != "urdf":
            kind = src.get("kind") if isinstance(src, dict) else type(robot).__name__
            raise ValueError(f"robot: identification needs a URDF robot (load_robot(urdf=...), ur5, "
                             f"panda), got {getattr(robot, 'name', robot)!r} of kind {kind!r}")
        self.name = str(robot.name)
        self.path = Path(src["path"])
        self.locked = dict(src.get("locked_joints") or {})
        self.snap_tol = float(src.get("snap_tol", 1e-9))
        self.ref = UrdfRobot(self.path, src.get("sha256"), self.locked, self.snap_tol)
        self.model, self.data = self.ref.model, self.ref.data
        self.n = n = self.ref.n
        self.joint_names = list(self.ref.joint_names)
        if list(robot.joint_names) != self.joint_names:
            raise ValueError(f"robot: joints {robot.joint_names} differ from its URDF's {self.joint_names}")
        self.p = 13 * n
        # the URDF: each joint's child link (the primary link, whose <inertial> is identified);
        # what else the body carries (fixed links, locked subtrees) is kept as the URDF has it
        self.tree = ET.parse(self.path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
        root = self.tree.getroot()
        joints = {j.get("name"): j for j in root.findall("joint")}
        links = {e.get("name"): e for e in root.findall("link")}
        self.links = [joints[j].find("child").get("link") for j in self.joint_names]
        self.pi_urdf = np.concatenate([self.model.inertias[i].toDynamicParameters()
                                       for i in range(1, n + 1)])
        primary = np.concatenate([_link_inertial(links[k]) for k in self.links])
        self.attached = self.pi_urdf - primary
        self.primary_urdf = primary
        # the robot's friction (URDF <dynamics> and side file), pinocchio's <dynamics> otherwise
        self.friction_urdf = np.concatenate([
            np.asarray(getattr(robot, "viscous", self.model.damping), float),
            np.asarray(getattr(robot, "coulomb", self.model.friction), float),
            np.asarray(getattr(robot, "offset", np.zeros(n)), float)])
        self.x_urdf = np.concatenate([self.pi_urdf, self.friction_urdf])
        self.q_lower = np.asarray(robot.q_lower, float)
        self.q_upper = np.asarray(robot.q_upper, float)
        vl = np.asarray(getattr(robot, "v_limit", np.full(n, np.nan)), float)
        self.v_limit_known = np.isfinite(vl) & (vl > 0)
        self.v_limit = np.where(self.v_limit_known, vl, 1.0)
        self.robot_width = getattr(robot, "coulomb_width", None)
        self.selection = None                # held-out RMS per (cut-off, width), when identify() selects
        if coulomb_width == "auto":          # identify() selects it; the robot's until then
            coulomb_width = None
        width = coulomb_width if coulomb_width is not None else self.robot_width
        self.width_source = ("given" if coulomb_width is not None else
                             "the robot model's coulomb_width, as its observers use it" if width is not None
                             else f"default {DEFAULT_COULOMB_WIDTH} rad/s (the robot model has no coulomb_width)")
        self.width = float(width) if width is not None else DEFAULT_COULOMB_WIDTH
        if not (math.isfinite(self.width) and self.width > 0):
            raise ValueError(f"coulomb_width: expected a positive number (rad/s), got {width!r}")
        self.names, self.owner = [], []
        for i, link in enumerate(self.links):
            self.names += [f"{link}.{k}" for k in INERTIAL]
            self.owner += [i] * 10
        for k in FRICTION:
            self.names += [f"{j}.{k}" for j in self.joint_names]
            self.owner += list(range(n))
        self.owner = np.array(self.owner)
        self._scales()
        self._bounds(joints, links)

    # ------------------------------------------------------------------ coordinates
    def pin_configurations(self, q):
        """(N, nq) pinocchio configurations of our (N, n) joint coordinates (cos, sin for
        continuous joints)."""
        Q = np.zeros((len(q), self.model.nq))
        for k, j in enumerate(self.model.joints[1:]):
            if j.nq == 2:
                Q[:, j.idx_q], Q[:, j.idx_q + 1] = np.cos(q[:, k]), np.sin(q[:, k])
            else:
                Q[:, j.idx_q] = q[:, k]
        return Q

    def regressor(self, q, v, a, width=None):
        """(N, n, 13 n): pinocchio's joint torque regressor of (N, n) ``q, v, a`` and the
        friction columns of (1) at Coulomb width ``width`` (default ``self.width``)."""
        N, n = len(q), self.n
        Y = np.zeros((N, n, self.p))
        Q = self.pin_configurations(q)
        reg = self.pin.computeJointTorqueRegressor
        for k in range(N):
            Y[k, :, :10 * n] = reg(self.model, self.data, Q[k], v[k], a[k])
        i = np.arange(n)
        Y[:, i, 10 * n + i] = v
        Y[:, i, 11 * n + i] = np.tanh(v / (self.width if width is None else width))
        Y[:, i, 12 * n + i] = 1.0
        return Y

    def probe(self, count=None, seed=0):
        """(q, v, a) of ``count`` random states: q uniform in the joint ranges, v in +-the
        velocity limit, a in +-2 (1/s) x the velocity limit."""
        rng = np.random.default_rng(seed)
        count = count or max(300, 3 * self.p)
        q = rng.uniform(self.q_lower, self.q_upper, (count, self.n))
        v = rng.uniform(-1, 1, (count, self.n)) * self.v_limit
        a = rng.uniform(-2, 2, (count, self.n)) * self.v_limit
        return q, v, a

    def _scales(self):
        """Scales of the parameters and of the joint torques.

        Body i of mass m and length l = max(|c|, radius of gyration, distance to its child
        joints, 1 cm): m, m l (first moment), m l^2 (inertia). Joint torque tau_s: the RMS of the
        URDF's rigid-body torque on :meth:`probe` states; friction: tau_s / v_limit (viscous),
        tau_s (Coulomb, offset)."""
        n, model = self.n, self.model
        s = np.empty(self.p)
        self.length = np.empty(n)
        for i in range(1, n + 1):
            Y = model.inertias[i]
            m = float(Y.mass)
            ell = [np.linalg.norm(Y.lever), math.sqrt(max(np.linalg.eigvalsh(Y.inertia)[-1], 0.0) / m), 0.01]
            ell += [np.linalg.norm(model.jointPlacements[k].translation)
                    for k in range(1, model.njoints) if model.parents[k] == i]
            ell = max(ell)
            s[10 * (i - 1):10 * i] = [m] + [m * ell] * 3 + [m * ell ** 2] * 6
            self.length[i - 1] = ell
        q, v, a = self.probe(seed=1)
        Y = self.regressor(q, v, a)
        tau = Y[:, :, :10 * n] @ self.pi_urdf
        ts = np.sqrt(np.mean(tau ** 2, axis=0))
        ts = np.maximum(ts, 1e-6 * max(ts.max(), 1e-12))
        self.torque_scale = ts
        s[10 * n:11 * n] = ts / self.v_limit
        s[11 * n:12 * n] = ts
        s[12 * n:] = ts
        self.scale = s
        effort = np.asarray(model.effortLimit, float)[[j.idx_v for j in model.joints[1:]]]
        effort = np.where(np.isfinite(effort) & (effort > 0), effort, 0.0)
        self.effort = effort
        self.prior_scale = s.copy()
        self.friction_prior(effort)
        Ws = Y / ts[None, :, None] * s
        # what one unit of a scaled parameter does to each joint's torque on these states (RMS,
        # in units of the joint's torque scale): see effect()
        self.effect_joint = np.sqrt(np.mean(Ws ** 2, axis=0))           # (n, p)
        W = Ws.reshape(-1, self.p)
        self.indep, self.dep, self.K = base_parameters(W)
        self.T = np.zeros((len(self.indep), self.p))       # beta~ = T x~ (scaled units), (2)
        self.T[np.arange(len(self.indep)), self.indep] = 1.0
        self.T[:, self.dep] = self.K
        _, sv, Vt = np.linalg.svd(W, full_matrices=False)
        self.rowspace = Vt[:len(self.indep)].T              # (p, r): what a log can determine
        self.K_phys = s[self.indep][:, None] * self.K / s[self.dep][None, :]

    def _bounds(self, joints, links):
        """Each primary link's :class:`LinkBounds` (physical units, ``bounds``; in the scaled units
        of its body, ``bounds_scaled``) and the prior: the URDF's <inertial> projected into them
        (``prior_primary``; ``projected``: link -> what moved, for the links that were not).

        Least mass: MASS_FLOOR x the URDF link's, or MASS_FLOOR_TOTAL x the robot's moving mass if
        larger; reach: the farthest origin of the link's child joints (of any type) or its URDF
        centre of mass, plus COM_MARGIN; rho: RHO, at most RHO_LENGTH x the body's length scale."""
        n = self.n
        total = float(sum(self.model.inertias[i].mass for i in range(1, n + 1)))
        self.bounds, self.bounds_scaled, self.projected = [], [], {}
        prior = []
        for i, link in enumerate(self.links):
            pi = self.primary_urdf[10 * i:10 * i + 10]
            m = float(pi[0])
            com = np.linalg.norm(pi[1:4] / m) if m > 0 else 0.0
            reach = [np.linalg.norm([float(v) for v in (j.find("origin").get("xyz", "0 0 0")
                                                          if j.find("origin") is not None else "0 0 0").split()])
                     for j in joints.values() if j.find("parent").get("link") == link]
            b = LinkBounds(mass=max(MASS_FLOOR * max(m, 0.0), MASS_FLOOR_TOTAL * total),
                           reach=max([com, *reach]) + COM_MARGIN,
                           rho=min(RHO, RHO_LENGTH * self.length[i]))
            self.bounds.append(b)
            m0, ell = self.scale[10 * i], self.length[i]
            self.bounds_scaled.append(LinkBounds(b.mass / m0, b.reach / ell, b.rho / ell))
            p, changes = project(pi, b)
            if changes:
                self.projected[link] = changes
            prior.append(p if changes else pi)
        self.prior_primary = np.concatenate(prior)
        self.x_prior = self.x_urdf.copy()
        self.x_prior[:10 * n] = self.attached + self.prior_primary

    def friction_prior(self, torque):
        """The prior's unit of the friction (``prior_scale``'s last 3 n entries): the parameter
        scale, or where larger the torque ``torque`` (n,) N m a joint shows (the RMS of its
        measured torque on a log; the effort limit without one), over the velocity limit for the
        viscous one. The URDF knows nothing of a real joint's friction, and its rigid-body torque
        scale can be far below it (a wrist roll); an effort limit far above it leaves Coulomb and
        offset free to cancel where a joint turns one way."""
        n, s = self.n, self.scale
        for k in range(3):
            f = slice(10 * n + k * n, 10 * n + (k + 1) * n)
            self.prior_scale[f] = np.maximum(s[f], np.asarray(torque, float) / (self.v_limit if k == 0 else 1.0))

    def combination(self, k, terms=None):
        """Readable text of base parameter ``k`` in physical units, 'x_i + c x_j + ...' (the
        first ``terms`` terms and '...' if given)."""
        i = self.indep[k]
        out = [self.names[i]]
        for c, j in sorted(zip(self.K_phys[k], self.dep), key=lambda cj: -abs(cj[0]) * self.scale[cj[1]]):
            if abs(c) * self.scale[j] > 1e-9 * self.scale[i]:
                out.append(f"{'-' if c < 0 else '+'} {abs(c):.6g} {self.names[j]}")
        return " ".join(out if terms is None or len(out) <= terms else out[:terms] + ["+ ..."])

    def friction_value(self, x):
        """(f_v, f_c, f_o) of a parameter vector ``x`` (13 n,)."""
        n = self.n
        return x[10 * n:11 * n], x[11 * n:12 * n], x[12 * n:]

