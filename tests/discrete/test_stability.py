"""Discrete-time stability check (codegen.discrete.stability): purpose-made unstable cases are refused
with one clear message, the default design and discretisation are stable, the C-side bound
is documented, and the same check guards parameter changes in Python and the reference."""
from pathlib import Path

import numpy as np
import pytest

from codegen import compile_observer
from codegen.families import observers
from codegen.reference import reference_observer
from codegen.discrete.stability import UnstableDiscretization, auto_substeps, check
from codegen.core.target import DEFAULT_DISCRETIZATION, Discretization
from models import load_robot

DAMPED = Path(__file__).parents[1] / "data" / "damped_arm.urdf"
RK4 = Discretization(method="rk4")                    # the default range: elapsed time up to 2 dt
RK4_AT_DT = Discretization(method="rk4", dt_max=1e-3)  # the elapsed time never above dt = 1 ms


@pytest.fixture(scope="module")
def damped():
    return load_robot(urdf=str(DAMPED))


def _damping_rate(robot):
    """max over sampled q of the eigenvalues of M(q)^-1 F."""
    return max(np.linalg.eigvals(np.linalg.solve(np.asarray(robot.M(q)), robot.F)).real.max()
               for q in robot.sample_configurations(64))


def test_damped_urdf_is_the_case_of_the_issue(damped):
    """(12) gives k0 ~ 1978 and lambda(M^-1 F) ~ 1317: (k0 + lambda) dt ~ 3.3 > RK4's 2.785."""
    k0 = observers.build("reduced_order", damped, design="guarantee").p_default[0]
    lam = _damping_rate(damped)
    assert 1900 < k0 < 2100 and 1200 < lam < 1400
    assert (k0 + lam) * 1e-3 > 2.79


def test_damped_urdf_default_design_and_discretisation_are_stable(damped, tmp_path):
    """The default (noise-aware) design and the guarantee gain (12) are both stable under ETD-RK4
    with one sub-step (it integrates k0 exactly, RK4 the damping rate lambda ~ 1300 1/s:
    lambda dt_max = 2.6 < 2.785); under the default expmid1 (the model held at its midpoint
    value, predicted from its last one: lambda h <= 1 on that axis, the midpoint rule's expmid
    2) the noise-aware gain is not, and "auto" (the default of compile_observer, the CLI and
    targets files) makes it stable (2 sub-steps at dt_max = 1.53 ms; expmid: 1 sub-step there);
    the guarantee gain's k0 (integrated exactly) is stable as it is. The compiled observer runs."""
    import dataclasses

    from codegen.discrete.stability import auto_substeps
    from codegen.verify.trajectory import demo_trajectory
    t, Q, QD, TAU = demo_trajectory(damped, T=0.5)
    etd = dataclasses.replace(DEFAULT_DISCRETIZATION, method="etdrk4")
    for design, as_is in (("noise", False), ("guarantee", True)):
        spec = observers.build("reduced_order", damped, design=design)
        report = check(spec, etd)
        assert report.stable, report
        assert check(spec, DEFAULT_DISCRETIZATION).stable == as_is == spec.design["stability"]["stable"]
        assert check(spec, auto_substeps(spec, DEFAULT_DISCRETIZATION)).stable
        obs = compile_observer(spec, out_dir=tmp_path, prefix=f"damped_{design}")
        obs.reset(Q[0])
        assert np.all(np.isfinite(obs.run(Q, TAU)))


def test_damped_urdf_with_rk4_is_refused_with_the_fix(damped, tmp_path):
    """The guarantee gain with plain RK4 at 1 kHz and one sub-step: one error naming the gain, dt
    and the fix; substeps="auto" (also the default when no substeps are given) picks the fix and
    the run stays finite. The default range lets the elapsed time reach dt_max = 2 ms:
    (k0 + lambda) dt_max ~ 6.6 needs ceil(6.6 / 2.785) = 3 substeps (2 at dt = 1 ms alone), which
    the refusal names; "auto" takes the 2 of dt and declares the dt_max they are stable at."""
    from codegen.verify.trajectory import demo_trajectory
    spec = observers.build("reduced_order", damped, design="guarantee")
    with pytest.raises(UnstableDiscretization) as err:
        compile_observer(spec, method="rk4", substeps=1, out_dir=tmp_path)
    msg = str(err.value)
    assert f"k0 = {spec.p_default[0]:.6g} at dt = 0.001 with rk4" in msg
    assert "spectral radius" in msg and "stable for 0 <= k0 <=" in msg and "substeps >= 3" in msg
    assert "dt <=" in msg and "elapsed time in [0.00025, 0.002]" in msg
    report = check(spec, RK4)
    top = report.gains["k0"]["max_stable"]
    assert report.gains["k0"]["limit_found"] and top < spec.p_default[0]
    assert check(spec, RK4, p=[0.999 * top]).stable and not check(spec, RK4, p=[1.001 * top]).stable
    assert check(spec, RK4_AT_DT).substeps_needed == 2 and report.substeps_needed == 3
    # "auto" with the range not declared: the fewest sub-steps stable at dt (2), and dt_max declared
    # as the largest sample time they are stable at (below 2 dt: 3 would be needed there)
    obs = compile_observer(spec, method="rk4", substeps="auto", out_dir=tmp_path)
    assert obs.meta["discretization"]["substeps"] == 2 and 1e-3 < obs.meta["discretization"]["dt_max"] < 2e-3
    assert check(spec, Discretization(method="rk4", substeps=2, dt_max=obs.meta["discretization"]["dt_max"])).stable
    t, Q, QD, TAU = demo_trajectory(damped, T=0.5)
    obs.reset(Q[0])
    assert np.all(np.isfinite(obs.run(Q, TAU)))


@pytest.mark.parametrize("k0,method", [(3000.0, "rk4"), (-5.0, "rk4"), (-5.0, "etdrk4")])
def test_unstable_gains_are_refused(k0, method, tmp_path):
    """k0 dt = 3 with RK4 (beyond its limit 2.785) and a negative k0 with any method."""
    robot = load_robot("seed000_2r")
    spec = observers.build("reduced_order", robot, k0=k0)
    with pytest.raises(UnstableDiscretization, match=rf"k0 = {k0:g} at dt = 0.001 with {method}"):
        compile_observer(spec, method=method, substeps=1, out_dir=tmp_path)
    if k0 > 0:          # RK4's limit (2784 at dt = 1 ms) at dt_max = 2 ms over the default range
        assert check(spec, RK4_AT_DT).gains["k0"]["max_stable"] == pytest.approx(2784, abs=2)
        assert check(spec, RK4).gains["k0"]["max_stable"] == pytest.approx(2784 / 2, abs=1)
    else:
        assert "k0 must be >= 0" in check(spec, Discretization(method=method)).message("reduced_order")


def test_etdrk4_has_no_gain_limit_and_rk4_the_textbook_one():
    """RK4 on z' = -k0 z alone is stable for k0 dt <= 2.7853; ETD-RK4 for any k0 >= 0, up to
    what double precision carries (z = x2hat - k0 y: the bound is far above any useful gain)."""
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=100.0)
    assert 2775 < check(spec, RK4_AT_DT).gains["k0"]["max_stable"] < 2785.3
    etd = check(spec, DEFAULT_DISCRETIZATION)
    top = etd.gains["k0"]["max_stable"]
    assert top > 1e7 and check(spec, DEFAULT_DISCRETIZATION, p=[0.99 * top]).stable
    above = check(spec, DEFAULT_DISCRETIZATION, p=[1.01 * top])
    assert not above.stable and above.spectral_radius <= 1 and above.rounding > above.rounding_limit


def test_header_and_metadata_record_the_bound(tmp_path):
    from codegen.pipeline.emit import emit
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=100.0)
    folder = emit(spec.target(method="rk4"), tmp_path, spec=spec)
    header = (folder / f"{folder.name}.h").read_text()
    import json
    meta = json.loads((folder / f"{folder.name}.json").read_text())
    top = meta["stability"]["gains"]["k0"]["max_stable"]       # at dt_max = 2 ms: 2.7853 / 2e-3
    assert meta["stability"]["stable"] and 2775 / 2 < top < 2785.3 / 2
    assert f"#define {folder.name.upper()}_K0_MAX_STABLE {top!r}" in header
    assert "set_params() does not check these bounds" in header


def test_params_setter_runs_the_check_in_python_and_the_reference(spec_of, tmp_path):
    """obs.params = ... (with the spec known, and from the metadata bounds alone) and the
    reference refuse an unstable or negative gain and keep the old parameters; k0 = 2000 is
    stable at dt = 1 ms (k0 dt = 2 < 2.785) but not at dt_max = 2 ms (4), so it is refused too."""
    spec = spec_of("seed000_2r")
    obs = compile_observer(spec, method="rk4", out_dir=tmp_path)
    ref = reference_observer(spec, method="rk4")
    y, u = np.array([0.3, -0.2]), np.array([1.0, 2.0])
    for o in (obs, ref):
        o.reset(y)
        o.step(y, u)
        for bad in ([3000.0], [2000.0], [-1.0]):
            with pytest.raises(ValueError, match="k0"):
                o.params = bad
        assert o.params == pytest.approx(spec.p_default)
        o.params = [1000.0]
        assert o.params == pytest.approx([1000.0])
    obs.spec = None                     # only the metadata's recorded bounds
    with pytest.raises(ValueError, match="recorded stable range"):
        obs.params = [3000.0]
    with pytest.raises(ValueError, match="k0"):
        obs.reset(y, p=[-1.0])


@pytest.mark.parametrize("name", ["seed000_2r", "seed002_2r", "seed003_2r_abs", "ur5", "panda", "damped"])
@pytest.mark.parametrize("family", ["reduced_order", "nicosia_tomei"])
def test_default_designs_are_stable_on_every_robot(name, family, damped):
    """No catalog robot gets an unstable default (design and discretisation); the damped URDF's
    damping mode needs "auto" (sub-steps, a shorter dt_max) under the default expmid1 with the reduced-order
    observer (test_damped_urdf_default_design_and_discretisation_are_stable)."""
    from codegen.discrete.stability import auto_substeps
    robot = damped if name == "damped" else load_robot(name)
    spec = observers.build(family, robot)
    assert "lowered_to_stable" not in spec.design
    if name == "damped" and family == "reduced_order":
        assert check(spec, auto_substeps(spec, DEFAULT_DISCRETIZATION)).stable
        return
    assert spec.design["stability"]["stable"]
    assert check(spec, DEFAULT_DISCRETIZATION).stable


def test_the_check_linearises_the_memory_of_expmid1(damped):
    """expmid1 keeps the model's last value as memory: the check linearises (x, m) -> (x+, m+),
    a 2n x 2n Jacobian whose memory block is not zero, at m = the model at the working point.
    On the test equation x' = -lambda x (the model alone) the memory halves the stable step,
    lambda h <= 1 against expmid's 2: on the damped arm's damping mode the check sees it
    (spectral radius 3.2 against expmid's 1.8, both refused) and "auto" asks for more sub-steps."""
    import dataclasses

    from codegen.discrete.discretize import step_jacobians
    spec = observers.build("reduced_order", damped)
    n = damped.n
    disc = dataclasses.replace(DEFAULT_DISCRETIZATION, method="expmid1")
    jac = step_jacobians(spec, disc)
    y = np.zeros(n)
    Phi = np.asarray(jac(spec.init(y, np.zeros(n), spec.p_default), y, np.zeros(n), spec.p_default, 1e-3)[0])
    assert Phi.shape == (2 * n, 2 * n) and np.abs(Phi[:, n:]).max() > 0
    radius = {m: check(spec, dataclasses.replace(disc, method=m)).spectral_radius for m in ("expmid", "expmid1")}
    assert 1 < radius["expmid"] < radius["expmid1"]
    assert auto_substeps(spec, disc).substeps > auto_substeps(spec, dataclasses.replace(disc, method="expmid")).substeps


def test_hybrid_default_is_stable_on_the_damped_urdf(damped):
    spec = observers.build("reduced_order_hybrid", damped)
    assert spec.design["stability"]["stable"] and check(spec, DEFAULT_DISCRETIZATION).stable


def test_auto_substeps_keeps_a_stable_discretisation():
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=100.0)
    assert auto_substeps(spec, RK4) is RK4
    with pytest.raises(UnstableDiscretization, match="k0 must be >= 0"):
        auto_substeps(spec, RK4, p=[-1.0])


def test_refusal_without_a_gain_limit_starts_with_its_first_fix():
    """An unstable family with no bisected gain (or none limited): the fixes start with the first
    one, not with a stray "or"; the unlocked gripper joint is named with the --lock to run."""
    from codegen.discrete.stability import StabilityReport
    stiff = {"rate": 5e4, "rate_dt": 50.0, "state": "z_finger_left", "joint": "finger_left",
             "cause": "the stiff mode (rate 5e+04 1/s = 50 / dt) is the small inertia of finger_left "
                      "(1e-06 kg m^2 seen from it), a gripper joint", "lock": "finger_left"}
    report = StabilityReport(stable=False, spectral_radius=3.0, flow_radius=1.0, step_error=0.0, dt=1e-3,
                             method="rk4", hold="foh", substeps=1, substeps_needed=2, stiff_mode=stiff)
    for form, first in (("python", "use substeps >= 2"), ("cli", "use --substeps 2 (or more)")):
        msg = report.message("su_nonsmooth", form=form)
        assert "; or" not in msg and f"a gripper joint; {first}" in msg, msg
    assert "or lock finger_left: --lock finger_left=0" in report.message("su_nonsmooth", form="cli")


# ---------------------------------------------------------------- issue 22: F1-F4, F6
def _cli(capsys, *argv):
    """(exit code, stderr) of ``python -m codegen`` run in-process."""
    from codegen import cli
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as e:
        code = e.code
    return code, capsys.readouterr().err


def test_switched_gain_after_the_switch_is_checked(tmp_path, capsys):
    """F1: k0_final = 5000 with RK4 (k0_final dt_max = 10 > 2.785) is refused however it is given
    (a build parameter, the spec's gains, the command line): the check linearises at the clock
    after the switch too, and k0_final gets the same bound as reduced_order's k0."""
    from codegen.discrete.stability import UnstableDiscretization
    robot = load_robot("seed000_2r")
    spec = observers.build("reduced_order_switched", robot)
    k0, _, t_switch = spec.p_default
    report = check(spec, RK4, p=[k0, 5000.0, t_switch])
    assert not report.stable and report.gains["k0_final"]["limit_found"]
    top = report.gains["k0_final"]["max_stable"]
    assert top == pytest.approx(check(observers.build("reduced_order", robot, k0=100.0), RK4)
                                .gains["k0"]["max_stable"], rel=1e-3)
    given = observers.build("reduced_order_switched", robot, k0=k0, k0_final=5000.0, t_switch=t_switch)
    with pytest.raises(UnstableDiscretization, match="k0_final = 5000 .*stable for 0 <= k0_final <="):
        compile_observer(given, method="rk4", substeps=1, out_dir=tmp_path)
    code, err = _cli(capsys, "build", "seed000_2r", "--family", "reduced_order_switched", "--method", "rk4",
                     "--substeps", "1", "--param", "k0_final=5000", "--out", tmp_path)
    assert code != 0 and "k0_final = 5000" in err and "--substeps" in err
    # "auto" finds the sub-steps k0_final needs; the header's bound is a real one; a run across
    # the switch at t_switch stays bounded
    from codegen.verify.trajectory import demo_trajectory
    obs = compile_observer(given, method="rk4", out_dir=tmp_path)
    assert obs.meta["discretization"]["substeps"] >= 2
    assert obs.meta["stability"]["gains"]["k0_final"]["limit_found"]
    t, Q, QD, TAU = demo_trajectory(robot, T=0.6)
    obs.reset(Q[0])
    assert np.abs(obs.run(Q, TAU)[t > t_switch + 0.1] - QD[t > t_switch + 0.1]).max() < 1.0


def test_non_finite_step_is_unstable(compiled):
    """F2: a gain that overflows the step is refused, not judged stable for want of a verdict:
    extended_state omega = 1e80 (1e30 already was) and reduced_order k0 = 1e300 with RK4 and
    with ETD-RK4 (``obs.params``)."""
    robot = load_robot("seed000_2r")
    eso = observers.build("extended_state", robot)
    for omega in (1e30, 1e80):
        assert not check(eso, DEFAULT_DISCRETIZATION, p=[omega], bounds=False).stable
    ro = observers.build("reduced_order", robot)
    report = check(ro, RK4, p=[1e300])
    assert not report.stable and not report.evaluable
    assert "not finite" in report.message("reduced_order") and "stable for 0 <= k0 <=" in report.message("reduced_order")
    obs = compiled("seed000_2r")
    with pytest.raises(UnstableDiscretization, match="k0 = 1e\\+300"):
        obs.params = [1e300]


def test_overflowing_gain_or_dt_names_itself(tmp_path, capsys):
    """F3: --param k0=1e300 and --dt 1e308 are refused naming the gain (with its stable range)
    or dt (with the largest the precision holds), not as a C literal that is not finite."""
    code, err = _cli(capsys, "build", "seed000_2r", "--param", "k0=1e300", "--out", tmp_path)
    assert code != 0 and "k0 = 1e+300" in err and "stable for 0 <= k0 <=" in err
    assert "non-finite default" not in err
    code, err = _cli(capsys, "build", "seed000_2r", "--dt", "1e308", "--out", tmp_path)
    assert code != 0 and "dt = 1e+308" in err and "at most 1.8e+308" in err
    assert "non-finite default" not in err


def test_gains_are_bounded_by_the_precision():
    """F4: z = x2hat - k0 y stores k0 y: the estimate's rounding error u k0 |y| must stay within
    2^-26 (double) or 2^-12 (float) of its size. k0 = 1e17 with ETD-RK4 (stable: no growth) is
    refused with the bound in the message; the float bound is (u_double / u_float)^(1/2) = 2^-14.5
    of the double one, and a gain between the two is refused in float only."""
    spec = observers.build("reduced_order", load_robot("seed000_2r"))
    report = check(spec, DEFAULT_DISCRETIZATION, p=[1e17])
    assert not report.stable and report.spectral_radius <= 1
    assert report.rounding > 10                      # the 33 rad/s the issue measured
    msg = report.message("reduced_order")
    top = check(spec, DEFAULT_DISCRETIZATION, p=[1e7]).gains["k0"]["max_stable"]
    import re
    assert "rounding error" in msg
    assert float(re.search(r"stable for 0 <= k0 <= ([0-9.e+]+)", msg).group(1)) == pytest.approx(top, rel=1e-3)
    single = check(spec, DEFAULT_DISCRETIZATION, precision="float").gains["k0"]
    assert single["limit_found"] and single["max_stable"] == pytest.approx(top * 2.0 ** -14.5, rel=1e-3)
    between = [10 * single["max_stable"]]
    assert check(spec, DEFAULT_DISCRETIZATION, p=between).stable
    assert not check(spec, DEFAULT_DISCRETIZATION, p=between, precision="float").stable


def test_float_clock_that_cannot_reach_t_switch_is_refused(tmp_path):
    """F6: a float clock s += h stalls where h < ulp(s) / 2 (s = 2^15 s at h = dt / 4 = 0.25 ms)
    and drifts before it: t_switch = 40000 s in float is refused with the bound (clock_limit:
    2.1 s at dt = 1 ms); double reaches it. At the bound the float clock, simulated, is within
    one sample of the time."""
    robot = load_robot("seed000_2r")
    spec = observers.build("reduced_order_switched", robot)
    k0, k0_final, _ = spec.p_default
    late = observers.build("reduced_order_switched", robot, k0=k0, k0_final=k0_final, t_switch=40000.0)
    with pytest.raises(UnstableDiscretization, match="t_switch = 40000 s") as err:
        compile_observer(late, precision="float", out_dir=tmp_path)
    from codegen.discrete.stability import clock_limit
    bound = clock_limit(1e-3, 2.5e-4, "float")
    assert f"t_switch <= {bound:.6g} s" in str(err.value) and 2.0 < bound < 2.2
    assert check(late, DEFAULT_DISCRETIZATION).stable
    h, s = np.float32(2.5e-4), np.float32(0.0)
    for _ in range(int(bound / 2.5e-4)):
        s = np.float32(s + h)
    assert abs(float(s) - int(bound / 2.5e-4) * float(h)) <= 1e-3
    assert np.float32(np.float32(39999.9) + h) == np.float32(39999.9)   # the stall of the issue


def test_every_scheduled_gain_of_the_hybrid_is_checked():
    """The hybrid observer switches among k_1 .. k_r_max: each one, set alone to 5000 with RK4
    (5000 dt_max = 10 > 2.785), is refused (the check linearises at every logic state, the
    estimate in its band), the cause named as the gain's rate, not the robot's inertia."""
    spec = observers.build("reduced_order_hybrid", load_robot("seed000_2r"))
    assert check(spec, RK4).stable
    for r in (2, 6):
        p = spec.p_default.copy()
        p[spec.p_names.index(f"k_{r}")] = 5000.0
        report = check(spec, RK4, p=p)
        assert not report.stable and report.spectral_radius > 100
        assert "the gain's own rate 5e+03 1/s" in report.message(spec.family)


def test_auto_substeps_refuses_what_substeps_cannot_fix_at_once():
    """A gain beyond the precision's bound with RK4 both grows and loses the estimate: sub-steps
    fix the growth, not the rounding, so "auto" refuses at once, naming the rounding error."""
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=1e9)
    with pytest.raises(UnstableDiscretization, match="rounding error") as err:
        auto_substeps(spec, RK4)
    assert "no substeps" not in str(err.value)


def test_auto_substeps_refused_does_not_suggest_itself():
    """A stiff friction no SUBSTEPS_MAX sub-steps hold: the refusal of "auto" names the step that
    would do (dt <=) and no longer "or substeps="auto" to choose them", which was just tried; a
    fixed substeps count's refusal still suggests it."""
    robot = load_robot(urdf=Path(__file__).parents[1] / "data" / "two_link.urdf").with_friction(
        coulomb=[2.0, 2.0], width=1e-3)
    spec = observers.build("reduced_order", robot)
    disc = Discretization(dt=5e-3, substeps="auto")
    with pytest.raises(UnstableDiscretization, match="no substeps <= 64 is stable") as err:
        auto_substeps(spec, disc)
    assert "dt <= " in str(err.value) and "auto" not in str(err.value)
    assert "--dt " in err.value.cli_message and "auto" not in err.value.cli_message
    fixed = check(spec, Discretization(dt=5e-3, substeps=1))
    assert 'substeps="auto" to choose them' in fixed.message(spec.family)


def test_widest_range_is_computed_once(monkeypatch):
    """auto_substeps' bisection for dt_max is cached as the check's reports are: compare ran it
    again each time (100 s for panda's identified model at 50 sub-steps); the second call does
    not linearise the step."""
    import codegen.discrete.stability as stability
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=1000.0)
    first = stability.widest_range(spec, RK4_AT_DT)

    def fail(*args, **kwargs):
        raise AssertionError("linearised again")
    monkeypatch.setattr(stability, "_Linearisation", fail)
    assert stability.widest_range(spec, RK4_AT_DT) == first


def test_the_bound_search_grows_on_its_probe_and_returns_what_ok_accepts():
    """_largest with a cheaper probe (the gain's growth on one sample time): the probe alone
    decides the growth, ok is asked only of the bracket and of the value returned; where the probe
    passes values ok refuses, the value returned is still ok's (the search redone with ok)."""
    from codegen.discrete.stability import BISECTIONS, _largest
    calls = []

    def counted(limit):
        def ok(v):
            calls.append(v)
            return v <= limit
        return ok
    # stable everywhere searched: 10 growths on the probe, one call of ok (the value returned)
    v, found = _largest(counted(1e9), 0.0, 1.0, 10, probe=lambda v: True)
    assert (v, found) == (4.0 ** 10, False) and calls == [4.0 ** 10]
    # the probe fails where ok does: the same bracket and bound as ok alone, fewer calls of ok
    calls.clear()
    alone = _largest(lambda v: v <= 10.0, 0.0, 1.0, 10)
    assert _largest(counted(10.0), 0.0, 1.0, 10, probe=lambda v: v <= 10.0) == alone
    assert len(calls) == 1 and 10 * (1 - 2.0 ** -12) < alone[0] <= 10
    # a probe weaker than ok (it passes 10 < v <= 1000): the result is ok's bound all the same
    v, found = _largest(counted(10.0), 0.0, 1.0, 10, probe=lambda v: v <= 1000.0)
    assert (v, found) == alone


def test_the_bisection_on_a_probe_keeps_the_bracket_of_ok_alone():
    """_bisect with a probe that passes values ok refuses (it tests one part of ok: a sample time
    or a working point) and learns that part when ok refuses what it passed, as _max_stable's
    does: the halving ok refuses is taken the other way, and the bracket is ok's own; ok is
    asked of the values the probe left, not of every halving."""
    from codegen.discrete.stability import BISECTIONS, _bisect
    limits = {"a": 7.3, "b": 5.1}            # ok: every part; the probe: the parts it knows
    known, calls = ["a"], []

    def ok(v):
        calls.append(v)
        bad = [k for k, limit in limits.items() if v > limit]
        known.extend(k for k in bad[:1] if k not in known)
        return not bad

    alone = _bisect(lambda v: v <= 5.1, 0.0, 16.0)
    assert _bisect(ok, 0.0, 16.0, probe=lambda v: all(v <= limits[k] for k in known)) == alone
    assert alone[0] <= 5.1 < alone[1] and alone[1] - alone[0] == 16.0 / 2 ** BISECTIONS
    assert known == ["a", "b"] and len(calls) <= 3


@pytest.fixture(scope="module")
def extended():
    return observers.build("extended_state", load_robot("seed000_2r"))


def _counted(monkeypatch, lin):
    """The number of point-evaluations of ``lin``'s mapped Jacobian (a list, updated)."""
    count = [0]
    _map = lin._map

    def counted(n):
        count[0] += n
        return _map(n)
    monkeypatch.setattr(lin, "_map", counted)
    return count


def test_the_verdict_is_that_of_every_point_and_an_unstable_one_costs_one_point(extended, monkeypatch):
    """_Linearisation.stable tries the point and sample time that failed last first: its verdict
    is that of all radii (``radii``) around the gain's bound, and once a value has failed, the
    next unstable one is found on that one point (16 points x 5 sample times in all)."""
    from codegen.discrete.stability import TOL, _Linearisation, sample_times
    disc = Discretization(dt=1e-3)
    lin, dts = _Linearisation(extended, disc), sample_times(disc)
    i = extended.p_names.index("omega")
    count = _counted(monkeypatch, lin)
    for omega in (100.0, 1200.0, 1380.0, 1400.0, 3000.0, 1e5):
        p = extended.p_default.copy()
        p[i] = omega
        assert lin.stable(p, dts) == bool(np.all(lin.radii(p, dts)[2] <= 1 + TOL)), omega
    p[i] = 2e5
    count[0] = 0
    assert not lin.stable(p, dts) and count[0] == 1
    assert len(dts) == 5 and lin.S == 16


def test_the_gain_bound_is_that_of_the_full_check_at_a_third_of_its_cost(extended, monkeypatch):
    """_max_stable (a probe on the sample times and points that failed, the value found confirmed
    on all) finds the bracket the full check at every halving finds (all points, all sample
    times), in under a third of its point-evaluations (the search that tried the last failing
    sample time first, and all points, took 0.45 of them)."""
    from codegen.discrete.stability import TOL, _Linearisation, _largest, _max_stable, sample_times
    disc = Discretization(dt=1e-3)
    lin, dts = _Linearisation(extended, disc), sample_times(disc)
    p, idx = extended.p_default, [extended.p_names.index("omega")]
    count = _counted(monkeypatch, lin)

    def full(v):
        q = p.copy()
        q[idx] = v
        return bool(np.all(lin.radii(q, dts)[2] <= 1 + TOL)) and lin.precise(q)
    bound = _largest(full, 0.0, float(p[idx[0]]), 10)
    cost, count[0] = count[0], 0
    assert _max_stable(lin, p, idx, dts) == bound and bound[1]
    assert count[0] < cost / 3


def test_a_second_parameter_vector_of_the_same_spec_is_checked_without_linearising_again(extended, monkeypatch):
    """check keeps the step's Jacobian of the last specs in the process (``linearisation``):
    tune and compare check many parameter vectors of one spec, and building it costs as much as
    a search (0.9 s for kalman_model on ur5). Another method is another linearisation."""
    import codegen.discrete.stability as stability
    disc, p = Discretization(dt=1e-3), extended.p_default * 1.5
    stability._linearisations.clear()
    fresh = check(extended, disc, p, cache=False)
    check(extended, disc, cache=False)

    def fail(*args, **kwargs):
        raise AssertionError("linearised again")
    monkeypatch.setattr(stability, "_Linearisation", fail)
    assert check(extended, disc, p, cache=False) == fresh      # the same report as a fresh one
    with pytest.raises(AssertionError, match="linearised again"):
        check(extended, Discretization(dt=1e-3, method="rk4"), cache=False)
