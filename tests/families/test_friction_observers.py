"""Observer families and tools on robots with Coulomb friction and torque offsets:

    tau_f(v) = viscous v + coulomb tanh(v / w) + offset

compiled C against the independent reference (codegen.verify.cross_check) for the reduced-order
and extended-state observers of tests/data/friction_arm.urdf (URDF damping and friction, side-file
offsets and w); the families that use the friction directly (Tomei, I&I AOV, Spong's manifold
law) symbolic against their reference; the sweep's model plant keeps the friction unscaled."""
from pathlib import Path

import numpy as np
import pytest

from codegen.reference import reference_observer

DATA = Path(__file__).parents[1] / "data"
ARM = DATA / "friction_arm.urdf"
TOL = 1e-9


def _rel(a, b):
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


def _arm():
    from models import load_robot
    robot = load_robot(urdf=ARM)
    assert robot.coulomb.all() and robot.offset.any() and robot.coulomb_width == 0.1
    return robot


@pytest.mark.parametrize("family", ["reduced_order", pytest.param("extended_state", marks=pytest.mark.slow)])
def test_compiled_observer_with_friction_equals_reference(family):
    """The C of the observer (default ETD-RK4, first-order hold, dt = 1e-3: stable with w = 0.1)
    against the reference rebuilt from the robot's source (pinocchio's model.friction, the side
    file's offsets and width carried in the source): steps, RHS and a run, relative 1e-9; and the
    friction changes the RHS by far more than that (the check is not vacuous)."""
    from codegen.families import observers
    from codegen.verify import cross_check
    from codegen.verify.inputs import random_inputs
    robot = _arm()
    spec = observers.build(family, robot)
    assert spec.robot_source["friction"] == {"offset": [0.25, 0.0, -0.12], "coulomb_width": 0.1}
    r = cross_check(spec, count=200)
    for key in ("step_est", "step_state", "rhs", "run"):
        assert r[key] <= TOL, (key, r)
    bare = observers.build(family, robot.with_friction(coulomb=0.0, offset=0.0))
    X, Y, U = random_inputs(spec, 20, 3)
    diff = max(_rel(spec.rhs(x, y, u, spec.p_default), bare.rhs(x, y, u, spec.p_default))
               for x, y, u in zip(X, Y, U))
    assert diff > 1e-6


def _symbolic_against_reference(spec, count=20, seed=0):
    """Worst relative error of spec.rhs against the reference's rhs on random inputs."""
    from codegen.verify.inputs import random_inputs
    ref = reference_observer(spec)
    X, Y, U = random_inputs(spec, count, seed)
    return max(_rel(spec.rhs(x, y, u, spec.p_default), ref.rhs(x, y, u)) for x, y, u in zip(X, Y, U))


def test_ii_aov_uses_the_friction():
    """I&I AOV (f = S pbh + T^T (u - g - tau_f(T pbh))) on seed 003's arm with friction: symbolic
    against the reference, and different from the viscous-only observer."""
    from codegen.families import observers
    from models import load_robot
    robot = load_robot("seed003_2r_abs").with_friction(viscous=0.2, coulomb=[0.3, 0.2], offset=[0.05, -0.02],
                                                       width=0.1)
    spec = observers.build("ii_aov", robot)
    assert _symbolic_against_reference(spec) < TOL
    plain = observers.build("ii_aov", robot.with_friction(coulomb=0.0, offset=0.0))
    from codegen.verify.inputs import random_inputs
    X, Y, U = random_inputs(spec, 5, 1)
    assert max(_rel(spec.rhs(x, y, u, spec.p_default), plain.rhs(x, y, u, spec.p_default))
               for x, y, u in zip(X, Y, U)) > 1e-6


def test_tomei_uses_the_friction():
    """Tomei's observer (M qhat1'' = ... - tau_f(qhat1') ...) on the elastic seed-004 2R with link
    friction: symbolic against the reference."""
    from codegen.families import observers
    from models.catalog import load_elastic
    e = load_elastic("seed004_2r").with_friction(coulomb=[3.0, 2.0], offset=[0.5, -0.4], width=0.1)
    spec = observers.build("tomei", e)
    assert _symbolic_against_reference(spec) < TOL
    plain = observers.build("tomei", load_elastic("seed004_2r"))
    x, y, u = np.r_[np.zeros(4), 0.3 * np.ones(2), np.zeros(4)], np.r_[0.1, 0.2, 0.3, -0.2], np.zeros(2)
    assert _rel(spec.rhs(x, y, u, spec.p_default), plain.rhs(x, y, u, spec.p_default)) > 1e-6


def test_spong_manifold_uses_the_friction():
    """Spong's integral-manifold law (c includes tau_f(q1'), h0', h0'' through it): symbolic law
    against the reference (hyper-dual derivatives through tanh) at random states."""
    from codegen.families import controllers
    from models.catalog import load_elastic
    e = load_elastic("seed004_2r").with_friction(coulomb=[3.0, 2.0], offset=[0.5, -0.4], width=0.1)
    spec = controllers.build("spong_manifold", e)
    plain = controllers.build("spong_manifold", load_elastic("seed004_2r"))
    ref = reference_observer(spec)
    rng = np.random.default_rng(9)
    p = np.r_[spec.p_default[:-1], 1e12]                      # unsaturated
    worst, moved = 0.0, 0.0
    for _ in range(20):
        q1, v1 = rng.uniform(-np.pi, np.pi, 2), rng.uniform(-1.0, 1.0, 2)
        y = np.r_[q1, v1, q1 + rng.uniform(-1e-2, 1e-2, 2), v1 + rng.uniform(-0.3, 0.3, 2),
                  q1 + rng.uniform(-0.3, 0.3, 2), rng.uniform(-1, 1, 8)]
        ref.reset(y, p=p)
        want = ref.estimate(y, [])
        got = np.asarray(spec.output(np.zeros(spec.nx), y, [], p)).ravel()
        worst = max(worst, _rel(got, want))
        moved = max(moved, _rel(np.asarray(plain.output(np.zeros(spec.nx), y, [], p)).ravel(), want))
    assert worst < TOL and moved > 1e-3


def test_sweep_model_plant_keeps_the_friction_unscaled():
    """true_run(mismatch = m): tau = (1 + m)(tau_model - tau_f(qd)) + tau_f(qd) with the full
    friction (Coulomb and offset too)."""
    from codegen.evaluate.sweep.work import true_run
    from codegen.verify.trajectory import demo_trajectory
    robot = _arm()
    rec = true_run(str(ARM), "model", 0.5, 0.2, 0, 1e-3)
    _, _, QD, TAU = demo_trajectory(robot, T=0.5, dt=1e-3, seed=0)
    tf = np.array(robot.tau_f.map(len(QD))(QD.T)).T
    assert _rel(np.asarray(rec.tau) - tf, 1.2 * (TAU - tf)) < 1e-14
