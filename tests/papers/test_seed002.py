"""Seed 002: non-minimal kinematics, the Lotfi–Namvar adaptive observer, the Su–Müller–Zheng
observer, their C against the numpy reference, and the §V experiment (short horizons here;
the full runs are `python -m codegen simulate seed002 | seed002-noisy | seed002-noise-3mrad |
seed002-ur5`)."""
import casadi as ca
import numpy as np
import pytest

from codegen import compile_observer
from codegen.families import observers
from codegen.families.observers._nonminimal import (conditioning, gravity_vector, moving_rows,
                                           nonminimal, observable_joints, select_rows)
from codegen.reference import reference_observer
from codegen.reference.robots import reference_robot
from codegen.verify import random_inputs, relative_error
from models import load_robot

TOL_C = 1e-9          # emitted C vs reference, relative (docs/architecture.md §4)
TOL_KIN = 1e-12       # symbolic kinematics vs closed form / pinocchio, relative to the scale


@pytest.fixture(scope="module")
def r2():
    return load_robot("seed002_2r")


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")


def _configs(robot, count=20, seed=5):
    return np.random.default_rng(seed).uniform(-np.pi, np.pi, (count, robot.n))


# ------------------------------------------------------------------------ non-minimal kinematics
@pytest.mark.parametrize("name", ["seed002_2r", "ur5"])
def test_com_kinematics_match_independent_reference(name):
    """p, J_p and Jdot_p qd of our SX kinematics against the reference: the closed form (34) and
    its derivative for seed002_2r; pinocchio (oMi * lever, joint Jacobians, classical
    accelerations) for ur5."""
    robot = load_robot(name)
    ref = reference_robot(robot.source)
    nm = nonminimal(robot)
    q, v = ca.SX.sym("q", robot.n), ca.SX.sym("v", robot.n)
    all_rows = list(range(robot.dim * robot.n))
    bias = ca.Function("b", [q, v], [ca.jtimes(ca.jtimes(robot.com_positions(q), q, v), q, v)])
    nm_bias = ca.Function("nb", [q, v], [nm.bias(q, v)])
    rng = np.random.default_rng(1)
    for qk in _configs(robot):
        vk = rng.normal(size=robot.n) * 3
        assert np.abs(np.asarray(robot.com(qk)).ravel() - ref.com_positions(qk)).max() <= TOL_KIN
        J = np.asarray(robot.Jcom(qk))
        assert np.abs(J - ref.com_jacobian(qk)).max() <= TOL_KIN
        b_ref = ref.com_bias(qk, vk)
        assert np.abs(np.asarray(bias(qk, vk)).ravel() - b_ref).max() <= TOL_KIN * np.abs(b_ref).max()
        assert np.allclose(np.asarray(nm_bias(qk, vk)).ravel(), b_ref[nm.rows], rtol=0, atol=1e-12 * np.abs(b_ref).max())
    assert len(all_rows) == len(ref.com_positions(_configs(robot)[0]))


def test_closed_form_34_entries(r2):
    """J_p of (34) written out: rows 1, 2 of joint 2 vanish; the rest by hand."""
    q = np.array([0.3, -1.1])
    lc1, l1, lc2 = 0.2, 0.4, 0.1
    s1, c1, s12, c12 = np.sin(q[0]), np.cos(q[0]), np.sin(q.sum()), np.cos(q.sum())
    J34 = np.array([[-lc1 * s1, lc1 * c1, -l1 * s1 - lc2 * s12, l1 * c1 + lc2 * c12],
                    [0.0, 0.0, -lc2 * s12, lc2 * c12]]).T                     # [S002 (34)]
    assert np.abs(np.asarray(r2.Jcom(q)) - J34).max() <= 1e-15


def test_rows_joints_and_gravity(r2, ur5):
    assert moving_rows(r2) == [0, 1, 2, 3] and observable_joints(r2, [0, 1, 2, 3]) == [0, 1]
    assert np.array_equal(gravity_vector(r2), [0.0, -9.81])
    assert np.array_equal(gravity_vector(ur5), [0.0, 0.0, -9.81])
    # ur5 (example-robot-data): the shoulder CoM lies on axis 1 and the wrist_2/3 CoMs on the
    # axes of joints 5, 6, so J_p has rank 4: rows 0..2 are zero, joints 5, 6 are unobservable
    rows = moving_rows(ur5)
    assert rows == list(range(3, 18))
    assert observable_joints(ur5, rows) == [0, 1, 2, 3]
    J = np.asarray(ur5.Jcom(_configs(ur5)[0]))
    assert np.abs(J[:3]).max() == 0.0 and np.abs(J[:, 4:]).max() < 1e-15


def test_row_selection_maximises_worst_conditioning(r2):
    best = select_rows(r2, 2)
    assert len(best) == 2
    c_best = conditioning(r2, best)
    for pair in ([0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]):
        assert conditioning(r2, pair) <= c_best + 1e-15
    assert conditioning(r2, [0, 1, 2, 3]) > c_best      # the seed's four rows: better conditioned
    with pytest.raises(ValueError, match="need 2 <= k <= 4"):
        select_rows(r2, 5)


@pytest.mark.parametrize("name", ["seed002_2r", "ur5"])
def test_force_signal_sign_convention(name):
    """docs/papers/seed002.md §3.1: f_{f,i} = m_i (J_p^i qdd + Jdot_p^i qd - g_o). At rest under gravity
    compensation (tau = g(q)) f_f = -m g_o (the supporting force); in motion it equals the
    reference's m (J_p qdd + Jdot_p qd - g_o) with qdd from pinocchio / closed-form dynamics."""
    robot = load_robot(name)
    ref = reference_robot(robot.source)
    nm = nonminimal(robot)
    f = nm.force_function()
    mass = 1.0 / nm.theta
    rng = np.random.default_rng(2)
    for qk in _configs(robot, 5):
        ff = np.asarray(f(qk, np.zeros(robot.n), ref.g(qk))).ravel()
        assert np.allclose(ff, -mass * nm.a, rtol=0, atol=1e-10 * np.abs(mass * nm.a).max())
        vk, tau = rng.normal(size=robot.n), ref.g(qk) + rng.normal(size=robot.n)
        qdd = ref.forward_dynamics(qk, vk, tau)
        expect = mass * ((ref.com_jacobian(qk) @ qdd + ref.com_bias(qk, vk))[nm.rows] - nm.a)
        got = np.asarray(f(qk, vk, tau)).ravel()
        assert np.abs(got - expect).max() <= 1e-9 * np.abs(expect).max()


# ------------------------------------------------------------------------ C against the reference
CASES = {
    "lotfi_2r": ("seed002_2r", "lotfi_namvar", {}),
    "lotfi_2r_projection": ("seed002_2r", "lotfi_namvar", {"projection": True, "theta_max": 2.0}),
    "su_literal": ("seed002_2r", "su_nonsmooth", {}),
    "su_xian_tanh": ("seed002_2r", "su_nonsmooth", {"form": "xian", "smoothing_eps": 1e-4}),
    "lotfi_ur5": ("ur5", "lotfi_namvar", {}),
}


def _cross_check(spec, count, dt=1e-4):
    """Worst relative errors of the C against the reference: single steps (estimate, next state,
    RHS) from `count` random (x, y, u), then a run of `count` samples."""
    obs = compile_observer(spec, dt=dt, method="rk4", hold="zoh")
    ref = reference_observer(spec, dt=dt, method="rk4", hold="zoh")
    X, Y, U = random_inputs(spec, count, seed=3)
    worst = {"est": 0.0, "state": 0.0, "rhs": 0.0}
    for x, y, u in zip(X, Y, U):
        obs.state = x
        ref.reset(y)
        ref.state = x
        worst["est"] = max(worst["est"], relative_error(obs.step(y, u), ref.step(y, u)))
        worst["state"] = max(worst["state"], relative_error(obs.state, ref.state))
        worst["rhs"] = max(worst["rhs"], relative_error(obs.rhs(x, y, u), ref.rhs(x, y, u)))
    # a run: a slow random walk of the measurements around the first random sample
    rng = np.random.default_rng(4)
    Yr = Y[0] + np.cumsum(1e-3 * rng.normal(size=Y.shape), axis=0) * np.maximum(1.0, np.abs(Y[0]))
    obs.reset(Yr[0]), ref.reset(Yr[0])
    worst["run"] = relative_error(obs.run(Yr, U), ref.run(Yr, U))
    return worst


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_emitted_c_equals_reference(case):
    name, family, kw = CASES[case]
    spec = observers.build(family, load_robot(name), **kw)
    worst = _cross_check(spec, count=1000)
    assert max(worst.values()) <= TOL_C, worst


def test_projection_keeps_thetahat_in_the_box(r2):
    spec = observers.build("lotfi_namvar", r2, projection=True, theta_min=0.4, theta_max=2.0)
    obs = compile_observer(spec, dt=1e-4)
    y = np.concatenate([[0.1, 0.2], [0.0, 19.62, 0.0, 9.81]])
    obs.reset(y)
    est = obs.step(y, np.zeros(2))
    assert np.array_equal(est[-4:], [2.0, 2.0, 0.5, 0.5])   # Table II's 3, 3 clipped to 2


def test_table_ii_defaults_and_sizes(r2, ur5):
    spec = observers.build("lotfi_namvar", r2)
    p = spec.params
    assert [p[f"gamma_{c}"] for c in ("link1_x", "link1_y", "link2_x", "link2_y")] == [200, 250, 250, 100]
    assert [p[f"thetahat0_{c}"] for c in ("link1_x", "link1_y", "link2_x", "link2_y")] == [3, 3, 0.5, 0.5]
    assert p["projection"] == 0.0 and p["zhat1_from_y0"] == 0.0
    assert (spec.nx, spec.ny, spec.nu, spec.nest) == (16, 6, 2, 10)
    s5 = observers.build("lotfi_namvar", ur5)
    assert (s5.nx, s5.ny, s5.nest) == (60, 21, 4 + 30)
    su = observers.build("su_nonsmooth", r2)
    assert (su.nx, su.ny, su.nu, su.nest) == (4, 2, 2, 4)
    with pytest.raises(ValueError, match="form must be"):
        observers.build("su_nonsmooth", r2, form="other")


# ------------------------------------------------------------------------ the experiment
@pytest.fixture(scope="module")
def nominal():
    from codegen.evaluate.scenarios.seed002 import experiment, summarize
    return summarize(experiment(T=4.0, noise=0.0))


def test_nominal_run_converges(nominal):
    """Noise-free §V run, 4 s: thetahat -> (0.5, 0.5, 1, 1) within 2e-3; the link-velocity and
    joint-velocity errors at the end are at the O(dt) level of the sampled (held) measurement."""
    s = nominal
    assert np.abs(np.array(s["thetahat_final"]) - [0.5, 0.5, 1.0, 1.0]).max() <= 2e-3, s
    assert s["nu_err_final_max"] <= 5e-3 and s["nu_err_rms_ss"] <= 5e-3, s
    assert s["qd_err_final_max"] <= 0.05 and s["qd_err_rms_ss_adaptive"] <= 0.05, s
    assert s["qd_err_final_max_su"] <= 0.5, s          # (35) converges too, with chattering


@pytest.mark.parametrize("noise,margin", [(0.003, 4.0), (0.03, 2.0)])
def test_adaptive_is_less_noise_sensitive(nominal, noise, margin):
    """std = 3 mrad and 30 mrad at 1 kHz: steady-state (last 1 s of 4 s) velocity-error RMS of
    the adaptive observer well below that of (35) (measured: 0.14 vs 2.05 and 1.38 vs 3.81 rad/s
    over 5 s). At the "30 %" reading (docs/papers/experiments.md) (~0.21 rad) the order reverses (9.5 vs 7.2): see the
    seed002-noisy scenario and the closing note."""
    from codegen.evaluate.scenarios.seed002 import experiment, summarize
    s = summarize(experiment(T=4.0, noise=noise))
    assert s["qd_err_rms_ss_adaptive"] * margin < s["qd_err_rms_ss_su"], s


def test_scenario_c_equals_reference():
    """The same short run with the compiled observers and with the numpy reference."""
    from codegen.evaluate.scenarios.seed002 import experiment
    kw = dict(T=0.05, noise=0.003)
    c, r = experiment(reference=False, **kw), experiment(reference=True, **kw)
    for key in ("qd_hat", "nu_hat", "theta_hat", "su_est"):
        assert relative_error(c[key], r[key]) <= 1e-8, key


@pytest.mark.slow
def test_ur5_tracking_run_converges():
    """Beyond the paper: ur5 (m = 3, 15 CoM rows, joints 1-4 observable), 10 s of sinusoidal
    tracking: the joint-velocity error falls from O(1) rad/s to below 0.02 rad/s."""
    from codegen.evaluate.scenarios.seed002 import experiment, summarize
    d = experiment("ur5", T=10.0, dt=1e-3, su=False, substeps=2, T_ss=1.0)
    e = np.abs(d["qd_hat"] - d["qd"][:, d["joints"]])
    t = d["t"]
    assert e[t < 1.0].max() > 0.5
    assert e[t >= 9.0].max() < 0.02, e[t >= 9.0].max()
    s = summarize(d)
    assert np.abs(np.array(s["thetahat_final"]) / s["theta_true"] - 1).max() < 0.1, s


# ------------------------------------------------------------------ the two open claims
def test_transient_is_set_by_the_adaptation():
    """Noise-free, [0.5, 1) s: with Table II the adaptive observer trails (35) (measured 5.84 vs
    3.56 rad/s); with the adaptation four times faster, or thetahat(0) = theta, it leads. So the
    paper's "faster" rests on the adaptation, not on the observer structure."""
    from codegen.evaluate.scenarios.seed002 import TABLE_II_GAMMA, experiment, windowed_rms
    paper = windowed_rms(experiment(T=1.0), windows=((0.5, 1.0),))
    assert paper["adaptive"][0] > 1.3 * paper["su"][0], paper
    for gains in ({"gamma": 4 * TABLE_II_GAMMA}, {"thetahat0": [0.5, 0.5, 1.0, 1.0]}):
        w = windowed_rms(experiment(T=1.0, gains=gains), windows=((0.5, 1.0),))
        assert w["adaptive"][0] < w["su"][0] and w["su"][0] == paper["su"][0], (gains, w)


def test_flip_noise_bisection_brackets_a_sign_change():
    """Short runs (2 s, steady state = last 1 s): the bisection ends on a bracket of relative width
    <= 10 % whose ends give opposite orderings, inside (0.03, 0.3) rad."""
    from codegen.evaluate.scenarios.seed002 import flip_noise, ordering
    f = flip_noise(T=2.0, rel_tol=0.1)
    lo, hi = f["bracket"]
    assert 0.03 < lo < f["std_rad"] < hi < 0.3 and hi / lo <= 1.1
    assert ordering(lo, T=2.0) < 0 < ordering(hi, T=2.0)
    with pytest.raises(ValueError, match="no flip"):
        flip_noise(lo=0.01, hi=0.02, T=2.0)
