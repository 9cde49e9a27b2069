"""The reduced-order observer with a time-switched gain (codegen.families.observers.reduced_order_switched):
its design, the bumpless switch in the C and the reference, and the refusals."""
import numpy as np
import pytest

from codegen.families import observers
from codegen.families.design import reduced_order_design, switched_gains
from models import load_robot


def test_switched_design_converges_then_quiets():
    """A 1e-4 rad encoder on ur5: k0 is the convergence floor ln(200)/0.2, the final gain the
    noise-aware optimum raised to ln(200)/t_settle, the switch after the initial error has
    decayed to the predicted error at k0; no switch without noise or when the optimum is above
    the floor (10 % uncertainty)."""
    robot = load_robot("ur5")
    nd = reduced_order_design(robot, 1e-3, quantization=1e-4)
    sw = switched_gains(nd, robot.n)
    assert sw["k0"] == pytest.approx(np.log(200) / 0.2)
    assert sw["k0_final"] == pytest.approx(max(nd.k0_noise, np.log(200) / 2.0))
    assert sw["k0_final"] < sw["k0"] / 5
    assert sw["t_switch"] == pytest.approx(np.log(2.0 / sw["predicted_error"]["k0"]) / sw["k0"])
    assert 0.2 <= sw["t_switch"] < 0.5
    assert sw["predicted_error"]["k0_final"] < sw["predicted_error"]["k0"] / 5
    for kw in ({"noise": 0.0, "quantization": 0.0}, {"quantization": 1e-4, "uncertainty": 0.1}):
        other = switched_gains(reduced_order_design(robot, 1e-3, **kw), robot.n)
        assert other["k0_final"] == other["k0"] and other["t_switch"] == 0.0
    with pytest.raises(ValueError, match="t_settle"):
        switched_gains(nd, robot.n, t_settle=0.0)


def test_switch_is_bumpless_in_c_and_reference(tmp_path):
    """At rest at q = (1, 0.5) under the static torque, the estimate stays 0 (<= 1e-12) through
    the switch, in the compiled C and in the reference; without the z reset it would jump by
    (k0 - k0_final) q (~ 24 rad/s). After the switch the clock is marked done (t_switch + 1)."""
    from codegen import compile_observer
    from codegen.reference import reference_observer
    robot = load_robot("seed000_2r")
    spec = observers.build("reduced_order_switched", robot, k0=30.0, k0_final=3.0, t_switch=0.05)
    q = np.array([1.0, 0.5])
    g = np.asarray(robot.g(q)).ravel()
    for o in (compile_observer(spec, out_dir=tmp_path), reference_observer(spec)):
        o.reset(q)
        est = np.array([o.step(q, g) for _ in range(100)])
        assert np.abs(est).max() <= 1e-12
        assert o.state[-1] == 0.05 + 1.0
        assert o.state[:-1] == pytest.approx(-3.0 * q, abs=1e-12)       # z = x2hat - k0_final y


def test_the_switch_happens_at_t_switch():
    """At rest, the clock counts the samples (dt = 1e-3 s each) until the first sample at or after
    t_switch, where the switch marks it done (t_switch + 1): k0_final is in force from there."""
    from codegen.reference import reference_observer
    robot = load_robot("seed000_2r")
    spec = observers.build("reduced_order_switched", robot, k0=30.0, k0_final=3.0, t_switch=0.0105)
    ref = reference_observer(spec)
    q = np.array([0.3, -0.2])
    g = np.asarray(robot.g(q)).ravel()
    ref.reset(q)
    clocks = []
    for _ in range(15):
        ref.step(q, g)
        clocks.append(ref.state[-1])
    # step k (k = 0 first) ends at t = k dt: 11 samples later the clock passed 0.0105
    assert clocks[10] == pytest.approx(0.010) and clocks[11] == pytest.approx(1.0105)
    assert clocks[-1] == pytest.approx(1.0105)


def test_gains_are_all_given_or_all_designed():
    robot = load_robot("seed000_2r")
    with pytest.raises(ValueError, match="give all three"):
        observers.build("reduced_order_switched", robot, k0=30.0)
    with pytest.raises(ValueError, match="t_switch must be a time"):
        observers.build("reduced_order_switched", robot, k0=30.0, k0_final=3.0, t_switch=-1.0)
