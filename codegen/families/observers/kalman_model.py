"""Steady-state Kalman-Bucy velocity observer on a constant-jerk motion model, with the robot
model's acceleration as a second, friction-aware measurement [DERIVED; the continuous-time
Kalman-Bucy filter (Kalman & Bucy, J. Basic Eng. 83, 1961) on the white-snap ("constant jerk")
kinematic model of target tracking, and the model-based acceleration pseudo-measurement of
joint velocity estimation with joint torque sensing].

Per joint, x = [q_hat, v_hat, a_hat, j_hat] (q_hat'''' white); one clock c (c' = 1, c(0) = 0)
switches the bandwidth omega_s = omega0 (c < t_switch: start-up, kinematic only) or omega
(after: with the model). With e = y - q_hat, omega standing for omega_s:

    kinematic variant (no model):
        x' = S x + [omega g1; omega^2 g2; omega^3 g3; omega^4 g4] e,
        S the shift (q_hat' = v_hat, v_hat' = a_hat, a_hat' = j_hat, j_hat' = 0) and
        g = (2.6131, 3.4142, 2.6131, 1): the error poles omega e^(i pi (2k+5)/8) (Butterworth)

    model variant (torque noise stated), from t_switch on, with the model at y_cfg and the Coulomb
    friction's sign uncertain near v_hat = 0 (s = erf(v_hat / (sqrt 2 width)): the mean of
    sign(v) for v ~ N(v_hat, width^2)):
        z     = tau - C(y, v_hat) v_hat - g(y) - F v_hat - b - Fc s           (b: torque offset)
        Sigma = diag(sigma_tau^2 + Fc^2 (1 - s^2))        (sensor noise + friction's variance)
        C_hat = M^-1 Sigma M^-1 / (sigma_q^2 omega^4)     (the a-measurement's normalised noise)
        per pole p_k (k = 1..K):
            r_k = (C_hat + p_k I)^-1 [e, M^-1 z - a_hat]
                = M (Sigma / (sigma_q^2 omega^4) + p_k M^2)^-1 [M e, z - M a_hat]
            block b of x' += p_k (omega^b cq_bk r_k,e + omega^(b-2) ca_bk r_k,a)

i.e. the Kalman gains K_q,b = omega^b g_q,b(C_hat), K_a,b = omega^(b-2) g_a,b(C_hat) as matrix
functions of the a-measurement's covariance (exact decoupling of the joints in the eigenvectors
of C_hat; partial fractions fitted in codegen.families.design.kalman_model). A stopped joint
(|v_hat| << width) has Fc^2 in Sigma: its torque says nothing (static friction holds an unknown
torque in [-Fc, Fc]) and its estimate is the kinematic one; a moving joint's acceleration is
taken from the model with the weight its torque noise allows.

State x = [q_hat; v_hat; a_hat; j_hat; c] (4n + 1), y = q, u = tau (measured), estimate v_hat.
p = [omega, omega0, t_switch] (kinematic) or those and [sigma_q, width, sigma_tau_<j>,
coulomb_<j>, offset_<j>, pole_k, cq<b>_k, ca<b>_k] (model): the stated noise levels and friction
are runtime parameters next to the fitted gain functions. The switch changes the gains only: the
state, hence the estimate, stays continuous.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ..design.kalman_model import (POLES, check_per_joint, check_torque_uncertainty, design_kalman_model,
                                   normalised_gains)
from ...core.options import InputRanges, VariantOptions
from ...core.spec import ObserverSpec, split_flow, split_model
from ...core.symbolic import apply_reflections, householder_tridiagonal, tridiagonal_factors, tridiagonal_solve
from ._design import design_discretization, stable_report

TUNE = {"omega": 1}       # the steady bandwidth a log tunes (codegen.logs.tune)
# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed000_2r"},
            {"robot": "seed000_2r", "design": {"torque_uncertainty": [0.5, 0.2], "coulomb": [1.0, 0.5],
                                               "torque_offset": [0.1, -0.1]}}]
VARIANTS = ("kinematic", "model")


def _p_names(joints, K):
    names = ["omega", "omega0", "t_switch"]
    if K is None:
        return names
    names += ["sigma_q", "width"]
    names += [f"sigma_tau_{j}" for j in joints] + [f"coulomb_{j}" for j in joints] + [f"offset_{j}" for j in joints]
    names += [f"pole_{k}" for k in range(K)]
    names += [f"cq{b}_{k}" for b in range(1, 5) for k in range(K)]
    names += [f"ca{b}_{k}" for b in range(1, 5) for k in range(K)]
    return names


def build(robot, variant=None, omega=None, noise=None, quantization=None, torque_uncertainty=None, coulomb=None,
          torque_offset=None, width=None, v_max=2.0, t_conv=0.2, t_settle=0.5, dt=None, poles=POLES):
    """kalman_model observer for ``robot`` (module docstring).

    Parameters
    ----------
    robot : RobotModel
    variant : {"kinematic", "model"}, optional
        Default "model" when ``torque_uncertainty`` is given, else "kinematic"; a given variant must
        agree with it.
    omega : float, optional
        Steady bandwidth (1/s) of the kinematic filter; default the design's (codegen.families.
        design.kalman_model: the smallest converging within t_settle).
    noise, quantization : float, optional
        Encoder noise std and quantisation step (rad); both None: a 2^16 counts/rev encoder.
    torque_uncertainty : float or (n,) sequence, optional
        Std of the measured torque's noise per joint (N m), e.g. the residual std of an
        identification; None: the kinematic variant (the model is not used).
    coulomb : (n,) sequence, optional
        Coulomb friction per joint (N m), default the robot's own (``robot.coulomb``: a URDF's
        ``<dynamics friction>`` or an identified side file; 0 if it has none) (model variant only).
    torque_offset : (n,) sequence, optional
        Offset of the measured torque per joint (N m), default the robot's own
        (``robot.offset``) (model variant only).
    width : float, optional
        Velocity (rad/s) below which the Coulomb friction's sign is uncertain; default the
        design's predicted velocity std per joint.
    v_max, t_conv, t_settle : float
        Speed bound (rad/s) and the convergence times (s) of the start-up and steady bandwidths.
    dt : float, optional
        Sample time of the design's noise predictions and stability check (s).
    poles : int
        Partial fractions of the gain functions (model variant).
    """
    disc = design_discretization(dt)
    design = design_kalman_model(robot, disc.dt, noise, quantization, torque_uncertainty, v_max, t_conv,
                                 t_settle, omega, poles)
    n = robot.n
    implied = "kinematic" if torque_uncertainty is None else "model"
    if variant is not None and variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    if variant is not None and variant != implied:
        raise ValueError(f"variant {variant!r} needs torque_uncertainty "
                         + ("stated (N m per joint)" if variant == "model" else "unstated (None)"))
    variant = implied
    if variant == "kinematic":
        for name, v in (("coulomb", coulomb), ("torque_offset", torque_offset), ("width", width)):
            if v is not None:
                raise ValueError(f"{name} is used with the model only: state torque_uncertainty too")
    joints = robot.joint_names
    K = None if variant == "kinematic" else len(design.poles)
    p_names = _p_names(joints, K)
    p_default = [design.omega, design.omega0, design.t_switch]
    if K is not None:
        # the robot's own friction (an identified URDF carries it): z below takes the viscous part
        # through F and the Coulomb part and offset through these parameters, never twice
        if coulomb is None:
            coulomb = [float(c) for c in getattr(robot, "coulomb", np.zeros(n))]
        if torque_offset is None:
            torque_offset = [float(o) for o in getattr(robot, "offset", np.zeros(n))]
        if width is None:
            width = design.width
        if not (isinstance(width, (int, float)) and math.isfinite(width) and width > 0):
            raise ValueError(f"width must be a positive velocity (rad/s), got {width!r}")
        c = np.asarray(design.coefficients)
        p_default += [design.sigma, float(width)]
        p_default += list(check_torque_uncertainty(torque_uncertainty, n)) + list(check_per_joint("coulomb", coulomb, n, True))
        p_default += list(check_per_joint("torque_offset", torque_offset, n))
        p_default += list(design.poles) + list(c[0].ravel()) + list(c[1].ravel())

    qh, vh, ah, jh = (ca.SX.sym(s, n) for s in ("q_hat", "v_hat", "a_hat", "j_hat"))
    clock = ca.SX.sym("t_clock")
    y, y_cfg, tau = ca.SX.sym("y", n), ca.SX.sym("y_cfg", n), ca.SX.sym("tau", n)
    p = ca.SX.sym("p", len(p_names))
    w = ca.if_else(clock < p[2], p[1], p[0])
    g = normalised_gains()
    x = ca.vertcat(qh, vh, ah, jh, clock)
    e = y - qh
    blocks = [vh + w * g[0] * e, ah + w ** 2 * g[1] * e, jh + w ** 3 * g[2] * e, w ** 4 * g[3] * e]
    if K is None:
        rhs, rhs_split = split_flow(x, y_cfg, y, tau, p, ca.vertcat(*blocks, 1))
        model = rhs_model = None
    else:
        # the model's part: the gain structure of the a-measurement at the configuration y_cfg and
        # the velocity v_hat (``gain_structure``), held over a step; the injection it makes, linear
        # in e and a_hat (``model_injection``), at every stage
        m = ca.SX.sym("m", structure_size(n, K))
        injection = model_injection(m, x, p, y, n, K, ca.DM(robot.F))
        xdot = ca.vertcat(*[blocks[b] + injection[b * n:(b + 1) * n] for b in range(4)], 1)
        rhs, rhs_split, model, rhs_model = split_model(x, y_cfg, y, tau, p, m,
                                                       gain_structure(robot, x, y_cfg, tau, p, K), xdot)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", n)
    names = [f"{s}_{j}" for s in ("q_hat", "qd_hat", "qdd_hat", "jerk_hat") for j in joints] + ["t_clock"]
    spec = ObserverSpec(
        family="kalman_model", robot=robot, variant=variant, options=VariantOptions(variant),
        x_names=names, y_names=[f"q_{j}" for j in joints], u_names=[f"tau_{j}" for j in joints],
        p_names=p_names, est_names=[f"qd_hat_{j}" for j in joints], p_default=p_default,
        rhs=rhs, rhs_split=rhs_split, model=model, rhs_model=rhs_model, model_correction=K is not None,
        output=ca.Function("output", [x, y, tau, p], [vh]),
        init=ca.Function("init", [y0, est0, p], [ca.vertcat(y0, est0, ca.DM.zeros(2 * n + 1))]),
        # q_hat' = [v_hat + omega_s g1 y + ...] - omega_s g1 q_hat: the rate omega_s g1 on q_hat
        # (at the step's start: exact within a phase; any rate splits the flow exactly)
        rate=ca.Function("rate", [x, p], [w * g[0]]), rate_states=[f"q_hat_{j}" for j in joints],
        gains={"omega0": ("omega0",), "omega": ("omega",)},
        design={**design.as_dict(), "variant": variant},
        # cross-check inputs: position errors ~0.01 rad about y (gains up to omega^4 ~ 1e6),
        # speeds ~2 rad/s, accelerations ~10 rad/s^2, jerks ~100 rad/s^3; the clock on both sides
        # of the switch
        inputs=InputRanges(x_scale=(0.01,) * n + (2.0,) * n + (10.0,) * n + (100.0,) * n + (0.0,),
                           x_about_y=tuple((f"q_hat_{j}", f"q_{j}") for j in joints),
                           x_uniform=(("t_clock", 0.0, 2 * design.t_switch),)),
    )
    return stable_report(spec, disc)


def structure_size(n, K):
    """Entries of ``gain_structure`` for ``n`` joints and ``K`` poles: W (n x n), per pole the LDL^T
    factors of I + p_k T (n inverse pivots, n - 1 multipliers), zeta (n), V (n x n), the friction's
    sign s and v_hat there (n each)."""
    return 2 * n * n + K * (2 * n - 1) + 3 * n


def _unpack(m, n, K):
    """(W, [(1/d, l)] per pole, zeta, V, s, v_hat) of a ``gain_structure`` vector ``m``."""
    W = ca.reshape(m[:n * n], n, n)
    factors, i = [], n * n
    for _ in range(K):
        factors.append((ca.vertsplit(m[i:i + n]), [None] + ca.vertsplit(m[i + n:i + 2 * n - 1])))
        i += 2 * n - 1
    return W, factors, m[i:i + n], ca.reshape(m[i + n:i + n + n * n], n, n), m[i + n + n * n:i + 2 * n + n * n], \
        m[i + 2 * n + n * n:i + 3 * n + n * n]


def _sign(vh, p):
    """s = erf(v_hat / (sqrt 2 width)): the mean of sign(v) for v ~ N(v_hat, width^2)."""
    return ca.erf(vh / (math.sqrt(2.0) * p[4]))


def _friction(vh, p, n, F):
    """The friction the model subtracts from the torque at v_hat: F v_hat + Fc s (N m)."""
    return ca.mtimes(F, vh) + p[5 + n:5 + 2 * n] * _sign(vh, p)


def gain_structure(robot, x, y_cfg, tau, p, K):
    """The model's part of the flow (module docstring), what the gains are made of at the
    configuration ``y_cfg`` and the state's velocity v_hat, (``structure_size``,) SX:

        D = Sigma / (sigma_q^2 omega^4),  B = D^-1/2 M^2 D^-1/2 = Q T Q^T   (T tridiagonal,
                                                                            Householder)
        V = Q^T D^-1/2,  W = V M,  zeta = V z = W a_m   (a_m = M^-1 z, the model's acceleration)

    with on (1 from t_switch on, else 0) times W, zeta, V and per pole the LDL^T factors of
    I + p_k T, then s and v_hat (for the friction's change over a step, ``model_injection``).
    (C_hat + p_k I)^-1 = W^T (I + p_k T)^-1 W (C_hat = W^-1 T^-1 W^-T, T = W W^T): the gains act
    through one tridiagonal solve per pole and W; zeros are the kinematic filter. ``robot``: the
    model (M, nle, F); x, tau, p: the flow's state, torque and parameters; ``K`` the poles."""
    n = robot.n
    vh, clock = x[n:2 * n], x[4 * n]
    sig_q, st, fc, off = p[3], p[5:5 + n], p[5 + n:5 + 2 * n], p[5 + 2 * n:5 + 3 * n]
    pk = p[5 + 3 * n:5 + 3 * n + K]
    M = robot.mass_matrix(y_cfg)
    s = _sign(vh, p)
    z = tau - robot.nle(y_cfg, vh) - _friction(vh, p, n, ca.DM(robot.F)) - off
    on = ca.if_else(clock < p[2], 0, 1)        # the model: steady phase only
    scale = 1 / ca.sqrt((st ** 2 + fc ** 2 * (1 - s ** 2)) / (sig_q ** 2 * p[0] ** 4))      # D^-1/2
    B = ca.mtimes(ca.diag(scale), ca.mtimes(ca.mtimes(M, M), ca.diag(scale)))
    diag, sub, reflections = householder_tridiagonal(B)
    V = ca.horzcat(*[ca.vertcat(*apply_reflections(reflections, [scale[j] if i == j else 0 for i in range(n)],
                                                   transpose=True)) for j in range(n)])
    W = ca.mtimes(V, M)
    out = [on * ca.reshape(W, n * n, 1)]
    for k in range(K):
        inv, low = tridiagonal_factors(diag, sub, pk[k])
        out += [on * ca.vertcat(*inv), on * ca.vertcat(*low[1:])]
    out += [on * ca.mtimes(V, z), on * ca.reshape(V, n * n, 1), s, vh]
    return ca.densify(ca.vertcat(*out))


def model_injection(m, x, p, y, n, K, F):
    """The injection (4n,) SX of the gain structure ``m`` (``gain_structure``) into the blocks
    b = 1..4 of the state x at the measurement y: with e = y - q_hat, the a-measurement at this
    v_hat, zeta + V (F (v_m - v_hat) + Fc (s_m - s)) (its friction terms follow the velocity over
    the step, the rest of the model held at the structure's v_m), e~ = W e, e~_a = zeta - W a_hat
    and w_k = (I + p_k T)^-1 [e~, e~_a] (tridiagonal solves with m's factors), block b of
    sum_k p_k (omega^b cq_bk r_k,e + omega^(b-2) ca_bk r_k,a), r_k = W^T w_k (module docstring);
    zero for m = 0. ``p``: the parameters (omega, the poles p_k and coefficients); n joints, ``K``
    poles; F: the robot's viscous friction (n, n)."""
    W, factors, zeta, V, s_m, v_m = _unpack(m, n, K)
    qh, vh, ah = x[:n], x[n:2 * n], x[2 * n:3 * n]
    base = 5 + 3 * n
    pk = p[base:base + K]
    cq = ca.reshape(p[base + K:base + 5 * K], K, 4).T          # (4, K): row b-1, column k
    ca_ = ca.reshape(p[base + 5 * K:base + 9 * K], K, 4).T
    wm = p[0]
    fc = p[5 + n:5 + 2 * n]
    zeta = zeta + ca.mtimes(V, ca.mtimes(F, v_m - vh) + fc * (s_m - _sign(vh, p)))
    u = [ca.vertsplit(ca.mtimes(W, y - qh)), ca.vertsplit(zeta - ca.mtimes(W, ah))]
    acc = [[0] * n for _ in range(4)]
    for k, (inv, low) in enumerate(factors):
        w_e, w_a = tridiagonal_solve(inv, low, u)
        for b in range(4):
            ce, ck = pk[k] * wm ** (b + 1) * cq[b, k], pk[k] * wm ** (b - 1) * ca_[b, k]
            acc[b] = [a + ce * we + ck * wa for a, we, wa in zip(acc[b], w_e, w_a)]
    return ca.vertcat(*[ca.mtimes(W.T, ca.vertcat(*acc[b])) for b in range(4)])
