"""Non-minimal (link centre-of-mass) kinematics of any RobotModel, seed 002 (docs/papers/seed002.md §3.1).

    p = [p_1; ...; p_n] in R^{m n},  v_p = J_p(q) qd                        [S002 (6),(8)]
    m_i p_i'' - m_i g_o = f_{f,i}      (net non-gravitational CoM force)     [S002 (4)], A2-2
    f_{f,i} = m_i (J_p^i qdd + Jdot_p^i qd - g_o)                           docs/papers/seed002.md §3.1 [DERIVED]
    pi = selected rows of p,  nu = J_n(q) qd,  nu_j' = a_j + theta_j f_{f,j}  [S002 (9)-(11)]

with a_j the matching entry of [g_o; ...; g_o] and theta_j = 1/m_{link(j)}. m = ``robot.dim``
(2 planar, 3 spatial). Rows whose Jacobian row vanishes identically (CoM on the joint axis of
every joint that moves it, e.g. a base link, or the wrist links of ur5) carry no velocity
information and are skipped; joints whose column of J_p vanishes identically (no CoM moves
with them: ur5 joints 5 and 6) are not observable from CoM kinematics and are left out of
qd_hat = J_n^+ nu [ASSUMPTION; the seed assumes J_p of full column rank].

The file name starts with "_": a helper of the observer families, not a family itself.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

ZERO_TOL = 1e-9      # a row/column of J_p is "identically zero" if below this at every sample


def _samples(robot, count, seed):
    """Configurations in [-pi, pi]^n (the same rule the reference uses)."""
    return np.random.default_rng(seed).uniform(-np.pi, np.pi, size=(count, robot.n))


def _jacobians(robot, Q):
    """J_p at the rows of Q: array (count, m n, n)."""
    Jmap = robot.Jcom.map(len(Q))
    J = np.asarray(Jmap(Q.T))                     # (m n, n count), column blocks per sample
    return J.reshape(J.shape[0], len(Q), robot.n).transpose(1, 0, 2)


def gravity_vector(robot, count=6, seed=1):
    """g_o in R^m: the robot's declared gravity, else fitted from g(q) = -sum_i m_i J_p^i(q)^T g_o
    [S002 Remark 2]; either way checked against g(q) at sampled q (raises if it does not hold)."""
    Q = _samples(robot, count, seed)
    J = _jacobians(robot, Q)
    m, n = robot.dim, robot.n
    masses = np.repeat(np.asarray(robot.masses, float), m)
    # g(q)_k = -sum_i m_i sum_a J[i a, k] go_a  ->  A go = g
    A = np.concatenate([-np.einsum("r,rk,ra->ka", masses, Jq,
                                   np.tile(np.eye(m), (n, 1))) for Jq in J])
    g = np.concatenate([np.asarray(robot.g(q)).reshape(-1) for q in Q])
    go = _declared_gravity(robot)
    if go is None:
        go, *_ = np.linalg.lstsq(A, g, rcond=None)
        go[np.abs(go) < 1e-12] = 0.0
    if np.linalg.norm(A @ go - g) > 1e-8 * max(1.0, np.linalg.norm(g)):
        raise ValueError(f"robot {robot.name!r}: g(q) is not -J_p^T M_p g_o for g_o = {go}")
    return go


def _declared_gravity(robot):
    """The exact g_o a robot declares (URDF tree gravity; planar g0 along -y), else None."""
    tree = getattr(robot, "tree", None)
    if tree is not None and getattr(tree, "gravity", None) is not None:
        return np.array(tree.gravity, dtype=float)
    params = getattr(robot, "p", None)
    if isinstance(params, dict) and "g0" in params and robot.dim == 2:
        return np.array([0.0, -float(params["g0"])])
    return None


def moving_rows(robot, count=64, seed=0, tol=ZERO_TOL):
    """Indices of the rows of J_p (into p in R^{m n}) that are not identically zero and belong
    to a link of positive mass."""
    J = _jacobians(robot, _samples(robot, count, seed))
    scale = max(1.0, np.abs(J).max())
    masses = np.repeat(np.asarray(robot.masses, float), robot.dim)
    return [r for r in range(J.shape[1])
            if np.abs(J[:, r, :]).max() > tol * scale and masses[r] > tol]


def observable_joints(robot, rows, count=64, seed=0, tol=ZERO_TOL):
    """Joints whose column of J_p[rows] is not identically zero."""
    J = _jacobians(robot, _samples(robot, count, seed))[:, rows, :]
    scale = max(1.0, np.abs(J).max())
    return [k for k in range(robot.n) if np.abs(J[:, :, k]).max() > tol * scale]


def conditioning(robot, rows, joints=None, count=256, seed=2):
    """min over sampled q of the smallest singular value of J_p[rows][:, joints] (joints: those
    observable from all moving rows, so a subset that misses a joint scores 0)."""
    joints = observable_joints(robot, moving_rows(robot)) if joints is None else joints
    J = _jacobians(robot, _samples(robot, count, seed))[:, rows][:, :, joints]
    return float(np.linalg.svd(J, compute_uv=False)[:, -1].min())


def select_rows(robot, k, count=256, seed=2, exhaustive_limit=5000):
    """k rows of J_p maximising min_q sigma_min(J_n(q)) over sampled q  [S002 §V, ASSUMPTION].

    Exhaustive over all subsets of the moving rows when there are at most ``exhaustive_limit``
    of them, else greedy (each step adds the row that maximises the worst |S|-th singular
    value). Returns sorted row indices."""
    cand = moving_rows(robot)
    joints = observable_joints(robot, cand)
    if not len(joints) <= k <= len(cand):
        raise ValueError(f"rows: need {len(joints)} <= k <= {len(cand)} (observable joints, "
                         f"moving rows) for robot {robot.name!r}, got k={k}")
    J = _jacobians(robot, _samples(robot, count, seed))[:, :, joints]

    def score(S):
        s = np.linalg.svd(J[:, list(S)], compute_uv=False)
        return s[:, min(len(S), len(joints)) - 1].min()

    combos = list(itertools.islice(itertools.combinations(cand, k), exhaustive_limit + 1))
    if len(combos) <= exhaustive_limit:
        return sorted(max(combos, key=score))
    S = []
    for _ in range(k):
        S.append(max((r for r in cand if r not in S), key=lambda r: score(S + [r])))
    return sorted(S)


@dataclass
class NonMinimal:
    """The non-minimal coordinates of a robot: selected rows of p and the observable joints.

    ``rows``    indices into p in R^{m n} (row r is axis r % m of link r // m)
    ``joints``  joints in qd_hat (columns of J_p that are not identically zero)
    ``g_o``     gravity vector (m,);  ``a`` (r,) = g_o entries of the rows  [S002 (11)], A2-2
    ``theta``   (r,) true 1/m_link of each row (for tests and plots; the observer estimates it)
    """

    robot: object
    rows: list
    joints: list
    g_o: np.ndarray
    row_names: list = field(init=False)

    def __post_init__(self):
        m = self.robot.dim
        axes = "xyz"[:m] if m <= 3 else [str(a) for a in range(m)]
        links = getattr(self.robot, "link_names", None) or [f"link{i + 1}" for i in range(self.robot.n)]
        self.row_names = [f"{links[r // m]}_{axes[r % m]}" for r in self.rows]

    r = property(lambda self: len(self.rows))
    a = property(lambda self: np.array([self.g_o[r % self.robot.dim] for r in self.rows]))
    theta = property(lambda self: 1.0 / np.asarray(self.robot.masses, float)[
        [r // self.robot.dim for r in self.rows]])
    joint_names = property(lambda self: [self.robot.joint_names[k] for k in self.joints])

    @property
    def source(self):
        """JSON-able description the reference reads (added to the spec's robot source)."""
        return {"rows": [int(r) for r in self.rows], "joints": [int(k) for k in self.joints],
                "g_o": [float(g) for g in self.g_o]}

    # ------------------------------------------------------------ symbolic
    def pi(self, q):
        """pi(q): selected CoM coordinates (r, 1) SX  [S002 (10)]."""
        return self.robot.com_positions(q)[self.rows]

    def jacobian(self, q):
        """J_n(q) = J_p[rows][:, joints]: (r, len(joints)) SX  [S002 (9)]."""
        return ca.jacobian(self.pi(q), q)[:, self.joints]

    def bias(self, q, qd):
        """Jdot_n(q, qd) qd = d/dq (J_n(q) qd) qd  (all joints): (r, 1) SX."""
        return ca.jtimes(ca.jtimes(self.pi(q), q, qd), q, qd)

    def force(self, q, qd, qdd):
        """f_f rows = m_link (J_n qdd + Jdot_n qd - a)  docs/papers/seed002.md §3.1."""
        mass = ca.DM(1.0 / self.theta)
        vdot = ca.jtimes(self.pi(q), q, qdd) + self.bias(q, qd)
        return mass * (vdot - ca.DM(self.a))

    def force_function(self):
        """Function (q, qd, tau) -> f_f rows, qdd from the robot's forward dynamics."""
        n = self.robot.n
        q, qd, tau = ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("tau", n)
        qdd = self.robot.forward_dynamics(q, qd, tau)
        return ca.Function("f_f", [q, qd, tau], [self.force(q, qd, qdd)], ["q", "qd", "tau"], ["f_f"])


def nonminimal(robot, rows="all"):
    """NonMinimal coordinates: ``rows`` = "all" (every moving row; the seed's J_n = J_p),
    an int k (k best-conditioned rows, :func:`select_rows`) or an explicit list of indices."""
    if isinstance(rows, str):
        if rows != "all":
            raise ValueError(f"rows must be 'all', an int or a list of row indices, got {rows!r}")
        sel = moving_rows(robot)
    elif isinstance(rows, (int, np.integer)):
        sel = select_rows(robot, int(rows))
    else:
        sel = sorted(int(r) for r in rows)
        bad = [r for r in sel if not 0 <= r < robot.dim * robot.n]
        if bad or len(set(sel)) != len(sel):
            raise ValueError(f"rows: indices must be distinct in [0, {robot.dim * robot.n}), got {rows}")
    if not sel:
        raise ValueError(f"robot {robot.name!r}: no link CoM moves with the joints")
    joints = observable_joints(robot, sel)
    if not joints:
        raise ValueError(f"robot {robot.name!r}: rows {sel} observe no joint")
    return NonMinimal(robot=robot, rows=sel, joints=joints, g_o=gravity_vector(robot))
