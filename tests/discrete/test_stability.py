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
    lambda dt_max = 2.6 < 2.785); under the default expmid (the model held at its midpoint
    value: the midpoint rule's 2 on that axis) the noise-aware gain is not, and "auto" (the
    default of compile_observer, the CLI and targets files) makes it stable (it keeps 1 sub-step
    and declares dt_max = 1.53 ms); the guarantee gain's k0 (integrated exactly) is stable as
    it is. The compiled observer runs."""
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
    """RK4 on z' = -k0 z alone is stable for k0 dt <= 2.7853; ETD-RK4 for any k0 >= 0."""
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=100.0)
    assert 2775 < check(spec, RK4_AT_DT).gains["k0"]["max_stable"] < 2785.3
    etd = check(spec, DEFAULT_DISCRETIZATION).gains["k0"]
    assert not etd["limit_found"] and etd["max_stable"] > 1e7


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
    damping mode needs "auto" (a shorter dt_max) under the default expmid with the reduced-order
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


def test_hybrid_default_is_stable_on_the_damped_urdf(damped):
    spec = observers.build("reduced_order_hybrid", damped)
    assert spec.design["stability"]["stable"] and check(spec, DEFAULT_DISCRETIZATION).stable


def test_auto_substeps_keeps_a_stable_discretisation():
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=100.0)
    assert auto_substeps(spec, RK4) is RK4
    with pytest.raises(UnstableDiscretization, match="k0 must be >= 0"):
        auto_substeps(spec, RK4, p=[-1.0])
