"""The velocity bound of the model-based velocity observers (codegen.families.observers._bound):
with a large model error they stay finite where the published equations escape, inside the bound
they are the published observers bit for bit, and the samples at the bound are counted."""
import numpy as np
import pytest

from codegen import compile_observer
from codegen.families import observers
from codegen.families.observers._bound import MARGIN, velocity_bound
from codegen.reference import reference_observer
from codegen.verify import saturated_samples, saturation_mask
from codegen.verify.trajectory import demo_trajectory
from models import load_robot

# gains low enough that, with the plant's masses 3 times the model's, the published observer
# (no bound) escapes to infinity on the built-in trajectory within 2.5 s (each checked below on
# the unbounded reference); the default design of reduced_order_switched already does
NONLINEAR_K0_DIVISOR = 30.0
ESCAPING = {
    "reduced_order": {"k0": 2.65},
    "reduced_order_switched": {},
    "reduced_order_hybrid": {"gains": [2.65] * 6},
    "reduced_order_nonlinear": "designed C, k0 / 30",
    "nicosia_tomei": {"kd": 2.0, "kp": 10.0},
    "extended_state": {"omega": 2.0},
}


def _gains(family, robot):
    if family == "reduced_order_nonlinear":
        from codegen.families.design.reduced_order_nonlinear import nonlinear_gain
        d = nonlinear_gain(robot)
        return {"k0": d.k0 / NONLINEAR_K0_DIVISOR, "C": d.C}
    return ESCAPING[family]


@pytest.fixture(scope="module")
def heavy_run():
    """The built-in trajectory of seed000_2r with masses and inertias 3 times the model's:
    (q, tau) exact for the heavy arm (its inverse dynamics), qd the truth."""
    t, Q, QD, TAU = demo_trajectory(load_robot("seed000_2r", mass_scale=3.0), T=2.5)
    return Q, QD, TAU


def _unbounded(spec):
    """The plain-data description of ``spec`` without its bound: the published observer."""
    desc = spec.describe()
    options = {k: v for k, v in desc["options"].items() if k != "v_bound"}
    if options["kind"] == "VelocityBoundOptions":
        options = {"kind": "Options"}
    return {**desc, "options": options}


@pytest.mark.slow
@pytest.mark.parametrize("family", list(ESCAPING))
def test_a_large_model_error_leaves_the_estimate_finite(family, heavy_run, tmp_path):
    """Plant masses 3 x the model's: the published equations (the reference without the bound)
    end non-finite; with the bound the C and the reference run all 2501 samples with finite
    estimates, agree (relative 1e-9 of the run's largest value), and the bound was hit (so the
    run tests it)."""
    Q, QD, TAU = heavy_run
    robot = load_robot("seed000_2r")
    spec = observers.build(family, robot, **_gains(family, robot))
    free = reference_observer(_unbounded(spec))
    free.reset(Q[0])
    with pytest.raises(FloatingPointError, match="non-finite"), np.errstate(all="ignore"):
        free.run(Q, TAU)
    obs, ref = compile_observer(spec, out_dir=tmp_path), reference_observer(spec)
    runs = []
    for o in (obs, ref):
        o.reset(Q[0])
        runs.append(o.run(Q, TAU))
    est, est_ref = runs
    assert est.shape == (len(Q), spec.nest) and np.all(np.isfinite(est))
    assert np.max(np.abs(est - est_ref)) <= 1e-9 * np.max(np.abs(est_ref))
    hits = saturated_samples(est, obs)
    assert hits > 0 and hits == saturated_samples(est_ref, ref) == saturated_samples(est, spec)


def test_a_torque_offset_leaves_every_family_finite(tmp_path):
    """ur5 with a constant 20 N m offset on the elbow and the lowest gains above: every
    bounded family stays finite over the built-in trajectory (fast form of the test above)."""
    robot = load_robot("ur5")
    t, Q, QD, TAU = demo_trajectory(robot, T=1.5)
    TAU = TAU.copy()
    TAU[:, 2] += 20.0
    for family in ("reduced_order", "nicosia_tomei", "extended_state"):
        spec = observers.build(family, robot, **ESCAPING[family])
        obs = compile_observer(spec, out_dir=tmp_path)
        obs.reset(Q[0])
        assert np.all(np.isfinite(obs.run(Q, TAU))), family


def test_model_free_families_have_no_model_to_bound():
    """su_nonsmooth (model-free, linear in its state but for sg) and lotfi_namvar (the measured
    CoM forces, never the model at an estimated velocity) declare no bound; the count is 0."""
    robot = load_robot("seed002_2r")
    for family in ("su_nonsmooth", "lotfi_namvar"):
        spec = observers.build(family, robot)
        assert not getattr(spec.options, "v_bound", ()), family
        assert saturated_samples(np.full((3, spec.nest), 1e9), spec) == 0


@pytest.mark.slow
@pytest.mark.parametrize("family", ["reduced_order", "reduced_order_switched", "reduced_order_hybrid",
                                    "reduced_order_nonlinear", "nicosia_tomei", "extended_state"])
@pytest.mark.parametrize("robot_name", ["seed000_2r", "ur5"])
def test_inside_the_bound_nothing_changes(family, robot_name, tmp_path):
    """The measure of "unchanged": over the built-in trajectory (2.5 s on the planar arm, 1 s on
    ur5, from a zero estimate) at the default design, the estimates of the C with the default bound and with a bound never
    reached (1e6 rad/s) are bit-identical, and so are those of the reference with the bound and
    of the published equations (no bound); no sample is at the bound."""
    robot = load_robot(robot_name)
    if family == "reduced_order_nonlinear" and robot_name == "ur5":
        pytest.skip("the nonlinear gain's design is for the planar arm (slow on ur5)")
    t, Q, QD, TAU = demo_trajectory(robot, T=2.5 if robot.n == 2 else 1.0)
    spec = observers.build(family, robot)
    wide = observers.build(family, robot, v_bound=1e6, **({"gains": list(spec.p_default[:-3])}
                                                           if family == "reduced_order_hybrid" else
                                                           dict(zip(spec.p_names, spec.p_default))
                                                           if family != "reduced_order_nonlinear" else
                                                           {"k0": spec.p_default[0],
                                                            "C": spec.p_default[1:].reshape(robot.n, -1)}))
    assert np.array_equal(wide.p_default, spec.p_default)
    runs = []
    for o in (compile_observer(spec, out_dir=tmp_path), compile_observer(wide, out_dir=tmp_path / "w"),
              reference_observer(spec), reference_observer(_unbounded(spec))):
        o.reset(Q[0])
        runs.append(o.run(Q, TAU))
    assert np.array_equal(runs[0], runs[1])
    assert np.array_equal(runs[2], runs[3])
    assert saturated_samples(runs[0], spec) == 0


def test_the_bound_rule():
    """2 x the URDF velocity limit (ur5: 3.15, 3.2 rad/s), else 2 x v_max (seed000_2r declares no
    limit), or given; the hybrid family's v_max is the top of its schedule r_max vbar; the spec
    records it as its options and in its design report."""
    ur5, planar = load_robot("ur5"), load_robot("seed000_2r")
    assert MARGIN == 2.0
    assert velocity_bound(ur5, 2.0) == pytest.approx(2 * np.asarray(ur5.v_limit))
    assert velocity_bound(planar, 3.0) == pytest.approx([6.0, 6.0])
    assert velocity_bound(planar, 3.0, v_bound=5.0) == pytest.approx([5.0, 5.0])
    assert velocity_bound(planar, 3.0, v_bound=[5.0, 7.0]) == pytest.approx([5.0, 7.0])
    spec = observers.build("reduced_order", ur5, k0=30.0)
    assert spec.options.v_bound == pytest.approx(tuple(2 * np.asarray(ur5.v_limit)))
    assert spec.design["v_bound"] == pytest.approx(list(spec.options.v_bound))
    assert "URDF velocity limit" in spec.design["v_bound_rule"]
    hybrid = observers.build("reduced_order_hybrid", planar, gains=[1.0] * 6, vbar=2.0)
    assert hybrid.options.v_bound == pytest.approx((24.0, 24.0))
    assert observers.build("nicosia_tomei", planar, kd=5.0, kp=5.0, v_bound=[1.0, 2.0]).design["v_bound_rule"] \
        == "given (v_bound)"
    for bad in (0.0, -1.0, float("inf"), [1.0, 2.0, 3.0]):
        with pytest.raises(ValueError, match="v_bound"):
            observers.build("reduced_order", planar, k0=10.0, v_bound=bad)


def test_counting_reads_the_bound_of_any_observer(tmp_path):
    """saturated_samples and saturation_mask read the bound from a spec, a compiled observer (its
    metadata JSON), a reference observer or a description dict alike; only the velocity slots
    count (extended_state's tau_d_hat may be large); > counts, = does not."""
    robot = load_robot("seed000_2r")
    spec = observers.build("extended_state", robot, omega=20.0, v_bound=[1.0, 2.0])
    est = np.array([[0.5, 0.5, 1e3, 1e3],      # torque-error slots large: not counted
                    [1.0, -2.0, 0.0, 0.0],     # at the bound: not beyond it
                    [-1.5, 0.0, 0.0, 0.0],
                    [0.0, 2.5, 0.0, 0.0]])
    obs = compile_observer(spec, out_dir=tmp_path)
    for who in (spec, obs, reference_observer(spec), spec.describe(), obs.meta):
        assert saturated_samples(est, who) == 2
        assert saturation_mask(est, who).tolist() == [[False, False], [False, False], [True, False],
                                                      [False, True]]
