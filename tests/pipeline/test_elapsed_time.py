"""The elapsed time as an input of the generated step (jittered loops, jittered logs): step(y, u, dt),
run(Y, U, t) against the reference, bit-identity with the fixed-rate step, the first-order hold's
unbiasedness on a ramp, gaps split into sub-intervals, refused elapsed times, the declared range."""
import json
import math

import numpy as np
import pytest

from codegen import compile_observer
from codegen.discrete.stability import UnstableDiscretization, check
from codegen.families import observers
from codegen.reference import reference_observer
from codegen.verify.inputs import jittered_stamps, run_inputs
from codegen.verify.measure import relative_error
from models import load_robot

TOL = 1e-9          # C against the reference, as the cross-checks


@pytest.fixture(scope="module")
def ur5(spec_of):
    spec = spec_of("ur5")
    return spec, compile_observer(spec), reference_observer(spec)


def test_jittered_stamps_c_equals_reference(ur5):
    """1000 samples 0.7-1.6 ms apart, every 100th 10 ms (split into 5 sub-intervals of 2 ms): the
    C's run_t and the reference agree to 1e-9; so do single steps after random elapsed times,
    and the estimate without advancing equals the step's bit for bit."""
    spec, obs, ref = ur5
    Y, U = run_inputs(spec, 1000, 1e-3, seed=2)
    t = jittered_stamps(1000, 1e-3, seed=2)
    assert np.sum(np.diff(t) > 2e-3) == 9
    for o in (obs, ref):
        o.reset(Y[0])
    E = obs.run(Y, U, t)
    assert relative_error(E, ref.run(Y, U, t)) <= TOL
    rng = np.random.default_rng(5)
    for k, h in enumerate(rng.uniform(2.5e-4, 7e-3, 50)):
        y, u = Y[k] + 0.01, U[k]
        est = obs.estimate(y, u, h)
        assert np.array_equal(est, obs.step(y, u, h))
        assert relative_error(est, ref.step(y, u, h)) <= TOL
        assert relative_error(obs.state, ref.state) <= TOL


def test_uniform_stamps_are_the_fixed_step_bit_for_bit(ur5):
    """Stamps k dt (rounded, from 0 or from 1e4 s) give run(Y, U)'s estimates exactly: an interval
    equal to dt up to its stamps' rounding is dt; so does step(y, u, dt) at dt, in C and in
    the reference; in pieces a run over stamps is the same as in one go."""
    spec, obs, ref = ur5
    Y, U = run_inputs(spec, 400, 1e-3, seed=3)
    for o in (obs, ref):
        o.reset(Y[0])
        fixed = o.run(Y, U)
        for t0 in (0.0, 1e4):
            o.reset(Y[0])
            assert np.array_equal(o.run(Y, U, t0 + np.arange(400) * 1e-3), fixed)
        o.reset(Y[0])
        assert np.array_equal(np.array([o.step(y, u, 1e-3) for y, u in zip(Y, U)]), fixed)
    # 1e4 + k dt is not k dt apart in doubles: without the rule the run would differ
    assert np.any(np.diff(1e4 + np.arange(400) * 1e-3) != 1e-3)
    t = jittered_stamps(400, 1e-3, seed=3)
    obs.reset(Y[0])
    whole = obs.run(Y, U, t)
    obs.reset(Y[0])
    assert np.array_equal(np.vstack([obs.run(Y[:150], U[:150], t[:150]), obs.run(Y[150:], U[150:], t[150:])]),
                          whole)


def _ramp(robot, t):
    """q = q0 + v (t - t0) on ur5's base joint (vertical axis: M, C, g do not depend on q1) and the
    torque that holds it (constant): the model is exact along the ramp."""
    q0 = np.array([0.1, -1.0, 1.2, -0.5, 0.8, 0.3])
    v = np.array([0.7, 0.0, 0.0, 0.0, 0.0, 0.0])
    tau = np.asarray(robot.C(q0, v)) @ v + robot.F @ v + np.asarray(robot.g(q0)).ravel()
    return q0 + np.outer(t - t[0], v), np.tile(tau, (len(t), 1)), v


def test_ramp_with_jittered_stamps_gives_its_slope(ur5):
    """y = v t sampled 0.7-1.6 ms apart with 10 ms gaps, from the equilibrium est = v: the default
    (ETD-RK4, first-order hold) keeps est = v (to 1e-9 |v|: the ETD stages see the model's
    dependence on the estimate at O(h^5)), in C and in the reference; the zero-order hold with
    the same stamps settles at a / (1 - e^-a) v, a = k0 h (~1.3 % at 1 ms): the test can fail."""
    spec, obs, ref = ur5
    t = jittered_stamps(500, 1e-3, seed=4)
    Q, TAU, v = _ramp(spec.robot, t)
    for o in (obs, ref):
        o.reset(Q[0], est0=v)
        assert np.max(np.abs(o.run(Q, TAU, t) - v)) <= 1e-9 * np.linalg.norm(v)
    zoh = compile_observer(spec, hold="zoh")
    zoh.reset(Q[0], est0=v)
    assert np.max(np.abs(zoh.run(Q, TAU, t) - v)) > 1e-3 * np.linalg.norm(v)


@pytest.mark.parametrize("method", ["expmid", "expmid1"])
def test_expmid_ramp_and_jittered_stamps(ur5, tmp_path, method):
    """expmid and expmid1 (the model at the step's midpoint configuration; expmid1 once, with its
    last value as memory): the ramp of ``test_ramp_with_jittered_stamps_gives_its_slope`` keeps
    est = v (1e-9 |v|) in C and in the reference; on random inputs over jittered stamps with
    10 ms gaps (split into sub-intervals, the memory carried through them) the C equals the
    reference, and estimate() equals step() bit for bit."""
    spec = ur5[0]
    obs = compile_observer(spec, method=method, out_dir=tmp_path)
    ref = reference_observer(spec, method=method)
    t = jittered_stamps(500, 1e-3, seed=4)
    Q, TAU, v = _ramp(spec.robot, t)
    for o in (obs, ref):
        o.reset(Q[0], est0=v)
        assert np.max(np.abs(o.run(Q, TAU, t) - v)) <= 1e-9 * np.linalg.norm(v)
    Y, U = run_inputs(spec, 600, 1e-3, seed=2)
    t = jittered_stamps(600, 1e-3, seed=2)
    for o in (obs, ref):
        o.reset(Y[0])
    assert relative_error(obs.run(Y, U, t), ref.run(Y, U, t)) <= TOL
    y, u = Y[-1] + 0.01, U[-1]
    est = obs.estimate(y, u, 7e-3)
    assert np.array_equal(est, obs.step(y, u, 7e-3))
    assert relative_error(est, ref.step(y, u, 7e-3)) <= TOL


def test_a_gap_ten_times_dt_is_integrated_stably(tmp_path):
    """RK4 with k0 = 1000 at dt = 1 ms: k0 dt_max = 2 is inside RK4's limit 2.785, one step of a
    10 ms gap (k0 h = 10, |R(-10)| = 291) is not. step(y, u, 10 dt) splits it into 5 sub-intervals
    of 2 ms: the estimate stays within the reference's (which integrates the same sub-intervals)
    and converges as the flow does; a single 10 ms step of the same observer (dt = 10 ms)
    diverges."""
    robot = load_robot("seed000_2r")
    spec = observers.build("reduced_order", robot, k0=1000.0)
    obs = compile_observer(spec, method="rk4", substeps=1, out_dir=tmp_path)
    ref = reference_observer(spec, method="rk4")
    y, u = np.array([0.3, -0.2]), np.asarray(robot.g([0.3, -0.2])).ravel()
    for o in (obs, ref):
        o.reset(y, est0=[5.0, -5.0])
        o.step(y, u)
        ests = np.array([o.step(y, u, 1e-2) for _ in range(20)])
        assert np.all(np.isfinite(ests)) and np.max(np.abs(ests[-1])) < 1e-9
    assert relative_error(obs.state, ref.state) <= TOL
    big = reference_observer(spec, method="rk4", dt=1e-2, dt_max=1e-2)   # the reference checks nothing
    big.reset(y, est0=[5.0, -5.0])
    big.step(y, u)
    worst = 0.0
    with np.errstate(all="ignore"):
        try:
            for _ in range(20):
                worst = max(worst, float(np.max(np.abs(big.step(y, u)))))
        except FloatingPointError:            # overflowed to a non-finite estimate
            worst = np.inf
    assert worst > 1e6


@pytest.mark.parametrize("dt", [0.0, -1e-3, np.nan, np.inf, 1e300, 1000 * 2e-3 * (1 + 1e-15)])
def test_bad_elapsed_time_is_refused_and_the_state_kept(dt, compiled):
    """Python: a ValueError naming dt; the C (raw step_dt): ERR_BAD_ARG, the state unchanged and
    the next step as if the bad call never happened. The longest elapsed time is split_max x
    dt_max = 1000 x 2 ms."""
    obs = compiled("seed000_2r")
    y, u = np.array([0.3, -0.2]), np.array([1.0, 2.0])
    obs.reset(y)
    obs.step(y, u)
    before = obs.state
    with pytest.raises(ValueError, match="dt must be"):
        obs.step(y, u, dt)
    with pytest.raises(ValueError, match="dt must be"):
        obs.estimate(y, u, dt)
    status, _ = obs.c_step(y + 0.1, u, dt)
    assert status == obs.meta["status"]["ERR_BAD_ARG"] and np.array_equal(obs.state, before)
    after = obs.step(y + 0.1, u, 1e-3)
    obs.reset(y)
    obs.step(y, u)
    assert np.array_equal(obs.step(y + 0.1, u, 1e-3), after)
    ref = reference_observer(obs.spec)
    ref.reset(y)
    with pytest.raises(ValueError, match="dt must be"):
        ref.step(y, u, dt)


def test_stamps_checked_before_the_c(compiled):
    """Stamps that repeat or go back, a first stamp not after the last sample's, a gap beyond
    split_max x dt_max, and a primed observer whose last sample has no stamp: ValueError naming t;
    the longest allowed gap runs."""
    obs = compiled("seed000_2r")
    Y, U = np.zeros((3, 2)), np.zeros((3, 2))
    obs.reset(Y[0])
    for t, words in (([0.0, 1e-3, 1e-3], "must increase"), ([0.0, 2e-3, 1e-3], "t\\[2\\]"),
                     ([0.0, 1e-3, 3.0], "longer than 2 s"), ([0.0, np.nan, 1.0], "NaN")):
        with pytest.raises(ValueError, match=words):
            obs.run(Y, U, t)
    obs.run(Y, U, [0.0, 1e-3, 2.0])
    with pytest.raises(ValueError, match="not after the last sample"):
        obs.run(Y, U, [2.0, 2.001, 2.002])
    obs.step(Y[0], U[0], 1e-3)                  # the stamp moves on with the step: 2.001
    obs.run(Y, U, [2.0015, 2.002, 2.003])
    obs.reset(Y[0])
    obs.step(Y[0], U[0])
    with pytest.raises(ValueError, match="no time stamp"):
        obs.run(Y, U, [0.0, 1e-3, 2e-3])


def test_an_unstable_range_is_refused_with_the_fix(tmp_path):
    """RK4, k0 = 2000 at dt = 1 ms: stable at dt (k0 dt = 2 < 2.785) but not when an elapsed time
    reaches 2 ms (4): with one sub-step, refused naming the range, the smaller dt_max and the
    substeps that fix it; each fix is then stable, "auto" (the default) keeps one sub-step and
    declares the smaller dt_max, and dt_max = dt is what the check certified at dt alone."""
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=2000.0)
    with pytest.raises(UnstableDiscretization) as err:
        compile_observer(spec, method="rk4", substeps=1, out_dir=tmp_path)
    msg = str(err.value)
    assert "k0 = 2000 at dt = 0.001 with rk4" in msg and "elapsed time in [0.00025, 0.002]" in msg
    assert "at elapsed time 0.002" in msg and "or use substeps >= 2" in msg and "or dt_max <= 0.00139" in msg
    report = check(spec, spec.target(method="rk4").discretization)
    assert not report.stable and report.worst_dt == 2e-3 and 1.39e-3 < report.dt_limit < 1.3927e-3
    assert check(spec, spec.target(method="rk4", dt_max=1.39e-3).discretization).stable
    assert check(spec, spec.target(method="rk4", substeps=2).discretization).stable
    # substeps "auto" (the default) with the range not declared: the fewest sub-steps stable at dt
    # (one), and dt_max declared as the largest sample time they are stable at; a longer one is split
    auto = compile_observer(spec, method="rk4", out_dir=tmp_path).meta
    assert auto["discretization"]["substeps"] == 1 and auto["discretization"]["dt_max"] == 1.39e-3
    assert auto["target"]["discretization"]["dt_max"] == 1.39e-3 and auto["stability"]["stable"]
    obs = compile_observer(spec, method="rk4", dt_max=1e-3, out_dir=tmp_path)
    meta = obs.meta["discretization"]
    assert (meta["dt_min"], meta["dt_max"]) == (2.5e-4, 1e-3)
    header = (tmp_path / obs.prefix / f"{obs.prefix}.h").read_text()
    assert f"#define {obs.prefix.upper()}_DT_MAX 0.001" in header


def test_float_target_steps_with_the_elapsed_time(spec_of):
    """Single precision: step_dt and run_t in float against the double reference over jittered
    stamps (relative to the run's largest estimate, within the float bound of the fixed step's
    tests: 32 eps32 (1 + k0 max|y| / max|est|)), and uniform stamps are the fixed step bit for bit."""
    spec = spec_of("seed000_2r")
    obs, ref = compile_observer(spec, precision="float"), reference_observer(spec)
    Y, U = run_inputs(spec, 2000, 1e-3, seed=6)
    t = jittered_stamps(2000, 1e-3, seed=6)
    for o in (obs, ref):
        o.reset(Y[0])
    E, R = obs.run(Y, U, t), ref.run(Y, U, t)
    k0 = spec.p_default[0]
    bound = 32 * np.finfo(np.float32).eps * (1 + k0 * np.abs(Y).max() / np.abs(R).max())
    assert np.max(np.abs(E - R)) / np.abs(R).max() <= bound
    obs.reset(Y[0])
    fixed = obs.run(Y, U)
    obs.reset(Y[0])
    assert np.array_equal(obs.run(Y, U, np.arange(2000) * 1e-3), fixed)


def test_zero_order_hold_steps_over_the_next_interval(spec_of, tmp_path):
    """The zero-order hold's dt is the time to the next sample: run(Y, U, t) advances sample k over
    t[k+1] - t[k] and the last one over dt, as step(y, u, dt) with those intervals does; C and
    reference agree."""
    spec = spec_of("seed000_2r")
    obs = compile_observer(spec, hold="zoh", out_dir=tmp_path)
    ref = reference_observer(spec, hold="zoh")
    Y, U = run_inputs(spec, 300, 1e-3, seed=7)
    t = jittered_stamps(300, 1e-3, seed=7)
    H = np.append(np.diff(t), 1e-3)
    for o in (obs, ref):
        o.reset(Y[0])
    E = obs.run(Y, U, t)
    assert relative_error(E, ref.run(Y, U, t)) <= TOL
    obs.reset(Y[0])
    assert np.array_equal(np.array([obs.step(y, u, h) for y, u, h in zip(Y, U, H)]), E)


def test_metadata_and_header_record_the_range(spec_of, tmp_path):
    """The metadata's discretization holds the resolved range, the split limit and the stamp
    tolerance; the header their macros and the new entry points."""
    from codegen.pipeline.emit import emit
    spec = spec_of("seed000_2r")
    folder = emit(spec.target(dt=5e-4, dt_min=1e-4, dt_max=4e-3, name="ranged"), tmp_path, spec=spec)
    meta = json.loads((folder / "ranged.json").read_text())
    d = meta["discretization"]
    assert (d["dt"], d["dt_min"], d["dt_max"], d["split_max"]) == (5e-4, 1e-4, 4e-3, 1000)
    assert meta["target"]["discretization"]["dt_max"] == 4e-3
    assert meta["stability"]["dts"] == sorted({1e-4, 5e-4, 4e-3, math.sqrt(1e-4 * 5e-4), math.sqrt(5e-4 * 4e-3)})
    h = (folder / "ranged.h").read_text()
    for text in ("#define RANGED_DT_MIN 0.0001", "#define RANGED_DT_MAX 0.004", "#define RANGED_SPLIT_MAX 1000",
                 "#define RANGED_STAMP_TOL 8.881784197001252e-16", "int ranged_step_dt(ranged_state *s, ranged_real dt,",
                 "int ranged_run_t(ranged_state *s, long n, const ranged_real *t,", "int ranged_estimate_dt("):
        assert text in h, text
