"""Discretisation: the hold, the code shape of the step, the checks of the Discretization value."""
import numpy as np
import pytest

from codegen import compile_observer
from codegen.build import build
from codegen.emit import emit
from codegen.runtime import load


@pytest.mark.parametrize("name", ["seed000_2r", "ur5"])
def test_first_order_hold_removes_the_sampling_bias(name, spec_of):
    """With y held, an output-injection observer settles at a/(1 - exp(-a)) qd, a = k0 dt (ur5:
    k0 dt ~ 0.48, a 27 % overshoot); the first-order hold leaves only an O(dt qdd) bias."""
    from codegen.trajectory import demo_trajectory
    spec = spec_of(name)
    t, Q, QD, TAU = demo_trajectory(spec.robot, T=2.0)
    err = {}
    for hold in ("zoh", "foh"):
        obs = compile_observer(spec, hold=hold)
        obs.reset(Q[0])
        err[hold] = np.abs(obs.run(Q, TAU)[len(t) // 2:] - QD[len(t) // 2:]).max()
    a = spec.p_default[0] * 1e-3
    assert err["zoh"] > 0.5 * (a / (1 - np.exp(-a)) - 1) * np.abs(QD).max()
    assert err["foh"] < 2e-3


def test_rk4_calling_a_shared_rhs_equals_the_inlined_one(spec_of, tmp_path):
    """inline=False (the stages call one RHS routine, for big observers) gives the same numbers
    and strict C99."""
    from codegen.trajectory import demo_trajectory
    spec = spec_of("ur5")
    t, Q, QD, TAU = demo_trajectory(spec.robot, T=0.3)
    ests = []
    for inline in (True, False):
        target = emit(spec.target(hold="foh", substeps=2, inline=inline), tmp_path / str(inline), spec=spec)
        obs = load(target, build(target, strict=True, cache=tmp_path / "cache"))
        obs.reset(Q[0])
        ests.append(obs.run(Q, TAU))
    assert np.allclose(ests[0], ests[1], rtol=1e-12, atol=1e-12)


def test_compile_observer_bad_arguments(spec_of):
    with pytest.raises(ValueError, match="method"):
        compile_observer(spec_of("seed000_2r"), method="rk45")
    with pytest.raises(ValueError, match="dt must be a positive"):
        compile_observer(spec_of("seed000_2r"), dt=-1.0)
