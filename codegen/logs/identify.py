"""Dynamic identification of a URDF robot from a log of q and tau, and the trajectory to log.

The model, per sample (n joints, one body per joint)::

    tau = Y(q, qd, qdd) pi + diag(qd) f_v + diag(tanh(qd / w)) f_c + f_o            (1)

``Y`` is pinocchio's joint torque regressor (``pin.computeJointTorqueRegressor`` on the URDF's
model with the locked joints removed), ``pi`` the 10 inertial parameters of each body
``[m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]`` (first moment and inertia about
the joint frame's origin), ``f_v, f_c, f_o`` (n,) viscous, Coulomb and constant (offset)
friction, ``w`` the Coulomb smoothing width (rad/s).

``identify`` (in this order):

1. velocity and acceleration by zero-phase smoothing of q (``codegen.logs.smoothing``), tau
   through the same zero-phase filter, so that both sides of (1) see the same band; the Coulomb
   column, not smooth where qd changes sign, is tanh of a wider-band velocity through that filter
   too (parallel filtering: without it the Coulomb and viscous estimates are biased by up to 6 %
   on a noise-free log at w = 0.05 rad/s, with it by 0.03 %);
2. the last ``test_fraction`` of the log held out; the filters' edges dropped; the least squares
   on every D-th training sample (a step of 1/(FIT_RATE cutoff)), weighted sqrt(D): below the
   cut-off nothing is lost, and the covariance is that of all samples. A joint's row is left
   out where its smoothed speed is at most ``v_stick``: stuck by dry friction, a joint holds any
   torque up to its Coulomb friction, which (1) cannot say. The covariance is
   sigma^2 (A^T A)^-1 with sigma the white noise of the unfiltered torque: the filter passes the
   band of the regressor with gain 1, so the estimate's variance is that of unfiltered data;
3. base parameters: the numerical rank of the regressor on random states of the robot (QR with
   column pivoting), i.e. which combinations of parameters any log can determine; then the
   log's own covariance of those combinations. A combination's relative std is its std times
   the torque one unit of it makes on random states of the robot (RMS, in units of each joint's
   RMS torque there or of its torque noise, whichever is larger, the largest over the joints):
   the torque uncertainty it leaves on the working range (a wrist whose rigid-body torque is
   below its sensor's noise is not asked to be known better than that noise). A log that
   leaves one above ``max_rel_std`` is refused, naming the joints (:class:`IdentificationError`);
4. a physically consistent estimate: each body's parameters as the URDF's fixed extras plus the
   primary link's pseudo-inertia ``J = U U^T`` in the log-Cholesky parametrisation of Rucker &
   Wensing ("Smooth parameterization of rigid-body inertia", RA-L 2022), friction ``f_v, f_c >= 0``,
   by ``scipy.optimize.least_squares`` from the URDF's values, with a Gaussian prior toward the
   URDF (relative std ``prior`` of each parameter's scale; friction's in units of the joint's
   effort limit, of which the URDF says nothing), which decides what the log does not excite;
   rows weighted by the torque noise of each joint, estimated from the residual;
5. the held-out residual before (URDF as shipped, no friction) and after.

Why not an SDP: cvxpy is not a dependency, and the log-Cholesky form turns the same
positive-definiteness constraint into an unconstrained smooth least-squares problem.

``excitation`` designs the trajectory to log: a Fourier series per joint (Swevers et al. 1997)
within the position, velocity and acceleration limits, at rest at t = 0 and T, whose
coefficients minimise the condition number of the stacked base regressor (SLSQP, exact gradient).
"""
from __future__ import annotations

import copy
import io
import json
import math
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .smoothing import derivatives

DEFAULT_COULOMB_WIDTH = 0.05    # rad/s, for a robot model without coulomb_width (models' have one)
WIDTHS = (0.2, 0.1, 0.05, 0.02, 0.01)   # rad/s: the Coulomb widths coulomb_width="auto" chooses from
BAND_MARGIN = 4.0              # the cut-off over the motion's band (identification_cutoff)
DEFAULT_TEST_FRACTION = 0.2
DEFAULT_PRIOR = 1.0             # relative std of the URDF's values: a payload makes the last link's a
                                # multiple of the URDF's (0.2 pulled the real ur5's wrist-3 link toward
                                # its URDF and its friction 27-36 % off; 1.0: 1-2 %)
DEFAULT_V_STICK = 0.05         # rad/s: a joint slower than this (smoothed) sticks; its rows are left out
                                # (kinova's friction within 8 % at 0.03-0.1, 47 % off with every row)
DEFAULT_MAX_REL_STD = 0.05      # a base parameter's torque uncertainty / the joint's RMS torque
INERTIAL = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
FRICTION = ("viscous", "coulomb", "offset")
WIDE = 4.0                      # the Coulomb column's velocity at WIDE x cutoff before the filter
FTOL = 1e-6                     # relative cost decrease at which the consistent solve stops
MAX_NFEV = 2000
FIT_RATE = 20.0                 # least-squares samples per second per Hz of cut-off
CHUNK = 4096                    # samples per regressor block of a prediction
STILL = 0.01                    # a joint slower than this x its velocity limit (RMS) does not move
STRUCTURAL_TOL = 1e-8           # |R_kk| / |R_00| below this: a structurally dependent column


class IdentificationError(ValueError):
    """A log that does not determine the model (the message names the joints and what to do)."""


# =============================================================================================
# rigid-body parameters
# =============================================================================================
def _inertia_matrix(p):
    """3x3 inertia of the (..., 6) entries (xx, xy, yy, xz, yz, zz)."""
    xx, xy, yy, xz, yz, zz = p
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def _inertia_entries(I):
    return np.array([I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def pseudo_inertia(pi):
    """The 4x4 pseudo-inertia of 10 inertial parameters (Wensing et al. 2017):

        J = [[Sigma, h], [h^T, m]],   Sigma = tr(I)/2 * 1 - I,

    with ``pi = [m, h (3), I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]``, ``h = m c`` and ``I`` the
    inertia about the frame's origin. ``pi`` is physically consistent iff J is positive definite.

    Parameters
    ----------
    pi : (10,) array

    Returns
    -------
    (4, 4) array
    """
    pi = np.asarray(pi, dtype=float)
    I = _inertia_matrix(pi[4:])
    J = np.empty((4, 4), dtype=pi.dtype)
    J[:3, :3] = 0.5 * np.trace(I) * np.eye(3) - I
    J[:3, 3] = J[3, :3] = pi[1:4]
    J[3, 3] = pi[0]
    return J


def _from_pseudo(J):
    """Inverse of :func:`pseudo_inertia` (linear): I = tr(Sigma) 1 - Sigma."""
    S = J[..., :3, :3]
    I = np.trace(S, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - S
    return np.concatenate([J[..., 3, 3:4], J[..., :3, 3],
                           np.stack([I[..., 0, 0], I[..., 0, 1], I[..., 1, 1], I[..., 0, 2],
                                     I[..., 1, 2], I[..., 2, 2]], axis=-1)], axis=-1)


def log_cholesky(pi):
    """Log-Cholesky coordinates theta (10,) of physically consistent parameters ``pi`` (10,)
    (Rucker & Wensing 2022): J = U U^T with

        U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]],
        theta = (alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3)

    (so m = e^(2 alpha) and the centre of mass is t). ValueError if J is not positive definite.

    Parameters
    ----------
    pi : (10,) array
        As in :func:`pseudo_inertia`.

    Returns
    -------
    (10,) array
    """
    J = pseudo_inertia(pi)
    P = np.eye(4)[::-1]
    try:
        L = np.linalg.cholesky(P @ J @ P)
    except np.linalg.LinAlgError:
        raise ValueError(f"pi: not physically consistent (pseudo-inertia eigenvalues "
                         f"{np.linalg.eigvalsh(J)})") from None
    U = P @ L @ P                       # upper triangular, J = U U^T
    ea = U[3, 3]
    return np.array([np.log(ea), np.log(U[0, 0] / ea), np.log(U[1, 1] / ea), np.log(U[2, 2] / ea),
                     U[0, 1] / ea, U[1, 2] / ea, U[0, 2] / ea, U[0, 3] / ea, U[1, 3] / ea, U[2, 3] / ea])


def from_log_cholesky(theta):
    """Inertial parameters pi (..., 10) and d pi / d theta (..., 10, 10) of log-Cholesky
    coordinates ``theta`` (..., 10) (:func:`log_cholesky`; batched over leading axes):
    pi = pseudo_inertia^-1(U U^T), d(U U^T) = dU U^T + U dU^T.

    Parameters
    ----------
    theta : (..., 10) array

    Returns
    -------
    pi : (..., 10) array
    dpi : (..., 10, 10) array
    """
    th = np.asarray(theta, dtype=float)
    lead = th.shape[:-1]
    th = th.reshape(-1, 10)
    e = np.exp(np.minimum(th[:, :4], 300.0))           # a trial step far out stays finite
    ea = e[:, 0]
    U = np.zeros((len(th), 4, 4))
    U[:, 0, 0], U[:, 1, 1], U[:, 2, 2], U[:, 3, 3] = e[:, 1], e[:, 2], e[:, 3], 1.0
    for k, (i, j) in enumerate(_OFF_DIAGONAL, start=4):
        U[:, i, j] = th[:, k]
    U *= ea[:, None, None]
    dU = np.zeros((len(th), 10, 4, 4))
    dU[:, 0] = U
    for k in range(3):
        dU[:, k + 1, k, k] = U[:, k, k]
    for k, (i, j) in enumerate(_OFF_DIAGONAL, start=4):
        dU[:, k, i, j] = ea
    Ut = np.swapaxes(U, -1, -2)
    dJ = dU @ Ut[:, None] + U[:, None] @ np.swapaxes(dU, -1, -2)
    pi = _from_pseudo(U @ Ut)
    dpi = np.swapaxes(_from_pseudo(dJ), -1, -2)
    return pi.reshape(*lead, 10), dpi.reshape(*lead, 10, 10)


_OFF_DIAGONAL = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))     # s12, s23, s13, t1, t2, t3


def inertial_to_urdf(pi):
    """(mass, com (3,), inertia about the com (3, 3)) of 10 parameters ``pi`` about a frame's
    origin: c = h/m, I_c = I - m (|c|^2 1 - c c^T) (parallel axis theorem)."""
    m = float(pi[0])
    c = np.asarray(pi[1:4], dtype=float) / m
    I = _inertia_matrix(pi[4:]) - m * (c @ c * np.eye(3) - np.outer(c, c))
    return m, c, 0.5 * (I + I.T)


def urdf_to_inertial(mass, com, inertia_com):
    """10 parameters about the frame's origin of a body of ``mass`` (kg) at ``com`` (3,) (m)
    with inertia ``inertia_com`` (3, 3) about its centre of mass: the inverse of
    :func:`inertial_to_urdf`."""
    c = np.asarray(com, dtype=float)
    I = np.asarray(inertia_com, dtype=float) + mass * (c @ c * np.eye(3) - np.outer(c, c))
    return np.concatenate([[mass], mass * c, _inertia_entries(I)])


def _rpy_matrix(r, p, y):
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _link_inertial(link):
    """10 parameters of a URDF <link>'s <inertial> about the link frame (zeros without one)."""
    e = link.find("inertial")
    if e is None:
        return np.zeros(10)
    o = e.find("origin")
    xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
    m = float(e.find("mass").get("value"))
    i = e.find("inertia")
    Ic = _inertia_matrix([float(i.get(k)) for k in ("ixx", "ixy", "iyy", "ixz", "iyz", "izz")])
    R = _rpy_matrix(*rpy)
    return urdf_to_inertial(m, xyz, R @ Ic @ R.T)


# =============================================================================================
# base parameters
# =============================================================================================
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
    condition number small), QR where the Gram matrix is singular in double precision."""
    if M.shape[0] <= M.shape[1]:
        return M
    try:
        return np.linalg.cholesky(M.T @ M).T
    except np.linalg.LinAlgError:
        return np.linalg.qr(M, mode="r")


def _std(M, G):
    """(std of G z where z has information M^T M (M: rows x k), inf along unexcited directions;
    cond M)."""
    _, sv, Vt = np.linalg.svd(_tri(M))
    ok = sv > 1e-7 * (sv[0] if sv.size else 1.0)     # R may come from the Gram matrix: sqrt(eps)
    C = G @ Vt.T
    var = np.sum((C[:, ok] / sv[ok]) ** 2, axis=1)
    lost = np.any(np.abs(C[:, ~ok]) > 1e-8 * (1.0 + np.abs(C).max(axis=1, keepdims=True)), axis=1)
    return np.where(lost, np.inf, np.sqrt(var)), (sv[0] / sv[-1] if sv.size and sv[-1] > 0 else np.inf)


# =============================================================================================
# the robot as pinocchio sees it, with its URDF
# =============================================================================================
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
        self.width_candidates = None         # held-out RMS per width, when identify() selects it
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

    def regressor(self, q, v, a):
        """(N, n, 13 n): pinocchio's joint torque regressor of (N, n) ``q, v, a`` and the
        friction columns of (1)."""
        N, n = len(q), self.n
        Y = np.zeros((N, n, self.p))
        Q = self.pin_configurations(q)
        reg = self.pin.computeJointTorqueRegressor
        for k in range(N):
            Y[k, :, :10 * n] = reg(self.model, self.data, Q[k], v[k], a[k])
        i = np.arange(n)
        Y[:, i, 10 * n + i] = v
        Y[:, i, 11 * n + i] = np.tanh(v / self.width)
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
        for i in range(1, n + 1):
            Y = model.inertias[i]
            m = float(Y.mass)
            ell = [np.linalg.norm(Y.lever), math.sqrt(max(np.linalg.eigvalsh(Y.inertia)[-1], 0.0) / m), 0.01]
            ell += [np.linalg.norm(model.jointPlacements[k].translation)
                    for k in range(1, model.njoints) if model.parents[k] == i]
            ell = max(ell)
            s[10 * (i - 1):10 * i] = [m] + [m * ell] * 3 + [m * ell ** 2] * 6
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
        # the prior's unit: the scale, but for friction and offset the joint's effort limit where
        # the URDF gives one (it knows nothing of a real joint's friction: at the rigid-body
        # torque scale the prior held kinova's wrist roll's Coulomb friction at 0.03 N m against
        # the plant's 0.51, its torque scale being 1.2e-3 N m)
        effort = np.asarray(model.effortLimit, float)[[j.idx_v for j in model.joints[1:]]]
        effort = np.where(np.isfinite(effort) & (effort > 0), effort, 0.0)
        self.prior_scale = s.copy()
        for k in range(3):
            f = slice(10 * n + k * n, 10 * n + (k + 1) * n)
            self.prior_scale[f] = np.maximum(s[f], effort / (self.v_limit if k == 0 else 1.0))
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


# =============================================================================================
# identification
# =============================================================================================
def _log_arrays(recording, joint_names):
    """(t, q, tau) of a recording in the robot's joint order."""
    names = list(getattr(recording, "joint_names", []) or [])
    missing = [j for j in joint_names if j not in names]
    if missing:
        raise ValueError(f"recording: no columns for joints {', '.join(missing)} of the robot "
                         f"(the recording has {', '.join(names) or 'none'})")
    idx = [names.index(j) for j in joint_names]
    t = np.asarray(recording.t, dtype=float).ravel()
    q = np.asarray(recording.q, dtype=float).reshape(len(t), -1)
    tau = np.asarray(recording.tau, dtype=float).reshape(len(t), -1)
    if q.shape[1] != len(names) or tau.shape[1] != len(names):
        raise ValueError(f"recording: q and tau need {len(names)} columns, got {q.shape[1]} and {tau.shape[1]}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(tau))):
        raise ValueError("recording: NaN or Inf in q or tau")
    return t, q[:, idx], tau[:, idx]


def _progress(progress, desc, total=None):
    from ..core.progress import bar
    return bar(total=total, desc=desc, file=sys.stderr, disable=not progress, leave=False, dynamic_ncols=True)


class Identification:
    """The identified model of a robot and how well the log determines it.

    Attributes
    ----------
    x : (13 n,) array
        Parameters of (1): 10 per body (about the joint frame), then f_v, f_c, f_o.
    std : (13 n,) array
        Their standard deviation from data and prior (linearised weighted least squares).
    std_data : (13 n,) array
        From the log alone (inf: the log cannot determine the parameter on its own).
    report : dict
        Everything of ``text`` as JSON-able data.
    text : str
        A readable report.
    """

    def __init__(self, arm, x, report):
        self.arm, self.x, self.report = arm, x, report
        self.std = np.array([p["std"] for p in report["parameters"]])
        self.std_data = np.array([p["std_data"] for p in report["parameters"]])

    @property
    def friction(self):
        """{"viscous", "coulomb", "offset"} -> (n,) array of the identified friction."""
        return dict(zip(FRICTION, (np.array(v) for v in self.arm.friction_value(self.x))))

    @property
    def text(self):
        """The readable report (:func:`report_text`)."""
        return report_text(self.report)

    def urdf(self):
        """The original URDF text with each primary link's identified <inertial> (mass, origin
        xyz = centre of mass, inertia about it) and <dynamics damping=f_v friction=f_c> on each
        identified joint; locked joints and everything else as they were."""
        arm, n = self.arm, self.arm.n
        tree = copy.deepcopy(arm.tree)
        root = tree.getroot()
        links = {e.get("name"): e for e in root.findall("link")}
        joints = {e.get("name"): e for e in root.findall("joint")}
        fv, fc, _ = arm.friction_value(self.x)
        num = lambda v: repr(float(v))  # noqa: E731  (shortest round-trip decimal)
        for i in range(n):
            pi = self.x[10 * i:10 * i + 10] - arm.attached[10 * i:10 * i + 10]
            m, c, Ic = inertial_to_urdf(pi)
            link = links[arm.links[i]]
            old = link.find("inertial")
            pos = list(link).index(old) if old is not None else 0
            if old is not None:
                link.remove(old)
            e = ET.Element("inertial")
            e.text, e.tail = "\n      ", (old.tail if old is not None else "\n    ")
            ET.SubElement(e, "origin", xyz=" ".join(num(v) for v in c), rpy="0 0 0").tail = "\n      "
            ET.SubElement(e, "mass", value=num(m)).tail = "\n      "
            ET.SubElement(e, "inertia", ixx=num(Ic[0, 0]), ixy=num(Ic[0, 1]), ixz=num(Ic[0, 2]),
                          iyy=num(Ic[1, 1]), iyz=num(Ic[1, 2]), izz=num(Ic[2, 2])).tail = "\n    "
            link.insert(pos, e)
            j = joints[arm.joint_names[i]]
            dyn = j.find("dynamics")
            if dyn is None:
                last = list(j)[-1] if len(j) else None
                dyn = ET.SubElement(j, "dynamics")
                if last is not None:                       # indented like its siblings
                    dyn.tail, last.tail = last.tail, (last.tail or "") + "  "
            dyn.set("damping", num(fv[i]))
            dyn.set("friction", num(fc[i]))
        note = ET.Comment(f" <inertial> of {', '.join(arm.links)} and <dynamics> of {', '.join(arm.joint_names)} "
                          f"identified by observer-codegen (codegen.logs.identify); Coulomb width and "
                          f"offsets in {arm.name}_identified.friction.json ".replace("--", "- -"))
        note.tail = root.text
        root.insert(0, note)
        buf = io.BytesIO()
        ET.ElementTree(root).write(buf, encoding="utf-8", xml_declaration=True)
        return buf.getvalue().decode("utf-8") + "\n"

    def friction_file(self):
        """The side file of what URDF has no tag for (dict): ``{"format": "observer-codegen
        friction 1", "coulomb_width": w, "offset": {joint: f_o}}`` (models.urdf reads it beside
        the URDF)."""
        from models.urdf import FRICTION_FORMAT
        _, _, fo = self.arm.friction_value(self.x)
        return {"format": FRICTION_FORMAT, "coulomb_width": self.arm.width,
                "offset": {j: float(v) for j, v in zip(self.arm.joint_names, fo)}}

    def write(self, out):
        """Write ``out/<robot>_identified.urdf``, ``out/<robot>_identified.friction.json``,
        ``out/report.json`` and ``out/report.txt`` (each through a temporary file; the URDF is
        checked first: pinocchio parses it back to the identified bodies).

        Parameters
        ----------
        out : path of the folder (created)

        Returns
        -------
        dict
            kind ("urdf", "friction", "report_json", "report_txt") -> Path.
        """
        arm = self.arm
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"urdf": out / f"{arm.name}_identified.urdf",
                 "friction": out / f"{arm.name}_identified.friction.json",
                 "report_json": out / "report.json", "report_txt": out / "report.txt"}
        report = dict(self.report, files={k: str(v) for k, v in paths.items()})
        texts = {"urdf": self.urdf(), "friction": json.dumps(self.friction_file(), indent=2) + "\n",
                 "report_json": json.dumps(_jsonable(report), indent=2) + "\n",
                 "report_txt": report_text(report)}
        tmp = {k: p.with_name(f".{p.name}.tmp") for k, p in paths.items()}
        try:
            for k, p in tmp.items():
                p.write_text(texts[k])
            self._check_urdf(tmp["urdf"])
            for k, p in tmp.items():
                os.replace(p, paths[k])
        finally:
            for p in tmp.values():
                p.unlink(missing_ok=True)
        self.report = report
        return paths

    def _check_urdf(self, path):
        """The written URDF, reduced like the robot, gives the identified bodies and friction."""
        from codegen.reference.robots.urdf import UrdfRobot
        arm = self.arm
        model = UrdfRobot(path, None, arm.locked, arm.snap_tol).model
        pi = np.concatenate([model.inertias[i].toDynamicParameters() for i in range(1, arm.n + 1)])
        # the robot's model snapped URDF round-off (|x| < snap_tol -> 0) in the other links' values
        err = np.abs(pi - self.x[:10 * arm.n]) / (1e-9 * arm.scale[:10 * arm.n] + 10 * arm.snap_tol)
        fv, fc, _ = arm.friction_value(self.x)
        if err.max() > 1 or not (np.allclose(model.damping, fv) and np.allclose(model.friction, fc)):
            raise RuntimeError(f"{path}: the written URDF does not reproduce the identified model "
                               f"(largest parameter error {err.max():.3g} x its tolerance)")


def _jsonable(v):
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else ("inf" if f > 0 else "-inf" if f < 0 else "nan")
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    return v


def identify(recording, robot, *, cutoff=None, test_fraction=DEFAULT_TEST_FRACTION,
             coulomb_width="auto", prior=DEFAULT_PRIOR, max_rel_std=DEFAULT_MAX_REL_STD,
             v_stick=DEFAULT_V_STICK, progress=False, out=None):
    """Identify the inertial parameters and the friction (1) of a URDF robot from a log.

    Parameters
    ----------
    recording : codegen.logs.recording.Recording
        ``t`` (N,) increasing time stamps (jitter and gaps allowed), ``q`` (N, n) positions,
        ``tau`` (N, n) measured joint torques, ``joint_names`` (all of the robot's; any order).
        ``qd`` is not used.
    robot : models.RobotModel
        A URDF robot (``load_robot(urdf=..., locked_joints=...)``, ``ur5``, ``panda``): the
        starting point and prior; its ``source`` says how pinocchio rebuilds it.
    cutoff : float, optional
        Hz, of the zero-phase low-pass that gives qd, qdd and the filtered tau; default chosen on
        the log (``identification_cutoff``).
    test_fraction : float
        The last fraction of the log's duration, held out for the residual (0 < f < 1).
    coulomb_width : float or "auto" or None
        w of tanh(qd/w) (rad/s). "auto" (default): of ``WIDTHS`` and the robot's own, the one
        whose least-squares fit (unconstrained, on the training samples) leaves the smallest
        held-out residual, sum over joints of (RMS / the smallest RMS any width leaves)^2: a
        real joint's dry friction switches faster than any one width assumes (MuJoCo's
        frictionloss on the real ur5: 0.01 rad/s is chosen and the friction found is within
        3.6 % of the plant's; at the models' 0.2 it was 2-52 % off). None: the robot's
        ``coulomb_width`` if it has one, else ``DEFAULT_COULOMB_WIDTH``.
    prior : float
        Relative std of the URDF's values as a prior (in units of each parameter's scale; of the
        joint's effort limit for friction and offset).
    v_stick : float
        rad/s: a joint's rows where its smoothed velocity is at most this are left out of the fit
        (a joint stuck by dry friction holds an unknown torque); 0 keeps every row.
    max_rel_std : float
        Refuse the log when a base parameter's relative std from the log (module docstring, 3:
        the torque uncertainty it leaves on random states, in units of the joint's RMS torque)
        exceeds this.
    progress : bool
        A tqdm bar on stderr over the solver iterations.
    out : path, optional
        Also write the files of :meth:`Identification.write` there.

    Returns
    -------
    Identification

    Raises
    ------
    IdentificationError
        The log does not excite some parameters (message: the joints, and the remedy).
    """
    from scipy.optimize import least_squares
    arm = _Arm(robot, coulomb_width)
    n, p, s = arm.n, arm.p, arm.scale
    t, q, tau = _log_arrays(recording, arm.joint_names)
    if cutoff is None:
        cutoff = identification_cutoff(t, q)
    tf = float(test_fraction)
    if not 0.0 < tf < 1.0:
        raise ValueError(f"test_fraction: expected a number in (0, 1), got {test_fraction!r}")
    for name, v in (("prior", prior), ("max_rel_std", max_rel_std), ("cutoff", cutoff)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name}: expected a positive number, got {v!r}")
    if not (isinstance(v_stick, (int, float)) and math.isfinite(v_stick) and v_stick >= 0):
        raise ValueError(f"v_stick: expected a velocity >= 0 (rad/s), got {v_stick!r}")
    bar = _progress(progress, f"identify {arm.name}")
    bar.set_postfix_str("smoothing")
    d = derivatives(t, q, cutoff)
    h = float(np.median(np.diff(t)))
    wide = min(WIDE * cutoff, 0.25 / h)
    dw = derivatives(t, q, wide)
    tau_f = lowpass(t, tau, cutoff)
    # a joint's row of a sample where its smoothed velocity is below v_stick is left out of the
    # fit: a joint at rest under dry friction holds any torque up to its Coulomb friction, which
    # (1) cannot say (on the real kinova it biased the viscous friction of the shoulder and the
    # elbow 47 % and 14 %, with the rows left out 5 % and 7 %)
    sliding = (np.abs(d.qd) > v_stick).astype(float)
    edge = 2.0 / cutoff + 2.0 / wide
    valid = (t >= t[0] + edge) & (t <= t[-1] - edge)
    t_split = t[0] + (1.0 - tf) * (t[-1] - t[0])
    train = valid & (t < t_split)
    test = valid & (t >= t_split)
    if train.sum() < 2 * p or test.sum() < 10:
        raise ValueError(f"recording: too short: {train.sum()} training and {test.sum()} test samples "
                         f"away from the filter's edges (need {2 * p} and 10)")
    bar.set_postfix_str("regressor")
    # the least squares on every D-th training sample: below the cut-off nothing is lost at a
    # step of 1/(FIT_RATE cutoff); weights x sqrt(D) keep the covariance that of all samples
    tr_idx = np.nonzero(train)[0]
    D = max(1, int(1.0 / (FIT_RATE * cutoff * h)))
    fit = tr_idx[::D]
    wD = math.sqrt(len(tr_idx) / len(fit))
    rows = arm.regressor(d.q[fit], d.qd[fit], d.qdd[fit])
    # parallel filtering: the Coulomb column, not smooth where qd changes sign, is tanh of the
    # wide-band velocity through the same filter as tau (the other columns are smooth functions
    # of the smoothed states: filtering them again changes nothing, measured to 1e-4)
    i = np.arange(n)
    base_rows = rows
    tau_fit = tau_f[fit]

    def with_width(w):
        """The fit's rows (columns in scaled units x~ = x / s) at Coulomb width ``w``, which
        becomes ``arm.width`` (what ``predict`` and the written files use)."""
        arm.width = float(w)
        r = base_rows.copy()
        r[:, i, 11 * n + i] = lowpass(t, np.tanh(dw.qd / w), cutoff)[fit]
        return r * s

    def predict(X, mask):
        """(samples of ``mask``, n, k): the torques of (1) with parameters X (p, k) at the
        smoothed states (the regressor in chunks: a long log is never held whole)."""
        idx = np.nonzero(mask)[0]
        out = np.empty((len(idx), n, X.shape[1]))
        for k in range(0, len(idx), CHUNK):
            j = idx[k:k + CHUNK]
            out[k:k + CHUNK] = arm.regressor(d.q[j], d.qd[j], d.qdd[j]) @ X
        return out

    def noise(x):
        """RMS per joint of the measured (unfiltered) torque less the model's, training samples."""
        return np.maximum(_rms(tau[train] - predict(x[:, None], train)[..., 0]), 1e-9 * arm.torque_scale)

    def compress(w):
        """(R, c): sum over all training samples of |diag(w) (A_fit x - tau_f)|^2 (a joint's rows
        where it sticks left out), from every D-th one weighted sqrt(D), = |R x~ - c|^2 + const."""
        w = w[None, :] * wD * sliding[fit]
        M = np.column_stack([(rows * w[:, :, None]).reshape(-1, p), (tau_fit * w).ravel()])
        Rb = _tri(M)
        return Rb[:p, :p], Rb[:p, p]

    def ols(R, c):
        """x of the unconstrained least squares of the base parameters (dependent ones 0)."""
        x = np.zeros(p)
        x[arm.indep] = np.linalg.lstsq(R[:, arm.indep], c, rcond=None)[0] * s[arm.indep]
        return x

    if isinstance(coulomb_width, str):
        if coulomb_width != "auto":
            raise ValueError(f"coulomb_width: expected a positive number (rad/s) or 'auto', got {coulomb_width!r}")
        bar.set_postfix_str("Coulomb width")
        widths = sorted({*WIDTHS, *([float(arm.robot_width)] if arm.robot_width else [])}, reverse=True)
        held_out = []
        for w in widths:
            rows = with_width(w)
            x0 = ols(*compress(1.0 / arm.torque_scale))
            held_out.append(_rms(tau[test] - predict(x0[:, None], test)[..., 0]))
        held_out = np.array(held_out)
        score = np.sum((held_out / held_out.min(axis=0)) ** 2, axis=1)
        best = int(np.argmin(score))
        arm.width_source = (f"selected by the held-out residual of the unconstrained fit from "
                            f"{', '.join(f'{w:g}' for w in widths)} rad/s")
        arm.width_candidates = {f"{w:g}": {j: float(r) for j, r in zip(arm.joint_names, res)}
                                for w, res in zip(widths, held_out)}
        rows = with_width(widths[best])
    else:
        rows = with_width(arm.width)

    # round 0: weights from the torque scales; its residual is the first noise estimate
    R0, c0 = compress(1.0 / arm.torque_scale)
    cond = float(np.linalg.cond(_tri(R0[:, arm.indep])))
    sigma = noise(ols(R0, c0))

    # what the log determines: std of the base parameters from the log alone, scaled, as the
    # torque uncertainty each leaves (arm.effect: against the torque or the noise, the larger)
    R, c = compress(1.0 / sigma)
    std_beta, _ = _std(R @ arm.rowspace, arm.T @ arm.rowspace)
    effect = arm.effect(sigma)
    rel = std_beta * effect[arm.indep]
    poor = np.nonzero(~(rel <= max_rel_std))[0]
    if len(poor):
        raise IdentificationError(_refusal(arm, poor, rel, max_rel_std, d, train))

    # physically consistent estimate, in scaled units x~ = x / s: each primary link's scaled
    # parameters in log-Cholesky coordinates (J~ = D^-1 J D^-1, D = sqrt(m) diag(l, l, l, 1) of
    # the body's scales: dimensionless, O(1)), friction f / s with f_v, f_c >= 0
    att = arm.attached / s[:10 * n]
    lb = np.concatenate([np.full(10 * n, -np.inf), np.zeros(2 * n), np.full(n, -np.inf)])
    x_prior = arm.x_urdf / s
    wp = s / (prior * arm.prior_scale)    # 1 / the prior's std, scaled units

    def assemble(z):
        """(x~, d x~ / d z) of the solver's variables z."""
        x, D = np.empty(p), np.zeros((p, p))
        pi, dpi = from_log_cholesky(z[:10 * n].reshape(n, 10))
        x[:10 * n] = att + pi.ravel()
        for i in range(n):
            D[10 * i:10 * i + 10, 10 * i:10 * i + 10] = dpi[i]
        x[10 * n:] = z[10 * n:]
        D[10 * n:, 10 * n:] = np.eye(3 * n)
        return x, D

    # |R x~ - c|^2 + |wp (x~ - x~_prior)|^2 = |Rp x~ - cp|^2 + const: one square system,
    # Rp^T Rp = R^T R + diag(wp^2) (Cholesky), cp = Rp^-T (R^T c + wp^2 x~_prior)
    def fun(z):
        return Rp @ assemble(z)[0] - cp

    def jac(z):
        bar.update(1)
        return Rp @ assemble(z)[1]

    z, rounds = None, []
    for rnd in range(2):                   # solve, re-estimate the noise, solve again
        # the same problem without the constraints is linear: its solution, each pseudo-inertia
        # clipped into the cone and friction to >= 0, starts the solver; the solver's cost is
        # the full one less the unconstrained minimum (the price of consistency), and it stops
        # when a step lowers that by less than FTOL of it
        Rp = np.linalg.cholesky(R.T @ R + np.diag(wp ** 2)).T
        cp = np.linalg.solve(Rp.T, R.T @ c + wp ** 2 * x_prior)
        x_lin = np.linalg.solve(Rp, cp)
        cost_lin = 0.5 * float(np.sum((R @ x_lin - c) ** 2) + np.sum((wp * (x_lin - x_prior)) ** 2))
        if z is None:
            z = np.concatenate([np.concatenate([_start_theta(x_lin[10 * i:10 * i + 10] - att[10 * i:10 * i + 10])
                                                for i in range(n)]), x_lin[10 * n:]])
            z[10 * n:12 * n] = np.maximum(z[10 * n:12 * n], 0.0)
        bar.set_postfix_str(f"solve {rnd + 1}/2")
        result = least_squares(fun, z, jac=jac, bounds=(lb, np.inf), method="trf", x_scale=1.0,
                               ftol=FTOL, xtol=1e-12, gtol=1e-12, max_nfev=MAX_NFEV)
        result.cost += cost_lin
        z = result.x
        rounds.append({"nfev": int(result.nfev), "status": int(result.status), "message": str(result.message),
                       "cost": float(result.cost), "cost_unconstrained": cost_lin})
        x = assemble(z)[0] * s
        sigma = noise(x)
        R, c = compress(1.0 / sigma)
    bar.close()

    # covariances at the final weights: every parameter (data + prior), from the log alone,
    # and the base parameters
    std_post = np.sqrt(np.diag(np.linalg.inv(R.T @ R + np.diag(wp ** 2)))) * s
    alone = np.linalg.norm(arm.rowspace, axis=1) > 1 - 1e-8     # e_i in the row space
    G = np.zeros((p, arm.rowspace.shape[1]))
    G[alone] = arm.rowspace[alone]
    std_data, _ = _std(R @ arm.rowspace, G)
    std_data = np.where(alone, std_data * s, np.inf)
    std_beta, _ = _std(R @ arm.rowspace, arm.T @ arm.rowspace)
    x_ols = ols(R, c)                      # the unconstrained optimum, for comparison

    pred = predict(np.column_stack([np.r_[arm.pi_urdf, np.zeros(3 * n)], x, x_ols]), test)
    residual = {"before": _rms(tau[test] - pred[..., 0]), "after": _rms(tau[test] - pred[..., 1]),
                "after_unconstrained": _rms(tau[test] - pred[..., 2]), "train_after": sigma}
    report = _report(arm, effect, t, t_split, train, test, x, residual, sigma, std_post, std_data, std_beta,
                     cond, cutoff, wide, D, tf, prior, max_rel_std, rounds, v_stick,
                     1.0 - sliding[train].mean(axis=0))
    ident = Identification(arm, x, report)
    if out is not None:
        ident.write(out)
    return ident


def identification_cutoff(t, q):
    """The zero-phase cut-off (Hz) identification fits on, from the log's measured spectrum
    (codegen.logs.noise): BAND_MARGIN x the highest joint's motion band, where the order-4
    forward-backward filter leaves the band's motion untouched to (1 / BAND_MARGIN)^8 = 1.5e-5 (the
    regression's nonlinear terms, g(q) and C(q, v) v, are filtered after they are formed: a filter
    that bites into the motion biases them, where noise only adds variance), and at least the cut-off
    of the least predicted acceleration error (``noise.reference_cutoff`` with ``derivative=2``),
    over the joints that move (a range of more than ten noise levels), below 0.45 x the Nyquist
    frequency. ``t`` (N,) s, ``q`` (N, n) rad."""
    from .noise import measure, reference_cutoff
    nz = measure(t, q)
    moving = np.ptp(q, axis=0) > 10 * np.maximum(nz.sigma, nz.resolution)
    if not moving.any():
        moving[:] = True
    cut = max(BAND_MARGIN * np.max(nz.band[moving]), np.median(reference_cutoff(nz, derivative=2)[moving]))
    return float(min(cut, 0.45 * 0.5 / nz.dt))


def lowpass(t, y, cutoff):
    """y (N, k) through the zero-phase low-pass of ``codegen.logs.smoothing.derivatives``
    at ``cutoff`` Hz (cubic to the uniform grid of the median step of ``t`` (N,), 4th-order
    Butterworth forward and backward, cubic back), in blocks of columns."""
    y = np.asarray(y, dtype=float)
    flat = y.reshape(len(t), -1)
    out = np.empty_like(flat)
    for k in range(0, flat.shape[1], 64):
        out[:, k:k + 64] = derivatives(t, flat[:, k:k + 64], cutoff).q
    return out.reshape(y.shape)


def _rms(e):
    return np.sqrt(np.mean(e ** 2, axis=0))


def _start_theta(pi):
    """Log-Cholesky coordinates of scaled parameters ``pi`` (10,) clipped into the cone: the
    pseudo-inertia's eigenvalues raised to at least 1e-6 (a point mass, a thin rod, a link without
    <inertial>, an unconstrained estimate outside the cone)."""
    lam, V = np.linalg.eigh(pseudo_inertia(pi))
    return log_cholesky(_from_pseudo((V * np.maximum(lam, 1e-6)) @ V.T))


def _refusal(arm, poor, std_beta, bound, d, train):
    """The message of a log that leaves base parameters ``poor`` undetermined: the joints that do
    not move (RMS speed below STILL of the velocity limit), else those whose parameters lead the
    undetermined combinations, with their motion, and what to do."""
    from models import names
    speed = _rms(d.qd[train])
    still = [j for j in range(arm.n) if speed[j] < STILL * arm.v_limit[j]]
    joints = still or sorted({int(arm.owner[arm.indep[k]]) for k in poor})
    motion = ", ".join(f"{arm.joint_names[j]} moves over {np.ptp(d.q[train, j]):.3g} rad at "
                       f"{speed[j]:.3g} rad/s RMS" for j in joints)
    worst = sorted(poor, key=lambda k: -std_beta[k])[:3]
    which = "; ".join(f"{arm.combination(k, 3)}: {std_beta[k]:.3g}" for k in worst)
    src = (f"--robot {arm.name}" if arm.name in names() else
           f"--urdf {arm.path}" + "".join(f" --lock {k}={v:g}" for k, v in arm.locked.items()))
    names_ = ", ".join(arm.joint_names[j] for j in joints)
    what = (f"joint{'s' if len(joints) > 1 else ''} {names_} do{'es' if len(joints) == 1 else ''} not move"
            if still else f"the motion of joint{'s' if len(joints) > 1 else ''} {names_} does not excite them enough")
    # a std falls as 1/sqrt(samples): how many more samples of the same motion (a longer log, or
    # the same one at a higher rate: a log at 200 Hz needs 5 x the duration of one at 1 kHz)
    longer = float(np.max(std_beta[poor]) / bound) ** 2
    duration = float(np.ptp(d.t[train]))
    rate = float(np.count_nonzero(train)) / duration
    excite = f"python -m codegen excite {src} --out traj.csv"
    accept = (f"accept the worst at {np.max(std_beta[poor]):.2g} "
              f"(--max-rel-std {np.max(std_beta[poor]) * 1.01:.2g})")
    head = (f"recording: the log does not determine the model: {len(poor)} of {len(arm.indep)} identifiable "
            f"parameter combinations have a relative std above {bound:g} ({which}"
            f"{'; ...' if len(poor) > len(worst) else ''}); {what} ({motion}). ")
    if still:
        return (head + f"Record a log along an excitation trajectory ({excite}) and identify on it, or lock a "
                f"joint that cannot move (--lock JOINT=VALUE)")
    return (head + f"Record {longer:.2g} x the samples of the same motion ({longer * duration:.3g} s at this "
            f"log's {rate:.3g} samples/s, or {duration:.3g} s at {longer * rate:.3g} samples/s), or a log "
            f"along an excitation trajectory if this one is not ({excite}), or {accept}")


def _report(arm, effect, t, t_split, train, test, x, residual, sigma, std_post, std_data, std_beta, cond,
            cutoff, wide, decimation, tf, prior, max_rel_std, rounds, v_stick, stuck):
    J = arm.joint_names
    per = lambda v: {j: float(a) for j, a in zip(J, v)}  # noqa: E731
    fv, fc, fo = arm.friction_value(x)
    sv, sc, so = arm.friction_value(std_post)
    bodies = {}
    for i, link in enumerate(arm.links):
        m, c, Ic = inertial_to_urdf(x[10 * i:10 * i + 10] - arm.attached[10 * i:10 * i + 10])
        m0, c0, _ = inertial_to_urdf(arm.primary_urdf[10 * i:10 * i + 10]) if arm.primary_urdf[10 * i] > 0 \
            else (0.0, np.zeros(3), None)
        bodies[link] = {"joint": J[i], "mass": m, "mass_urdf": m0, "com": c.tolist(), "com_urdf": c0.tolist(),
                        "inertia_com": Ic.tolist(),
                        "pseudo_inertia_min_eigenvalue": float(np.linalg.eigvalsh(
                            pseudo_inertia(x[10 * i:10 * i + 10]))[0])}
    beta = (arm.T @ (x / arm.scale)) * arm.scale[arm.indep]
    with np.errstate(invalid="ignore"):
        rel_data = np.where(np.isfinite(std_data), std_data / arm.scale * effect, np.inf)
    return {
        "robot": arm.name, "urdf": str(arm.path), "locked_joints": arm.locked, "joints": J,
        "model": "tau = Y(q, qd, qdd) pi + f_v qd + f_c tanh(qd / w) + f_o",
        "log": {"samples": len(t), "duration_s": float(t[-1] - t[0]),
                "median_step_s": float(np.median(np.diff(t))), "cutoff_hz": float(cutoff),
                "coulomb_column_cutoff_hz": float(wide), "fit_every": int(decimation),
                "train_samples": int(train.sum()), "test_samples": int(test.sum()),
                "test_from_s": float(t_split), "test_fraction": tf, "v_stick": float(v_stick),
                "stuck_fraction": per(stuck)},
        "coulomb_width": arm.width, "coulomb_width_source": arm.width_source,
        **({"coulomb_width_held_out_rms": arm.width_candidates} if arm.width_candidates else {}),
        "noise_std": per(sigma),
        "residual_rms": {k: per(v) for k, v in residual.items()},
        "condition_number": cond,
        "condition_number_definition": "base regressor on the training samples, columns in units of "
                                       "the parameter scales, rows in units of the joint torque scales",
        "prior": prior, "max_rel_std": max_rel_std,
        "solver": rounds,
        "base_parameters": [{"combination": arm.combination(k), "value": float(beta[k]),
                             "std": float(std_beta[k] * arm.scale[arm.indep[k]]),
                             "relative_std": float(std_beta[k] * effect[arm.indep[k]])}
                            for k in range(len(arm.indep))],
        "parameters": [{"name": arm.names[i], "joint": J[arm.owner[i]], "urdf": float(arm.x_urdf[i]),
                        "value": float(x[i]), "std": float(std_post[i]), "std_data": float(std_data[i]),
                        "scale": float(arm.scale[i]),
                        "relative_std": float(rel_data[i]), "identifiable": bool(rel_data[i] <= max_rel_std)}
                       for i in range(arm.p)],
        "friction": {j: {"viscous": float(fv[k]), "viscous_std": float(sv[k]), "coulomb": float(fc[k]),
                         "coulomb_std": float(sc[k]), "offset": float(fo[k]), "offset_std": float(so[k])}
                     for k, j in enumerate(J)},
        "links": bodies,
    }


def report_text(report):
    """A readable text of an identification report dict (:class:`Identification`.report)."""
    J = report["joints"]
    lines = [f"identification of {report['robot']} ({report['urdf']})",
             f"model: {report['model']}, w = {report['coulomb_width']:g} rad/s ({report['coulomb_width_source']})"]
    if report["locked_joints"]:
        lines.append("locked joints (kept as they were): " + ", ".join(f"{k} = {v:g}" for k, v in
                                                                       report["locked_joints"].items()))
    lg = report["log"]
    lines += [f"log: {lg['samples']} samples over {lg['duration_s']:.3f} s (median step {lg['median_step_s'] * 1e3:.3f} ms), "
              f"zero-phase cut-off {lg['cutoff_hz']:g} Hz; trained on {lg['train_samples']}, held out "
              f"{lg['test_samples']} from t = {lg['test_from_s']:.3f} s",
              f"left out of the fit where a joint sticks (|qd| <= {lg['v_stick']:g} rad/s): "
              + ", ".join(f"{j} {100 * lg['stuck_fraction'][j]:.1f} %" for j in J),
              f"condition number of the base regressor: {report['condition_number']:.4g} "
              f"({len(report['base_parameters'])} base parameters)", "",
              "held-out torque residual RMS (N m or N):",
              f"  {'joint':<24}{'noise std':>12}{'before':>12}{'after':>12}"]
    r = report["residual_rms"]
    for j in J:
        lines.append(f"  {j:<24}{report['noise_std'][j]:>12.4g}{r['before'][j]:>12.4g}{r['after'][j]:>12.4g}")
    lines += ["", "friction (value +- std):"]
    for j in J:
        f = report["friction"][j]
        lines.append(f"  {j:<24}viscous {f['viscous']:.4g} +- {f['viscous_std']:.2g}, coulomb "
                     f"{f['coulomb']:.4g} +- {f['coulomb_std']:.2g}, offset {f['offset']:.4g} +- {f['offset_std']:.2g}")
    lines += ["", "links (identified; URDF):"]
    for link, b in report["links"].items():
        lines.append(f"  {link:<24}mass {b['mass']:.4g} kg ({b['mass_urdf']:.4g}), com "
                     f"[{', '.join(f'{v:.4g}' for v in b['com'])}] m ([{', '.join(f'{v:.4g}' for v in b['com_urdf'])}])")
    lines += ["", f"identifiable combinations (relative std: the torque uncertainty it leaves on random "
                  f"states / the joint's RMS torque; refused above {report['max_rel_std']:g}):"]
    for b in report["base_parameters"]:
        lines.append(f"  {b['value']:>12.5g} +- {b['std']:<10.2g} ({b['relative_std']:.1e})  {b['combination']}")
    lines += ["", "parameters (value, std from log and prior, std from the log alone, URDF):"]
    for prm in report["parameters"]:
        sd = prm["std_data"]
        lines.append(f"  {prm['name']:<28}{prm['value']:>12.5g} +- {prm['std']:<10.2g}"
                     f"{('log alone +- ' + format(sd, '.2g')) if math.isfinite(sd) else 'not alone':<22}"
                     f"URDF {prm['urdf']:.5g}")
    if "files" in report:
        lines += ["", "files:"] + [f"  {v}" for v in report["files"].values()]
    return "\n".join(lines) + "\n"


# =============================================================================================
# excitation trajectory
# =============================================================================================
class Excitation:
    """A periodic Fourier-series trajectory per joint (Swevers et al. 1997),

        q_j(t) = q0_j + sum_l a_jl/(w l) sin(w l t) - b_jl/(w l) cos(w l t),   w = 2 pi f0,
        qd_j   = sum_l a_jl cos(w l t) + b_jl sin(w l t),
        qdd_j  = sum_l w l (b_jl cos(w l t) - a_jl sin(w l t)),

    at rest at t = 0 (sum_l a_jl = 0, sum_l l b_jl = 0) and so at every whole period.

    Attributes
    ----------
    joint_names : list of str
    f0 : float
        Base frequency (Hz).
    a, b : (n, L) arrays
        Coefficients (rad/s).
    q0 : (n,) array
    T : float
        Duration (s), a whole number of periods 1/f0.
    condition : float
        Condition number of the stacked base regressor along it (as in the identification report).
    """

    def __init__(self, joint_names, f0, a, b, q0, T, condition=math.nan):
        self.joint_names, self.f0, self.T, self.condition = list(joint_names), float(f0), float(T), condition
        self.a, self.b, self.q0 = np.asarray(a, float), np.asarray(b, float), np.asarray(q0, float)

    def at(self, t):
        """(q, qd, qdd), each (N, n), at times ``t`` (N,) s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        w = 2 * math.pi * self.f0
        wl = w * np.arange(1, self.a.shape[1] + 1)
        S, C = np.sin(np.outer(t, wl)), np.cos(np.outer(t, wl))
        q = self.q0 + S @ (self.a / wl).T - C @ (self.b / wl).T
        qd = C @ self.a.T + S @ self.b.T
        qdd = C @ (self.b * wl).T - S @ (self.a * wl).T
        return q, qd, qdd

    def sample(self, dt=1e-3):
        """(t, q, qd, qdd) on [0, T] every ``dt`` s."""
        t = dt * np.arange(int(round(self.T / dt)) + 1)
        return (t, *self.at(t))

    def write_csv(self, path, dt=1e-3):
        """The CSV a user plays on the robot: t, q_<joint>..., qd_<joint>..., qdd_<joint>...
        every ``dt`` s (to ``path``, atomically). Returns the path."""
        from codegen.core.columns import write_columns
        t, q, qd, qdd = self.sample(dt)
        cols = {"t": t}
        for g, a in (("q", q), ("qd", qd), ("qdd", qdd)):
            cols.update({f"{g}_{j}": a[:, k] for k, j in enumerate(self.joint_names)})
        return write_columns(path, cols)


class _Design:
    """The excitation design problem in y = (a (n, L), b (n, L), q0 (n)): minimise
    f = log cond W = log sigma_1(W) - log sigma_r(W), W = diag(1/tau_s) Y(q, qd, qdd) S_b stacked
    over a period's ``points`` instants, subject to linear constraints on a fine grid of the period
    (position within [lower, upper], |qd| <= vmax, |qdd| <= amax) and at rest at t = 0
    (sum_l a_l = 0, sum_l l b_l = 0).

    Gradient: d sigma_i = u_i^T dW v_i = sum_k w_ik^T d tau_k(x_i) with w_ik = u_ik / tau_s and
    x_i = S_b v_i, whose derivatives in q, qd, qdd are pinocchio's RNEA derivatives on a model
    with the (linear) parameters x_i (shifted by a consistent x0 and subtracted again, so that no
    body's mass is near 0) plus the friction's; then back through the series (linear in y)."""

    def __init__(self, arm, f0, L, lower, upper, vmax, amax, points):
        self.arm, self.L, self.n = arm, L, arm.n
        self.lower, self.upper, self.vmax, self.amax = lower, upper, vmax, amax
        self.wl = 2 * math.pi * f0 * np.arange(1, L + 1)
        self.fine = self.grid(np.linspace(0.0, 1.0 / f0, 40 * L + 1)[:-1])
        self.coarse = self.grid(np.linspace(0.0, 1.0 / f0, points + 1)[:-1])
        self.models = [arm.model.copy() for _ in range(3)]
        self.datas = [m.createData() for m in self.models]

    def grid(self, t):
        """(sin, cos) of the harmonics at times ``t``."""
        return np.sin(np.outer(t, self.wl)), np.cos(np.outer(t, self.wl))

    def split(self, y):
        """(a, b, q0) of the variables y."""
        n, L = self.n, self.L
        return y[:n * L].reshape(n, L), y[n * L:2 * n * L].reshape(n, L), y[2 * n * L:]

    def states(self, y, grid=None):
        """(q, qd, qdd) of y on ``grid`` (default the coarse one)."""
        a, b, q0 = self.split(y)
        S, C = grid or self.coarse
        wl = self.wl
        return (q0 + S @ (a / wl).T - C @ (b / wl).T, C @ a.T + S @ b.T,
                C @ (b * wl).T - S @ (a * wl).T)

    def constraints(self):
        """scipy LinearConstraints: limits on the fine grid, at rest at t = 0."""
        from scipy.optimize import LinearConstraint
        from scipy.sparse import lil_matrix
        n, L, wl = self.n, self.L, self.wl
        S, C = self.fine
        F, nv = len(S), 2 * n * L + n
        out = []
        for ra, rb, rq, lo, hi in ((S / wl, -C / wl, 1.0, self.lower, self.upper),
                                   (C, S, 0.0, -self.vmax, self.vmax),
                                   (-S * wl, C * wl, 0.0, -self.amax, self.amax)):
            A = np.zeros((n * F, nv))
            for j in range(n):
                r = slice(j * F, (j + 1) * F)
                A[r, j * L:(j + 1) * L] = ra
                A[r, n * L + j * L:n * L + (j + 1) * L] = rb
                A[r, 2 * n * L + j] = rq
            out.append(LinearConstraint(A, np.repeat(lo, F), np.repeat(hi, F)))
        E = lil_matrix((2 * n, nv))
        for j in range(n):
            E[j, j * L:(j + 1) * L] = 1.0
            E[n + j, n * L + j * L:n * L + (j + 1) * L] = np.arange(1, L + 1)
        out.append(LinearConstraint(E.toarray(), 0.0, 0.0))
        return out

    def start(self, c):
        """A feasible y from raw coefficients ``c`` (n, 2L): projected to rest at t = 0, each
        joint scaled to the tightest of its limits (times 0.98) and centred in its range."""
        n, L = self.n, self.L
        ell = np.arange(1, L + 1)
        a = c[:, :L] - c[:, :L].mean(axis=1, keepdims=True)
        b = c[:, L:] - np.outer(c[:, L:] @ ell / (ell @ ell), ell)
        y = np.concatenate([a.ravel(), b.ravel(), np.zeros(n)])
        return self.fit(y, 0.98)

    def fit(self, y, factor=1.0):
        """y with each joint's series scaled so that its motion on a grid 10x finer than the
        constraints' stays within ``factor`` x its limits, centred in its range."""
        a, b, _ = self.split(y)
        dense = self.grid(np.linspace(0.0, 2 * math.pi / self.wl[0], 400 * self.L, endpoint=False))
        q, v, acc = self.states(np.concatenate([a.ravel(), b.ravel(), np.zeros(self.n)]), dense)
        k = factor * np.minimum.reduce([(self.upper - self.lower) / np.maximum(np.ptp(q, axis=0), 1e-12),
                                        self.vmax / np.maximum(np.abs(v).max(axis=0), 1e-12),
                                        self.amax / np.maximum(np.abs(acc).max(axis=0), 1e-12)])
        q0 = 0.5 * (self.lower + self.upper) - 0.5 * k * (q.max(axis=0) + q.min(axis=0))
        return np.concatenate([(a * k[:, None]).ravel(), (b * k[:, None]).ravel(), q0])

    def inside(self, y):
        """y with each joint that exceeds a limit on a grid 10x finer than the constraints' scaled
        down (about its mid-range) and shifted just enough to be within them; the others as
        they are."""
        a, b, q0 = (v.copy() for v in self.split(y))
        dense = self.grid(np.linspace(0.0, 2 * math.pi / self.wl[0], 400 * self.L, endpoint=False))
        q, v, acc = self.states(np.concatenate([a.ravel(), b.ravel(), np.zeros(self.n)]), dense)
        k = np.minimum.reduce([np.ones(self.n),
                               (self.upper - self.lower) / np.maximum(np.ptp(q, axis=0), 1e-12),
                               self.vmax / np.maximum(np.abs(v).max(axis=0), 1e-12),
                               self.amax / np.maximum(np.abs(acc).max(axis=0), 1e-12)])
        mid = 0.5 * (q.max(axis=0) + q.min(axis=0))
        q0 = q0 + (1 - k) * mid                              # the mid-range kept
        top, bottom = q0 + k * q.max(axis=0), q0 + k * q.min(axis=0)
        q0 = q0 - np.maximum(top - self.upper, 0.0) + np.maximum(self.lower - bottom, 0.0)
        return np.concatenate([(a * k[:, None]).ravel(), (b * k[:, None]).ravel(), q0])

    def matrix(self, q, v, acc):
        """The stacked, scaled base regressor W at those states."""
        arm = self.arm
        Y = arm.regressor(q, v, acc) / arm.torque_scale[None, :, None] * arm.scale
        return Y.reshape(-1, arm.p)[:, arm.indep]

    @staticmethod
    def _extremes(W):
        """(sigma_1, sigma_r, v_1, v_r) of W from the eigenvalues of W^T W (ascending)."""
        lam, V = np.linalg.eigh(W.T @ W)
        return math.sqrt(max(lam[-1], 0.0)), math.sqrt(max(lam[0], 0.0)), V[:, -1], V[:, 0]

    def value(self, y):
        """log cond W of the variables ``y``."""
        s1, sr, _, _ = self._extremes(self.matrix(*self.states(y)))
        return math.log(s1 / sr) if sr > 0 else 1e3

    def value_and_grad(self, y):
        """(log cond W, its gradient in ``y``)."""
        pin, arm, n, wl = self.arm.pin, self.arm, self.n, self.wl
        q, v, acc = self.states(y)
        W = self.matrix(q, v, acc)
        s1, sr, v1, vr = self._extremes(W)
        if not sr > 1e-12 * s1:
            return 1e3, np.zeros(len(y))
        K = len(q)
        gq, gv, ga = np.zeros((K, n)), np.zeros((K, n)), np.zeros((K, n))
        xs = []
        for vec, sig, sign in ((v1, s1, 1.0 / s1), (vr, sr, -1.0 / sr)):
            x = np.zeros(arm.p)
            x[arm.indep] = arm.scale[arm.indep] * vec
            xs.append((x, sign, (W @ vec / sig).reshape(K, n) / arm.torque_scale))   # u = W v / sigma
        # a consistent x0 that keeps every body's mass of x + x0 away from 0
        masses = arm.pi_urdf[0:10 * n:10]
        x0 = (2.0 + max(np.abs(x[0:10 * n:10]).max() for x, _, _ in xs) / masses.min()) * arm.pi_urdf
        for m, xi in zip(self.models, [x0] + [x0 + x[:10 * n] for x, _, _ in xs]):
            for i in range(1, n + 1):
                m.inertias[i] = pin.Inertia.FromDynamicParameters(xi[10 * (i - 1):10 * i])
        Q = arm.pin_configurations(q)
        for k in range(K):
            d0 = pin.computeRNEADerivatives(self.models[0], self.datas[0], Q[k], v[k], acc[k])
            for j, (_, sign, w) in enumerate(xs, start=1):
                d1 = pin.computeRNEADerivatives(self.models[j], self.datas[j], Q[k], v[k], acc[k])
                wk = sign * w[k]
                Ma = np.triu(d1[2] - d0[2])                # pinocchio fills M's upper triangle
                gq[k] += wk @ (d1[0] - d0[0])
                gv[k] += wk @ (d1[1] - d0[1])
                ga[k] += wk @ (Ma + np.triu(Ma, 1).T)
        th = np.tanh(v / arm.width)
        for x, sign, w in xs:                               # friction: d/dqd
            fv, fc = x[10 * n:11 * n], x[11 * n:12 * n]
            gv += sign * w * (fv + fc * (1 - th ** 2) / arm.width)
        S, C = self.coarse
        g_a = (S.T @ gq).T / wl + (C.T @ gv).T - (S.T @ ga).T * wl
        g_b = -(C.T @ gq).T / wl + (S.T @ gv).T + (C.T @ ga).T * wl
        return math.log(s1 / sr), np.concatenate([g_a.ravel(), g_b.ravel(), gq.sum(axis=0)])


def excitation(robot, T=10.0, *, base_frequency=None, harmonics=5, margin=0.05, speed=0.8,
               qdd_max=None, coulomb_width=None, points=None, starts=2, maxiter=30, seed=0,
               progress=False):
    """An excitation trajectory for :func:`identify`: a Fourier series per joint within the
    limits, its coefficients chosen for a low condition number of the stacked base regressor.

    From ``starts`` random coefficient sets, each joint scaled to its tightest limit and centred
    in its range (feasible), SLSQP minimises log cond W, W the stacked base regressor at
    ``points`` instants of a period (columns in parameter scales, rows in joint torque scales, as
    in the identification report), with its exact gradient (:class:`_Design`), subject to the
    limits at 40 L instants per period (linear in the coefficients) and rest at t = 0: positions
    within the range less ``margin`` at both ends, |qd| <= ``speed`` x the velocity limit,
    |qdd| <= ``qdd_max``. A final check on a 10x finer grid scales a joint back to its limits
    should it exceed one between the grid's instants.

    Parameters
    ----------
    robot : models.RobotModel
        A URDF robot (as for :func:`identify`).
    T : float
        Duration (s), a whole number of periods so the trajectory ends at rest.
    base_frequency : float, optional
        f0 (Hz); default the smallest f0 >= 0.1 Hz with T f0 whole.
    harmonics : int
        L >= 2, the number of harmonics (top frequency L f0).
    margin : float
        Fraction of each joint's range kept free at both ends.
    speed : float
        Fraction of each joint's velocity limit used (limit 1 rad/s where the URDF gives none).
    qdd_max : float or (n,) array, optional
        Acceleration limit (rad/s^2); default 2 (1/s) x the velocity used.
    coulomb_width : float, optional
        w of the Coulomb column (as in :func:`identify`).
    points : int, optional
        Instants per period in the objective (default max(60, 3 x base parameters / n)).
    starts : int
        Random starting coefficient sets.
    maxiter : int
        SLSQP iterations per start (0: the scaled random start itself).
    seed : int
        Seeds the starting coefficients.
    progress : bool
        A tqdm bar on stderr over the optimiser's iterations.

    Returns
    -------
    Excitation
    """
    from scipy.optimize import minimize
    arm = _Arm(robot, coulomb_width)
    n = arm.n
    T = float(T)
    if not (math.isfinite(T) and T > 0):
        raise ValueError(f"T: expected a positive duration (s), got {T!r}")
    if base_frequency is None:
        f0 = math.ceil(0.1 * T - 1e-9) / T
    else:
        f0 = float(base_frequency)
        if not (f0 > 0 and abs(T * f0 - round(T * f0)) < 1e-9 and round(T * f0) >= 1):
            raise ValueError(f"T: {T:g} s is not a whole number of periods of base_frequency {f0:g} Hz "
                             "(the trajectory would not end at rest)")
    L = int(harmonics)
    if L < 2:
        raise ValueError(f"harmonics: expected an integer >= 2 (one harmonic cannot start and end at "
                         f"rest), got {harmonics!r}")
    if not 0 <= margin < 0.5:
        raise ValueError(f"margin: expected a fraction in [0, 0.5), got {margin!r}")
    if not 0 < speed <= 1:
        raise ValueError(f"speed: expected a fraction in (0, 1], got {speed!r}")
    vmax = speed * arm.v_limit
    amax = np.broadcast_to(np.asarray(qdd_max, float), (n,)) if qdd_max is not None else 2.0 * vmax
    if not np.all(np.isfinite(amax) & (amax > 0)):
        raise ValueError(f"qdd_max: expected positive accelerations (rad/s^2), got {qdd_max!r}")
    lo, hi = arm.q_lower, arm.q_upper
    points = int(points or max(60, math.ceil(3 * len(arm.indep) / n)))
    design = _Design(arm, f0, L, lo + margin * (hi - lo), hi - margin * (hi - lo), vmax, amax, points)
    constraints = design.constraints()
    rng = np.random.default_rng(seed)
    bar = _progress(progress, f"excitation {arm.name}", total=int(starts) * int(maxiter))
    best = None
    ell = np.arange(1, L + 1)
    for _ in range(int(starts)):
        y0 = design.start(rng.normal(size=(n, 2 * L)) / np.r_[ell, ell])
        res = minimize(design.value_and_grad, y0, jac=True, method="SLSQP", constraints=constraints,
                       options={"maxiter": int(maxiter)}, callback=lambda *_: bar.update(1)) \
            if maxiter > 0 else None
        y, f = (res.x, res.fun) if res is not None and np.all(np.isfinite(res.x)) else (y0, design.value(y0))
        if best is None or f < best[1]:
            best = (y, f)
        bar.set_postfix_str(f"cond {math.exp(best[1]):.4g}")
    bar.close()
    y = best[0]
    # the constraints hold on the fine grid; between its points the motion may exceed them by
    # round-off or a sliver: scaled back within them on a grid 10x finer
    y = design.inside(y)
    a, b, q0 = design.split(y)
    dense = design.grid(np.linspace(0.0, 1.0 / f0, 400, endpoint=False))
    cond = float(np.linalg.cond(_tri(design.matrix(*design.states(y, dense)))))
    return Excitation(arm.joint_names, f0, a, b, q0, T, condition=float(cond))
