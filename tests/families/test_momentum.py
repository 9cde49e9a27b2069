"""The momentum observer (codegen.families.observers.momentum): its C against the reference, its
residual against a known external torque on the model's own plant, detection and isolation, and
the design rule's formulas against direct computation."""
import math

import casadi as ca
import numpy as np
import pytest

from codegen import compile_observer, observers
from codegen.families.design.momentum import crossing_time, design_momentum, threshold_level
from codegen.verify import cross_check
from models import load_robot

TOL = 1e-9
SENSOR = {"torque_noise": 0.2, "noise": 0.0, "quantization": 0.0}   # the noise-free plant's thresholds


@pytest.mark.parametrize("robot_name", ["seed000_2r", "ur5"])
def test_c_equals_the_reference(robot_name):
    """The emitted C and the numpy/pinocchio reference agree within 1e-9 on random inputs
    (step, elapsed-time step, flow, runs)."""
    robot = load_robot(robot_name)
    if robot_name == "ur5":                        # friction the residual must subtract
        robot = robot.with_friction(viscous=[0.5] * 6, coulomb=[1.0] * 6, offset=[0.1] * 6)
    spec = observers.build("momentum", robot)
    res = cross_check(spec, count=100)
    worst = max(v for k, v in res.items() if k != "samples")
    assert worst < TOL, res


def _plant_run(robot, tau_ext, T=1.0, dt=1e-3, t_on=0.3, sub=10):
    """The model's own plant under a computed-torque hold at q0 plus tau_ext from t_on: (t, Q, U, true tau_ext)."""
    n = robot.n
    q, v = np.full(n, 0.3), np.zeros(n)
    fd = robot.fd
    g = robot.g
    N = int(round(T / dt)) + 1
    Q, U, E = np.zeros((N, n)), np.zeros((N, n)), np.zeros((N, n))
    q0 = q.copy()
    for k in range(N):
        t = k * dt
        tau = np.asarray(g(q)).ravel() + 50.0 * (q0 - q) - 10.0 * v
        ext = tau_ext if t >= t_on else np.zeros(n)
        Q[k], U[k], E[k] = q, tau, ext
        h = dt / sub
        for _ in range(sub):                        # RK4 on the model with tau + tau_ext held
            f = lambda q_, v_: (v_, np.asarray(fd(q_, v_, tau + ext)).ravel())
            k1 = f(q, v); k2 = f(q + h / 2 * k1[0], v + h / 2 * k1[1])
            k3 = f(q + h / 2 * k2[0], v + h / 2 * k2[1]); k4 = f(q + h * k3[0], v + h * k3[1])
            q = q + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            v = v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return np.arange(N) * dt, Q, U, E


def _observed(tau_ext):
    """(t, estimate) of the compiled momentum observer on the 2R plant of ``_plant_run``."""
    robot = load_robot("seed000_2r")
    obs = compile_observer(observers.build("momentum", robot, **SENSOR), dt=1e-3)
    t, Q, U, _ = _plant_run(robot, np.array(tau_ext))
    obs.reset(Q[0])
    return t, obs.run(Q, U)


def test_residual_converges_to_the_external_torque_and_isolates_the_link():
    """On the model's own 2R plant a 5 N m torque on joint 1 only (a contact on link 1) is the
    residual within 0.5 % from 0.2 s after it on (0.1 % at 1 s: the arm the contact moves is settling
    under its controller), joint 2's residual stays below 1 % of it, the alarm of joint 1
    rises within 20 ms and the link is 1; no alarm before the contact."""
    t, est = _observed([5.0, 0.0])
    n = 2
    r, alarm, link = est[:, n:2 * n], est[:, 2 * n:3 * n], est[:, 3 * n]
    late = t > 0.5
    assert np.max(np.abs(r[late, 0] - 5.0)) < 0.025
    assert abs(r[-1, 0] - 5.0) < 5e-3
    assert np.max(np.abs(r[late, 1])) < 0.05
    assert not alarm[t < 0.3].any()
    first = t[np.argmax(alarm[:, 0] > 0.5)]
    assert 0.3 <= first <= 0.32
    assert np.all(link[late] == 1.0)


def test_a_torque_on_the_last_joint_names_the_last_link():
    t, est = _observed([4.0, 4.0])
    assert np.all(est[t > 0.5, -1] == 2.0)


def test_the_design_rule():
    """omega t* is where the closed loop's step response first reaches 1/3 (a simulation of
    r'' = omega^2 (1 - r) - sqrt(2) omega r'); the level gives the stated rate by Rice's formula; sigma_r
    without an encoder's noise is the std of white torque noise through that filter, simulated
    exactly per sample (5 %)."""
    from scipy.signal import cont2discrete, dlsim
    x = crossing_time(3.0)
    A, B, C = np.array([[0.0, 1.0], [-1.0, -math.sqrt(2)]]), np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, np.zeros((1, 1))), 1e-4)
    _, y, _ = dlsim((Ad, Bd, Cd, Dd, 1e-4), np.ones(40_000))
    assert np.argmax(y[:, 0] >= 1 / 3) * 1e-4 == pytest.approx(x, abs=2e-4)
    u = threshold_level(6, 20.0, 1.0)
    assert 2 * 6 * 20.0 * math.exp(-u * u / 2) * 3600 == pytest.approx(1.0, rel=1e-9)
    robot = load_robot("seed000_2r")
    d = design_momentum(robot, 1e-3, torque_noise=[1.0, 1.0], noise=0.0, quantization=0.0)
    w, dt = d["omega"], 1e-3
    assert w * (d["t_detect"] - 3 * dt - d["t_rise"] / 2) == pytest.approx(x + 1 / 4)
    Ad, Bd, Cd, Dd, _ = cont2discrete((np.array([[0.0, 1.0], [-w * w, -math.sqrt(2) * w]]),
                                       np.array([[0.0], [w * w]]), C, np.zeros((1, 1))), dt)
    e = np.random.default_rng(0).standard_normal(200_000)
    _, r, _ = dlsim((Ad, Bd, Cd, Dd, dt), e)
    assert np.std(r[1000:, 0]) == pytest.approx(d["sigma_r"][0], rel=0.05)


def test_bad_gains_are_refused_with_their_name():
    robot = load_robot("seed000_2r")
    with pytest.raises(ValueError, match="K_O"):
        observers.build("momentum", robot, K_O=[10.0, -1.0])
    with pytest.raises(ValueError, match="th0"):
        observers.build("momentum", robot, th0=[1.0, 2.0, 3.0])
