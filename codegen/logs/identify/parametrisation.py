"""Inertial parametrisations of a rigid body: the 10 parameters about a frame's origin
``pi = [m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]``, the pseudo-inertia
(Wensing et al. 2017), the log-Cholesky coordinates (Rucker & Wensing, RA-L 2022), and a URDF
<inertial> (mass, centre of mass, inertia about it)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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
# physical consistency with a margin
# =============================================================================================
MASS_FLOOR = 0.1                # a link's least mass: this x its URDF mass ...
MASS_FLOOR_TOTAL = 1e-3         # ... or this x the robot's moving mass, whichever is larger
COM_MARGIN = 0.1                # m: the centre of mass within the link's reach plus this
RHO = 1e-3                      # m: every principal second moment about the CoM >= m RHO^2 ...
RHO_LENGTH = 0.1                # ... RHO at most this x the body's length scale
INSIDE = 1e-3                   # a projected point this far (relatively) inside the bounds


@dataclass(frozen=True)
class LinkBounds:
    """The physical region of a link's <inertial>: mass >= ``mass`` (kg); each coordinate of the
    centre of mass within +-``reach`` (m) of the joint frame's origin; every principal second
    moment about the centre of mass, s_k = int x_k^2 dm, >= m ``rho``^2 (so the inertia about it
    is positive definite with the triangle inequalities I_a + I_b - I_c = 2 s_c >= 2 m rho^2)."""
    mass: float
    reach: float
    rho: float


def _shift(rho):
    """10 parameters of a unit mass's second moment rho^2 1 about its centre (I = 2 rho^2 1)."""
    r = 2.0 * rho ** 2
    return np.array([0.0, 0.0, 0.0, 0.0, r, 0.0, r, 0.0, 0.0, r])


def from_bounded(theta, rho):
    """(pi (..., 10), d pi / d theta (..., 10, 10)) of the log-Cholesky coordinates of
    :func:`from_log_cholesky` with the second moment about the centre of mass raised by
    m rho^2 1 (``rho`` (...,)): Sigma_c = m (D D^T + rho^2 1), inside :class:`LinkBounds`' margin
    by construction (its mass and centre-of-mass bounds are bounds on theta_0 = log(m)/2 and
    theta_7..9 = c)."""
    pi, dpi = from_log_cholesky(theta)
    extra = pi[..., :1] * np.stack([_shift(r) for r in np.ravel(rho)]).reshape(pi.shape)
    dpi = dpi.copy()
    dpi[..., :, 0] += 2.0 * extra                        # d m / d theta_0 = 2 m
    return pi + extra, dpi


def to_bounded(pi, rho):
    """Coordinates theta of :func:`from_bounded` of parameters ``pi`` (10,) inside the margin of
    ``rho`` (m, or in the body's scaled units)."""
    return log_cholesky(np.asarray(pi, float) - pi[0] * _shift(rho))


def project(pi, bounds):
    """(pi', changes): the parameters ``pi`` (10,) of a link moved into its ``bounds``
    (:class:`LinkBounds`, ``INSIDE`` within them): the mass raised to the least (the inertia about the centre of mass
    scaled with it), each coordinate of the centre of mass clipped to the reach, the second moment
    about it Sigma_c = tr(I_c)/2 1 - I_c with its eigenvalues raised to m rho^2 (the nearest such
    matrix in the Frobenius norm); ``changes`` says what moved (empty: ``pi`` was inside)."""
    pi = np.asarray(pi, dtype=float)
    m0 = float(pi[0])
    changes = []
    if m0 > 0:
        m, c, Ic = inertial_to_urdf(pi)
    else:
        m, c, Ic = m0, np.zeros(3), np.zeros((3, 3))
    lo = bounds.mass * (1 + INSIDE)
    if not m > lo:
        changes.append(f"mass {m:.4g} kg raised to {lo:.4g}")
        Ic = Ic * (lo / m) if m > 0 else Ic
        m = lo
    reach = bounds.reach * (1 - INSIDE)
    if np.any(np.abs(c) > reach):
        changes.append(f"centre of mass [{', '.join(f'{v:.4g}' for v in c)}] m clipped to +-{reach:.4g}")
        c = np.clip(c, -reach, reach)
    S = 0.5 * np.trace(Ic) * np.eye(3) - Ic
    lam, V = np.linalg.eigh(0.5 * (S + S.T))
    least = m * bounds.rho ** 2 * (1 + INSIDE)
    if lam[0] < least:
        changes.append(f"principal second moments [{', '.join(f'{v:.3g}' for v in lam)}] kg m^2 raised to "
                       f">= {least:.3g} (inertia about the centre of mass positive definite within the "
                       f"triangle inequalities)")
        S = (V * np.maximum(lam, least)) @ V.T
    Ic = np.trace(S) * np.eye(3) - S
    return urdf_to_inertial(m, c, Ic), changes


def inside(pi, bounds, slack=1e-9):
    """Whether parameters ``pi`` (10,) satisfy ``bounds`` (:class:`LinkBounds`) to a relative
    ``slack``."""
    m, c, Ic = inertial_to_urdf(pi)
    S = 0.5 * np.trace(Ic) * np.eye(3) - Ic
    return bool(m >= bounds.mass * (1 - slack) and np.all(np.abs(c) <= bounds.reach * (1 + slack))
                and np.linalg.eigvalsh(S)[0] >= m * bounds.rho ** 2 * (1 - 1e-6))
