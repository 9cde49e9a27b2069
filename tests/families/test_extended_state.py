"""The model-based extended-state observer (codegen.families.observers.extended_state): its design
formulas against direct simulation, and what the design chooses."""
import math

import numpy as np
import pytest

from codegen.families import observers
from codegen.families.design.noise import (extended_state_floor, extended_state_gains, extended_state_noise,
                                  extended_state_noise_gain)
from models import load_robot


def _error_dynamics(omega, dt):
    """Exact discretisation (zero-order hold on the noise, fine steps) of the per-joint error
    system driven by the measurement noise: e' = A e + b n."""
    from scipy.linalg import expm
    l1, l2, l3 = extended_state_gains(omega)
    A = np.array([[-l1, 1.0, 0.0], [-l2, 0.0, 1.0], [-l3, 0.0, 0.0]])
    b = np.array([l1, l2, l3])
    Ad = expm(A * dt)
    Bd = np.linalg.solve(A, (Ad - np.eye(3)) @ b)
    return Ad, Bd


def test_noise_formula_matches_a_simulation():
    """The stationary std of v_hat from white measurement noise (Lyapunov equation) within 3 %
    of a 200 000-sample simulation of the error dynamics (exact step, noise held per sample)."""
    omega, dt, sigma = 60.0, 1e-3, 3e-5
    Ad, Bd = _error_dynamics(omega, dt)
    rng = np.random.default_rng(0)
    e, vs = np.zeros(3), []
    for n in sigma * rng.normal(size=200_000):
        e = Ad @ e + Bd * n
        vs.append(e[1])
    assert np.std(vs[2000:]) == pytest.approx(extended_state_noise(omega, dt, sigma), rel=0.03)


def test_floor_converges_in_t_conv():
    """From a velocity error v_max the floor gain is below 1e-2 rad/s from t_conv on (and not
    from much earlier: it is the least such gain)."""
    from scipy.linalg import expm
    w = extended_state_floor(2.0, 0.2)
    l1, l2, l3 = extended_state_gains(w)
    A = np.array([[-l1, 1.0, 0.0], [-l2, 0.0, 1.0], [-l3, 0.0, 0.0]])
    v = [abs((expm(A * t) @ [0.0, 2.0, 0.0])[1]) for t in np.linspace(0.0, 1.0, 2001)]
    ts = np.linspace(0.0, 1.0, 2001)
    last_above = ts[np.nonzero(np.array(v) > 1e-2)[0][-1]]
    assert 0.195 <= last_above <= 0.2


def test_design_rises_with_uncertainty():
    """No model error: the convergence floor; 10 % uncertainty: an interior optimum above it,
    with a lower predicted error than at the floor."""
    robot = load_robot("ur5")
    exact = observers.build("extended_state", robot, quantization=1e-4)
    off = observers.build("extended_state", robot, quantization=1e-4, uncertainty=0.1)
    assert exact.design["choice"] == "convergence floor"
    assert exact.p_default[0] == pytest.approx(extended_state_floor(2.0, 0.2))
    assert off.design["choice"] == "noise-aware optimum" and off.p_default[0] > exact.p_default[0]
    n, d = robot.n, off.design
    at_floor = extended_state_noise_gain(n, 1e-3, d["sigma"], d["e_dot"], d["omega_floor"])
    assert d["predicted_error"] < math.sqrt(n * extended_state_noise(d["omega_floor"], 1e-3, d["sigma"]) ** 2
                                            + (3 * d["e_dot"] / d["omega_floor"] ** 2) ** 2)
    assert at_floor[0] == pytest.approx(d["omega"])
    assert d["stability"]["stable"]


def test_a_constant_model_error_leaves_no_bias():
    """The seed-000 arm at rest at q = (1, 0.5) while the torque is 20 % below the static one:
    the reduced-order observer settles at a velocity bias e / k0, the extended-state observer at
    0 (its d_hat takes the model error: d_hat = -FD(q, 0, 0.8 g) = 0.2 M^-1 g), and its
    torque-error output tau_d_hat = M(q) d_hat is the missing torque 0.2 g(q) (N m), in the C and
    in the reference."""
    from codegen import compile_observer
    from codegen.core.estimator import velocity_estimate
    from codegen.reference import reference_observer
    robot = load_robot("seed000_2r")
    q = np.array([1.0, 0.5])
    g = np.asarray(robot.g(q)).ravel()
    spec = observers.build("extended_state", robot, omega=40.0)
    assert spec.est_names == ["qd_hat_q1", "qd_hat_q2", "tau_d_hat_q1", "tau_d_hat_q2"]
    eso, ref = compile_observer(spec), reference_observer(spec)
    ro = compile_observer(observers.build("reduced_order", robot, k0=40.0))
    for o in (eso, ref, ro):
        o.reset(q)
        est = o.run(np.tile(q, (3000, 1)), np.tile(0.8 * g, (3000, 1)))
        o.last = est[-1]
    for o in (eso, ref):
        assert np.abs(velocity_estimate(o.last, spec.est_names)).max() < 1e-9
        assert o.last[2:] == pytest.approx(0.2 * g, rel=1e-6)
    assert np.abs(ro.last).max() > 1e-2
    M = np.asarray(robot.M(q))
    assert eso.state[4:] == pytest.approx(np.linalg.solve(M, 0.2 * g), rel=1e-6)


def test_init_takes_the_torque_error_estimate():
    """reset(y0, est0) with est0 = [v_hat(0); tau_d_hat(0)] starts d_hat at M(y0)^-1 tau_d_hat(0):
    the first estimate returns both (C and reference alike)."""
    from codegen import compile_observer
    from codegen.reference import reference_observer
    robot = load_robot("seed000_2r")
    spec = observers.build("extended_state", robot, omega=40.0)
    q = np.array([0.3, -0.7])
    est0 = np.array([0.5, -0.25, 1.5, -2.0])
    for o in (compile_observer(spec), reference_observer(spec)):
        o.reset(q, est0=est0)
        assert o.estimate(q, np.zeros(2)) == pytest.approx(est0, rel=1e-12)
        assert o.state[4:] == pytest.approx(np.linalg.solve(np.asarray(robot.M(q)), est0[2:]), rel=1e-12)
