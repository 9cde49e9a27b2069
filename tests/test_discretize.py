"""Discretisation: the hold, the code shape of the step, the checks of the Discretization value."""
import numpy as np
import pytest

from codegen import compile_observer, observers
from codegen.build import build
from codegen.emit import emit
from codegen.runtime import load
from models import load_robot


def _steady_gain(t, est, qd, t0=1.0):
    """g of the least-squares fit est = g qd - g lag qdd over t >= t0, all joints pooled."""
    m = t >= t0
    qdd = np.gradient(qd, t, axis=0)[m]
    X = np.column_stack([qd[m].ravel(), qdd.ravel()])
    return np.linalg.lstsq(X, est[m].ravel(), rcond=None)[0][0]


def _rk4_stability(z):
    return 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_default_is_unbiased_whatever_k0_dt(name, tmp_path):
    """At the guarantee gain (12) (ur5 k0 dt ~ 0.48, panda ~ 2.1): the default (ETD-RK4, first-
    order hold) has a steady gain within 1e-4 of 1; the zero-order hold settles at a / (1 - R(-a))
    with R the method's stability function: RK4's polynomial (ur5 1.262, panda 3.54), e^-a for
    ETD-RK4 (1.262, 2.43)."""
    from codegen.trajectory import demo_trajectory
    spec = observers.build("reduced_order", load_robot(name), design="guarantee")
    a = spec.p_default[0] * 1e-3
    t, Q, QD, TAU = demo_trajectory(spec.robot, T=2.5)
    expected = {("etdrk4", "foh"): 1.0, ("rk4", "zoh"): a / (1 - _rk4_stability(-a)),
                ("etdrk4", "zoh"): a / (1 - np.exp(-a))}
    for (method, hold), g in expected.items():
        obs = compile_observer(spec, method=method, hold=hold, out_dir=tmp_path)
        obs.reset(Q[0])
        tol = 1e-4 if hold == "foh" else 5e-3 * g
        assert _steady_gain(t, obs.run(Q, TAU), QD) == pytest.approx(g, abs=tol), (method, hold)


def test_etdrk4_phi_functions_and_exactness():
    """phi_k by series (|z| < 1) and closed form agree at the switch; at z = 0 they are RK4's
    1, 1/2, 1/6 exactly; an ETD-RK4 step integrates z' = -a z + c0 + c1 t exactly (the reference's
    step, written separately, agrees)."""
    import casadi as ca

    from codegen.discretize import integrator_step, phi_functions
    from codegen.reference.discretize import etdrk4_step, phi
    z = ca.SX.sym("z")
    f = ca.Function("phi", [z], list(phi_functions(z)))
    assert [float(v) for v in f(0.0)] == [1.0, 1.0, 0.5, 1.0 / 6.0]
    for x in (-1 + 1e-12, -1 - 1e-12, 0.3, -7.0):
        assert np.allclose([float(v) for v in f(x)], phi(x), rtol=1e-13, atol=0)
    a, c0, c1, h, x0 = 2146.0, 3.0, -40.0, 1e-3, 0.7
    exact = x0 * np.exp(-a * h) + c0 * (1 - np.exp(-a * h)) / a + c1 * (h / a - (1 - np.exp(-a * h)) / a ** 2)
    flow = lambda s, x: -a * x + c0 + c1 * s          # noqa: E731
    xs = ca.SX.sym("x")
    step = ca.Function("s", [xs], [integrator_step(flow, xs, 0.0, h, "etdrk4", a, [1])])
    assert float(step(x0)) == pytest.approx(exact, rel=1e-13)
    assert etdrk4_step(flow, 0.0, np.array([x0]), h, a, [1])[0] == pytest.approx(exact, rel=1e-13)


@pytest.mark.slow
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
