"""Simulation engine: plant accuracy against scipy, sensors, the blocks (C or reference) and
their fast ports."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from codegen.reference import SEED_SOURCES, reference_robot
from codegen.evaluate.sim import blocks
from codegen.evaluate.sim.engine import Law, Port, simulate
from codegen.evaluate.sim.plant import Plant
from codegen.evaluate.sim.sensors import Sensor

PLANT_TOL = 1e-10    # stated accuracy of the compiled RK4 plant at h = 1e-4 s (measured 1.7e-14)


@pytest.fixture(scope="module")
def robot():
    from models.closed_form import seed000_2r
    return seed000_2r()


@pytest.mark.slow
def test_plant_matches_dop853(robot):
    """Compiled RK4 plant (h = dt/substeps = 1e-4 s) vs solve_ivp DOP853 (rtol = atol = 1e-12), same
    torque held over each 5 ms sample, 2 s of Example-1 motion: max |x - x_ref| <= 1e-10 (50
    sub-steps: at most SUBSTEPS_MAX, codegen.core.target)."""
    dt, substeps, N = 5e-3, 50, 400
    plant = Plant(robot, dt, substeps=substeps)
    ref = reference_robot(SEED_SOURCES["seed000_2r"])
    x = np.array([-2 * np.pi / 3, np.pi / 10, -0.5, 1.0])
    plant.reset(x[:2], x[2:])
    worst = 0.0
    for k in range(N):
        t = k * dt
        tau = ref.g(x[:2]) + np.array([np.cos(t / 2) + 3 * np.sin(5 * t), -np.cos(t)])
        sol = solve_ivp(lambda _, s: np.concatenate([s[2:], ref.forward_dynamics(s[:2], s[2:], tau)]),
                        (t, t + dt), x, method="DOP853", rtol=1e-12, atol=1e-12)
        x = sol.y[:, -1]
        worst = max(worst, np.max(np.abs(plant.advance(tau) - x)))
    print(f"plant vs DOP853: max abs error {worst:.2e}")
    assert worst <= PLANT_TOL, worst
    assert np.max(np.abs(x[:2] - [-2 * np.pi / 3, np.pi / 10])) > 0.3    # it moved


def test_sensor_quantises_holds_and_is_seeded():
    s = Sensor(noise_std=1e-3, quantum=7e-4, every=3, seed=5)
    q = np.array([0.3, -1.2])
    ys = [s(k, q + k * 1e-2) for k in range(7)]
    for y in ys:
        assert np.allclose(y / 7e-4, np.round(y / 7e-4), atol=1e-9)
    assert np.array_equal(ys[0], ys[1]) and np.array_equal(ys[0], ys[2])
    assert not np.array_equal(ys[2], ys[3])
    s.reset()
    again = [s(k, q + k * 1e-2) for k in range(7)]
    assert all(np.array_equal(a, b) for a, b in zip(ys, again))
    out = np.empty(2)
    s.reset()
    assert np.array_equal(s.measure(0, q, out), ys[0]) and s.measure(1, q + 1.0, out) is out
    assert np.array_equal(out, ys[0])             # held between samples
    with pytest.raises(ValueError):
        Sensor(every=0)


def test_exact_sensor_passes_q_through():
    y = Sensor()(0, np.array([0.1234567, -2.0]))
    assert np.array_equal(y, [0.1234567, -2.0])


def test_port_calls_c_like_the_checked_api(robot):
    """The engine's zero-copy Port gives the same estimates and states as step()/estimate()."""
    from codegen import compile_observer
    from codegen.families import observers
    spec = observers.build("nicosia_tomei", robot)
    a, b = compile_observer(spec), compile_observer(spec)
    y, u = np.zeros(2), np.zeros(2)
    a.reset([0.1, 0.2]), b.reset([0.1, 0.2])
    port = Port(b, y, u)
    rng = np.random.default_rng(0)
    for _ in range(50):
        y[:], u[:] = rng.normal(size=2), 50 * rng.normal(size=2)
        assert np.array_equal(a.estimate(y, u), port.estimate())
        assert np.array_equal(a.step(y, u), port.step())
        assert np.array_equal(a.state, port.state())
    y[0] = np.nan
    with pytest.raises(Exception, match="ERR_NONFINITE_INPUT"):
        port.step()


def test_block_is_c_or_reference_under_the_stated_discretization(robot):
    """blocks.block: the C records the Discretization it was given (not the library default),
    the reference steps under the same one, and both give the same steps (<= 1e-12 relative);
    anything but a Discretization is refused, naming the argument."""
    from codegen.families import observers
    from codegen.core.target import Discretization
    spec = observers.build("nicosia_tomei", robot)
    disc = Discretization(dt=2e-3, method="euler", hold="zoh", substeps=3)
    c, ref = blocks.block(spec, disc), blocks.block(spec, disc, reference=True)
    assert c.meta["target"]["discretization"] == disc.to_dict()
    assert type(ref).__name__ == "ReferenceObserver" and ref.disc == disc
    rng = np.random.default_rng(1)
    c.reset([0.1, 0.2]), ref.reset([0.1, 0.2])
    for _ in range(20):
        y, u = rng.normal(size=2), 20 * rng.normal(size=2)
        a, b = c.step(y, u), ref.step(y, u)
        assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(b)))
    with pytest.raises(TypeError, match="disc"):
        blocks.block(spec, {"dt": 1e-3})
    with pytest.raises(TypeError, match="disc"):
        blocks.block(spec, None)


def test_huge_kernels_get_the_extra_compiler_flags():
    from types import SimpleNamespace
    spec = lambda k: SimpleNamespace(rhs=SimpleNamespace(n_instructions=lambda: k))  # noqa: E731
    assert blocks.compiler_flags(spec(blocks.HUGE_KERNEL + 1)) == blocks.HUGE_FLAGS == ("-O1",)
    assert blocks.compiler_flags(spec(blocks.HUGE_KERNEL)) == ()


def test_port_on_the_reference_equals_the_port_on_c(robot):
    """blocks.bind on the numpy reference (buffers longer than ny, nu: sliced) writes what the
    C writes through its bound entry points (<= 1e-12)."""
    from codegen.families import observers
    from codegen.core.target import Discretization
    spec = observers.build("reduced_order", robot)
    disc = Discretization(dt=1e-3, method="rk4", hold="foh")
    c, ref = blocks.block(spec, disc), blocks.block(spec, disc, reference=True)
    y, u = np.zeros(3), np.zeros(4)              # one slot more than the blocks read
    c.reset([0.3, -0.1]), ref.reset([0.3, -0.1])
    pc, pr = Port(c, y, u), Port(ref, y, u)
    rng = np.random.default_rng(2)
    for _ in range(30):
        y[:], u[:] = rng.normal(size=3), 30 * rng.normal(size=4)
        assert np.allclose(pc.estimate(), pr.estimate(), rtol=1e-12, atol=1e-12)
        assert np.allclose(pc.step(), pr.step(), rtol=1e-12, atol=1e-12)
        assert np.allclose(pc.state(), pr.state(), rtol=1e-12, atol=1e-12)


def test_closed_loop_with_compiled_law(robot):
    """A compiled open-loop law (18) drives the plant with two compiled observers attached: the
    torque it applies equals g(q) + (cos(t/2), -cos(t)) from the independent numpy robot. (The
    loop's wall time is measured in `make bench`, seed000_loop, not asserted here.)"""
    from codegen import compile_observer
    from codegen.families import observers
    from codegen.families.controllers.seed000 import open_loop

    def assemble(t, y, est, x, out):
        out[:2] = x[:2]
        out[2] = t
    law = Law(compile_observer(open_loop(robot, 1)), assemble)
    obs = {f: compile_observer(observers.build(f, robot)) for f in ("reduced_order", "nicosia_tomei")}
    plant = Plant(robot, 1e-3, substeps=10)
    res = simulate(plant, [-2.0, 0.3], [-0.5, 1.0], 2.0, 1e-3, law, obs)
    ref = reference_robot(SEED_SOURCES["seed000_2r"])
    for k in (0, 1000, 2000):
        t, q = res.t[k], res.q[k]
        assert np.allclose(res.u[k], ref.g(q) + [np.cos(t / 2), -np.cos(t)], rtol=1e-12, atol=1e-12)


def test_figures_have_every_line_in_the_legend_units_and_the_paper(tmp_path, monkeypatch):
    """Seed 000's positions figure: each joint's target q_i,d in the legend (q2's had none), every
    axis with a unit, the legend beside the axes; inside ``plots.citing`` the figure carries
    the paper and experiment it reproduces."""
    import matplotlib.pyplot as plt

    from codegen.evaluate.sim import plots
    figs = []
    monkeypatch.setattr(plt, "close", figs.append)
    t = np.linspace(0, 1, 101)
    q = np.column_stack([np.sin(t), np.cos(t)])
    with plots.citing("seed000-ex3: seed 000 (Cristofaro & De Luca), Example 3"):
        plots.positions_and_bound(tmp_path / "f.png", t, q, q, q, np.ones_like(t), 2.0, q_ref=q)
    [fig] = figs
    top, bottom = fig.axes
    labels = top.get_legend_handles_labels()[1]
    assert {"q1,d (target)", "q2,d (target)"} <= set(labels)
    for ax in fig.axes:
        assert "[" in ax.get_ylabel()
        assert ax.get_legend() is not None and ax.get_legend().get_bbox_to_anchor().x0 > ax.bbox.x1 - 1
    assert bottom.get_xlabel() == "t [s]"
    assert [t.get_text() for t in fig.texts] == ["seed000-ex3: seed 000 (Cristofaro & De Luca), Example 3"]


@pytest.mark.slow
def test_o1_kernels_estimate_to_the_bit_what_o3_kernels_do(robot):
    """HUGE_FLAGS change the compile, not the arithmetic (no -ffast-math, -ffp-contract=off):
    kalman_model's model variant on seed000_2r compiled at -O3 and at -O1, run over the same
    3 s of jittered samples with friction and torque noise, gives bit-identical estimates; and
    its panda kernel (the one compare spends most of its compile on) is one HUGE_FLAGS applies to."""
    from codegen.core.target import discretization
    from codegen.families import observers
    from codegen.pipeline.stages import compile_observer
    from models import load_robot
    spec = observers.build("kalman_model", robot, torque_uncertainty=[0.5, 0.2], coulomb=[1.0, 0.5],
                           quantization=1e-4)
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.7e-3, 1.6e-3, 2500))
    Q = np.column_stack([np.sin(2 * t), 0.5 * np.cos(3 * t)])
    U = np.column_stack([np.cos(2 * t), np.sin(t)]) + 0.05 * rng.normal(size=(len(t), 2))
    disc = discretization(None, dt=float(np.median(np.diff(t))), substeps=2)
    est = []
    for flags in ((), blocks.HUGE_FLAGS):
        obs = compile_observer(spec, disc, cflags=flags)
        obs.reset(Q[0])
        est.append(obs.run(Q, U, t=t))
    assert np.all(np.isfinite(est[0])) and np.ptp(est[0][:, 0]) > 1.0      # it tracked the motion
    assert np.array_equal(est[0], est[1])
    panda = observers.build("kalman_model", load_robot("panda"), torque_uncertainty=0.1)
    assert blocks.compiler_flags(panda) == blocks.HUGE_FLAGS
