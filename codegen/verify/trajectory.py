"""A short built-in trajectory for any robot, exact by inverse dynamics.

    q(t)  = q_c + a sin(w t + phi)                 (per joint, inside the joint range)
    tau(t) = M(q) qdd + C(q, qd) qd + tau_f(qd) + g(q)   [S000 (1)], tau_f the friction

so (q, qd, tau) satisfy the model exactly at every sample; an observer fed
y = q(t_k), u = tau(t_k) (held over a step) must reconstruct qd(t_k).

An elastic-joint robot (no inverse dynamics to the motor input) is simulated instead:
``elastic_trajectory`` from rest under gravity compensation plus sinusoidal torques, and
``elastic_measurement`` reads an observer's measurement slots off the true states by name.
"""
from __future__ import annotations

import casadi as ca
import numpy as np


def inverse_dynamics_function(robot):
    """Function (q, v, a) -> tau = M a + C v + tau_f(v) + g (the model of [S000 (1)], tau_f the
    friction F v + coulomb tanh(v / w) + offset) of ``robot``."""
    q, v, a = ca.SX.sym("q", robot.n), ca.SX.sym("v", robot.n), ca.SX.sym("a", robot.n)
    tau = ca.mtimes(robot.mass_matrix(q), a) + robot.nle(q, v) + robot.friction_torque(v)
    return ca.Function("id", [q, v, a], [tau])


def demo_trajectory(robot, T=2.0, dt=1e-3, amplitude=0.3, omega=2.0, seed=0):
    """Samples t, Q, QD, TAU (each (N, n), N = round(T/dt) + 1) of a smooth motion of ``robot``:
    sines of ``amplitude`` (rad) and frequency ``omega`` (rad/s, spread over the joints) about
    mid-range, phases drawn with ``seed``; T, dt in s.

    Speeds stay below amplitude*omega (0.6 rad/s by default), inside the observers'
    design bound v_max = 2 rad/s."""
    rng = np.random.default_rng(seed)
    n = robot.n
    lo, hi = robot.q_lower, robot.q_upper
    centre = np.clip(0.5 * (lo + hi), lo + amplitude, hi - amplitude)
    a = amplitude * np.minimum(1.0, 0.5 * (hi - lo) / max(amplitude, 1e-12))
    phi = rng.uniform(0, 2 * np.pi, n)
    w = omega * (1.0 + 0.25 * np.arange(n) / max(n - 1, 1))
    t = np.arange(int(round(T / dt)) + 1) * dt
    arg = np.outer(t, w) + phi
    Q = centre + a * np.sin(arg)
    QD = a * w * np.cos(arg)
    QDD = -a * w ** 2 * np.sin(arg)
    f = inverse_dynamics_function(robot).map(len(t))
    TAU = np.asarray(f(Q.T, QD.T, QDD.T)).T
    return t, Q, QD, TAU


def elastic_trajectory(robot, T=2.0, dt=1e-3, amplitude=0.2, omega=2.0, seed=0, substeps=2):
    """Samples t, X (N, 4n), U (N, n) of an ElasticRobot [S004 (2.8)], N = round(T/dt) + 1.

    From rest at mid-range links, q2 = q1 + K^-1 g(q1) (the static equilibrium), under
    u(t) = g(q1(0)) + amplitude max(1, |g|) sin(w t + phi); RK4 with ``substeps`` sub-steps per
    sample, u held over each sample. ``robot``: the ElasticRobot; T, dt in s; ``omega`` (rad/s, spread
    over the joints) and ``seed`` (the phases phi) of the input."""
    rng = np.random.default_rng(seed)
    n, rigid = robot.n, robot.rigid
    q1 = np.clip(0.5 * (robot.q_lower + robot.q_upper), -np.pi, np.pi)
    g0 = np.asarray(rigid.g(q1)).ravel()
    x = np.concatenate([q1, np.zeros(n), q1 + np.linalg.solve(robot.K, g0), np.zeros(n)])
    t = np.arange(int(round(T / dt)) + 1) * dt
    w = omega * (1.0 + 0.25 * np.arange(n) / max(n - 1, 1))
    U = g0 + amplitude * np.maximum(1.0, np.abs(g0)) * np.sin(np.outer(t, w) + rng.uniform(0, 2 * np.pi, n))
    xs, us, h = ca.SX.sym("x", robot.nx), ca.SX.sym("u", n), dt / substeps
    k1 = robot.dynamics(xs, us)
    k2 = robot.dynamics(xs + h / 2 * k1, us)
    k3 = robot.dynamics(xs + h / 2 * k2, us)
    k4 = robot.dynamics(xs + h * k3, us)
    rk4 = ca.Function("rk4", [xs, us], [xs + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    xm, um = ca.MX.sym("x", robot.nx), ca.MX.sym("u", n)
    z = xm
    for _ in range(substeps):
        z = rk4(z, um)
    step = ca.Function("sample", [xm, um], [z]).expand().mapaccum(len(t) - 1)
    X = np.vstack([x, np.asarray(step(x, U[:-1].T)).T])
    return t, X, U


def elastic_measurement(spec, X):
    """The measurement y (N, ny) of ``spec`` (an observer of an ElasticRobot) for true states X
    (N, 4n): a slot named like a state (``robot.state_names``) reads it, ``tau_<joint>`` the
    elastic torque K (q1 - q2) of that joint."""
    robot = spec.robot
    n, names = robot.n, list(robot.state_names)
    tau = (X[:, :n] - X[:, 2 * n:3 * n]) @ robot.K
    cols = []
    for y in spec.y_names:
        if y in names:
            cols.append(X[:, names.index(y)])
        elif y.startswith("tau_") and y[4:] in robot.joint_names:
            cols.append(tau[:, robot.joint_names.index(y[4:])])
        else:
            raise ValueError(f"{spec.family}: measurement slot {y!r} is neither a state of "
                             f"{robot.name} ({', '.join(names)}) nor tau_<joint>")
    return np.column_stack(cols)
