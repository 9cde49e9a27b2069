"""The independent reference (codegen.reference): its independence (imports), the observer
families bound to their options, the reduced-order observer, its discretization and its input
checks. The robots are tested in test_reference_robots.py.

Uses a tiny fake description (a plain dict), so it depends on no other module of the project.
"""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from codegen.reference import SEED_SOURCES, reference_observer, reference_robot
from conftest import ur5_source

RNG = np.random.default_rng(20240601)


@pytest.fixture(autouse=True)
def _fresh_rng():
    """Every test draws the same numbers whatever ran before it (order-independent)."""
    global RNG
    RNG = np.random.default_rng(20240601)


def fake_spec(source, k0=16.037, family="reduced_order"):
    """The plain-data description the reference reads (ObserverSpec.describe() keys)."""
    n = reference_robot(source).n
    return {"family": family, "variant": None, "robot": source, "p_default": [k0],
            "names": {"p": ["k0"], "x": [f"z{i}" for i in range(n)], "y": [f"q{i}" for i in range(n)],
                      "u": [f"tau{i}" for i in range(n)], "est": [f"dq_hat{i}" for i in range(n)]},
            "options": {"kind": "Options"}, "hybrid": False,
            "rate_states": [f"z{i}" for i in range(n)] if family == "reduced_order" else [],
            "gains": {"k0": ["k0"]} if family == "reduced_order" else {}}


# ---------------------------------------------------------------------------- independence
# what the reference may import: the standard library, numpy, pinocchio, itself, and the two
# plain-data modules of ours and the input validator; nothing else of the project, no CasADi
ALLOWED_THIRD_PARTY = {"numpy", "pinocchio"}
ALLOWED_OURS = {"codegen.core.target", "codegen.core.options", "codegen.core.arrays"}


def _imports(path, package="codegen.reference"):
    """Absolute names of every module a file imports (also inside functions)."""
    import ast
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            names += [mod] if node.module else [f"{mod}.{a.name}" for a in node.names]
    return names


def _allowed(name):
    root = name.split(".")[0]
    return (root in sys.stdlib_module_names or root in ALLOWED_THIRD_PARTY or name in ALLOWED_OURS
            or name == "codegen.reference" or name.startswith("codegen.reference."))


def test_source_import_is_independent():
    """Every import of codegen/reference/ (all its folders) is on the allow-list."""
    files = sorted(Path(__file__).parents[2].joinpath("codegen", "reference").rglob("*.py"))
    assert len(files) > 10
    root = Path(__file__).parents[2]
    for f in files:
        parts = f.relative_to(root).with_suffix("").parts
        package = ".".join(parts[:-1] if parts[-1] != "__init__" else parts[:-1])
        bad = [m for m in _imports(f, package) if not _allowed(m)]
        assert not bad, (f.name, bad)
    assert not _allowed("casadi") and not _allowed("models.urdf") and not _allowed("codegen.core.spec")


def test_reference_runs_without_casadi_or_models():
    """Importing the reference and stepping an observer loads neither CasADi nor ``models``, and
    of ours only the reference and the plain-data modules (beyond what ``import codegen`` loads)."""
    code = ("import sys, json; import codegen; package = set(sys.modules); "
            "from codegen.reference import reference_observer; "
            "ref = reference_observer(json.loads(sys.argv[1]), hold='zoh'); "
            "ref.reset([0.1, 0.2], [1.0, 0.0]); ref.run([[0.1, 0.2]] * 3, [[1.0, 2.0]] * 3); "
            "print(json.dumps([sorted(sys.modules), sorted(set(sys.modules) - package)]))")
    out = subprocess.run([sys.executable, "-c", code, json.dumps(fake_spec(SEED_SOURCES["seed000_2r"]))],
                         cwd=Path(__file__).parents[2], capture_output=True, text=True, check=True)
    loaded, added = json.loads(out.stdout)
    assert "casadi" not in loaded and not any(m.split(".")[0] == "models" for m in loaded)
    ours = [m for m in added if m.split(".")[0] == "codegen"]
    assert "codegen.reference.robots" in ours
    assert all(m in ALLOWED_OURS or m.startswith("codegen.reference") for m in ours), ours


# ---------------------------------------------------------------------------- observer
def test_reduced_order_equations_and_init():
    """rhs = forward_dynamics(y, x2hat, tau) - k0 x2hat; output = z + k0 y; the first
    estimate equals est0 [S000 (6),(9)]."""
    for source in (SEED_SOURCES["seed000_2r"], ur5_source()):
        spec = fake_spec(source, k0=7.5)
        ref = reference_observer(spec, dt=1e-3, hold="zoh")
        robot = ref.robot
        n = robot.n
        x, y, u = RNG.standard_normal((3, n))
        x2hat = x + 7.5 * y
        np.testing.assert_allclose(ref.output(x, y, u), x2hat, rtol=1e-15)
        # M z' = tau - C x2hat - F x2hat - g - k0 M x2hat, the unsolved form of [S000 (6)]
        M = robot.M(y)
        lhs = M @ ref.rhs(x, y, u)
        rhs = u - robot.C(y, x2hat) @ x2hat - robot.F @ x2hat - robot.g(y) - 7.5 * M @ x2hat
        np.testing.assert_allclose(lhs, rhs, rtol=1e-10, atol=1e-10)
        est0 = RNG.standard_normal(n)
        ref.reset(y, est0)
        np.testing.assert_allclose(ref.state, est0 - 7.5 * y, rtol=1e-15)
        np.testing.assert_allclose(ref.step(y, u), est0, rtol=1e-14, atol=1e-15)
        # p given at reset overrides the default
        ref.reset(y, est0, p=[3.0])
        assert ref.params[0] == 3.0
        np.testing.assert_allclose(ref.state, est0 - 3.0 * y, rtol=1e-15)


def _exact_step(ref, x, y, u, dt):
    sol = solve_ivp(lambda t, z: ref.rhs(z, y, u), (0.0, dt), x, method="DOP853", rtol=1e-13, atol=1e-13)
    return sol.y[:, -1]


@pytest.mark.parametrize("dt,substeps", [(1e-3, 1), (1e-2, 10)])
def test_rk4_step_matches_exact_flow(dt, substeps):
    """One step of rk4 with y, u held equals the exact flow (solve_ivp, rtol 1e-13) to 1e-9."""
    spec = fake_spec(SEED_SOURCES["seed000_2r"])
    ref = reference_observer(spec, dt=dt, method="rk4", substeps=substeps, hold="zoh")
    for _ in range(5):
        y, est0 = RNG.uniform(-2, 2, 2), RNG.uniform(-3, 3, 2)
        u = 100 * RNG.standard_normal(2)
        ref.reset(y, est0)
        x0 = ref.state
        ref.step(y, u)
        assert np.abs(ref.state - _exact_step(ref, x0, y, u, dt)).max() <= 1e-9


@pytest.mark.parametrize("method,order", [("euler", 1), ("rk4", 4)])
def test_convergence_order(method, order):
    """Halving h divides the error over a step by 2^order (checked within 25 %)."""
    spec = fake_spec(SEED_SOURCES["seed000_2r"], k0=5.0)
    dt = 0.05
    y, est0, u = np.array([0.4, -0.8]), np.array([1.0, -2.0]), np.array([30.0, -10.0])
    errs = []
    for substeps in (4, 8, 16):
        ref = reference_observer(spec, dt=dt, method=method, substeps=substeps, hold="zoh")
        ref.reset(y, est0)
        x0 = ref.state
        ref.step(y, u)
        errs.append(np.abs(ref.state - _exact_step(ref, x0, y, u, dt)).max())
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    np.testing.assert_allclose(ratios, 2.0 ** order, rtol=0.25)


def _seed000_plant(t):
    robot = reference_robot(SEED_SOURCES["seed000_2r"])

    def tau(tt):
        return robot.g(np.zeros(2)) + np.array([20 * np.sin(3 * tt), 10 * np.cos(2 * tt)])

    def f(tt, s):
        return np.concatenate([s[2:], robot.forward_dynamics(s[:2], s[2:], tau(tt))])

    return robot, tau, f, np.array([0.1, -0.2, 0.5, -0.3])


def test_continuous_observer_converges_on_seed000_plant():
    """docs/papers/seed000.md §1.1: with k0 = 16.037 (docs/papers/seed000.md §1.2) the estimate of the continuous-time observer
    converges to the true velocity; the error falls by > 1e5 within 1 s (rate ~ k0)."""
    t = np.linspace(0.0, 1.0, 11)
    robot, tau, plant, s0 = _seed000_plant(t)
    ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), hold="zoh")
    k0 = ref.params[0]

    def f(tt, s):
        return np.concatenate([plant(tt, s[:4]), ref.rhs(s[4:], s[:2], tau(tt))])

    z0 = -k0 * s0[:2]                                   # x2hat(0) = 0
    sol = solve_ivp(f, (0, 1), np.concatenate([s0, z0]), t_eval=t, method="DOP853", rtol=1e-12, atol=1e-12)
    err = [np.linalg.norm(ref.output(s[4:], s[:2], tau(tt)) - s[2:4]) for tt, s in zip(t, sol.y.T)]
    assert err[0] > 0.5 and err[-1] < 1e-5 * err[0]
    assert np.all(np.diff(err) < 0)


def test_sampled_observer_error_is_first_order_in_dt():
    """The sampled observer (y, u held over each step) tracks the velocity up to a bias
    O(dt) from the hold: halving dt halves the final error (within 20 %)."""
    finals = []
    for dt in (1e-3, 5e-4):
        t = np.arange(int(round(1.0 / dt)) + 1) * dt
        robot, tau, plant, s0 = _seed000_plant(t)
        sol = solve_ivp(plant, (0, t[-1]), s0, t_eval=t, method="DOP853", rtol=1e-12, atol=1e-12)
        Q, V = sol.y[:2].T, sol.y[2:].T
        U = np.array([tau(tt) for tt in t])
        ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), dt=dt, method="rk4", hold="zoh")
        ref.reset(Q[0])                                   # x2hat(0) = 0
        err = np.linalg.norm(ref.run(Q, U) - V, axis=1)
        assert err[0] > 0.5 and err[-1] < 0.1 * err[0]
        finals.append(err[-1])
    np.testing.assert_allclose(finals[0] / finals[1], 2.0, rtol=0.2)


def test_step_run_consistency():
    spec = fake_spec(SEED_SOURCES["seed002_2r"], k0=12.0)
    Y, U = RNG.uniform(-1, 1, (50, 2)), RNG.standard_normal((50, 2))
    a = reference_observer(spec, dt=2e-3, method="rk4", substeps=2, hold="zoh")
    b = reference_observer(spec, dt=2e-3, method="rk4", substeps=2, hold="zoh")
    a.reset(Y[0], [0.3, -0.1])
    b.reset(Y[0], [0.3, -0.1])
    EST = a.run(Y, U)
    EST_steps = np.array([b.step(y, u) for y, u in zip(Y, U)])
    np.testing.assert_array_equal(EST, EST_steps)
    np.testing.assert_array_equal(a.state, b.state)
    assert EST.shape == (50, 2)


def test_euler_is_one_explicit_step():
    spec = fake_spec(SEED_SOURCES["seed000_2r"])
    ref = reference_observer(spec, dt=1e-3, method="euler", hold="zoh")
    y, u = np.array([0.2, 0.3]), np.array([1.0, 2.0])
    ref.reset(y, [1.0, 1.0])
    x0 = ref.state
    ref.step(y, u)
    np.testing.assert_allclose(ref.state, x0 + 1e-3 * ref.rhs(x0, y, u), rtol=1e-15)


@pytest.mark.parametrize("args,name", [
    ((np.zeros(3), np.zeros(2)), "y"),
    ((np.zeros(2), np.zeros((2, 2))), "u"),
    ((np.array([0.0, np.nan]), np.zeros(2)), "y"),
    ((np.zeros(2), np.array([np.inf, 0.0])), "u"),
    (("ab", np.zeros(2)), "y"),
])
def test_bad_step_inputs_raise_and_keep_state(args, name):
    ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), hold="zoh")
    ref.reset([0.1, 0.2], [1.0, 2.0])
    before = ref.state
    with pytest.raises(ValueError, match=rf"^{name}: expected (2 real|2 finite|shape \(2,\))"):
        ref.step(*args)
    np.testing.assert_array_equal(ref.state, before)


def test_bad_run_and_reset_inputs():
    ref = reference_observer(fake_spec(SEED_SOURCES["seed000_2r"]), hold="zoh")
    with pytest.raises(RuntimeError, match="reset"):
        ref.step(np.zeros(2), np.zeros(2))
    ref.reset([0.1, 0.2])
    before = ref.state
    Y, U = np.zeros((5, 2)), np.zeros((5, 2))
    with pytest.raises(ValueError, match=r"^U: .*\(5, 2\)"):
        ref.run(Y, U[:4])
    with pytest.raises(ValueError, match=r"^Y: .*\(N, 2\)"):
        ref.run(np.zeros((5, 3)), U)
    U[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"^U: NaN or Inf at row 3"):
        ref.run(Y, U)
    np.testing.assert_array_equal(ref.state, before)
    with pytest.raises(ValueError, match=r"^y0: "):
        ref.reset([0.1])
    with pytest.raises(ValueError, match=r"^est0: "):
        ref.reset([0.1, 0.2], [np.nan, 0.0])
    with pytest.raises(ValueError, match=r"^p: "):
        ref.reset([0.1, 0.2], p=[1.0, 2.0])
    np.testing.assert_array_equal(ref.state, before)


def test_bad_construction():
    spec = fake_spec(SEED_SOURCES["seed000_2r"])
    with pytest.raises(ValueError, match="method"):
        reference_observer(spec, method="rk45")
    with pytest.raises(ValueError, match="dt"):
        reference_observer(spec, dt=0.0)
    with pytest.raises(ValueError, match="substeps"):
        reference_observer(spec, substeps=0)
    with pytest.raises(ValueError, match="family"):
        reference_observer(fake_spec(SEED_SOURCES["seed000_2r"], family="nope"))
    with pytest.raises(ValueError, match="sizes"):
        reference_observer({**spec, "names": {**spec["names"], "x": ["a"]}})
    with pytest.raises(ValueError, match="jump"):
        reference_observer({**spec, "hybrid": True})
    with pytest.raises(ValueError, match="options"):
        reference_observer({**spec, "options": {"kind": "Nonsense"}})


# ---------------------------------------------------------------------------- families bound to options
def _family_configure(name):
    from codegen.reference import FAMILIES
    return FAMILIES[name].configure


@pytest.mark.parametrize("name,source,options", [
    ("ii_speed", SEED_SOURCES["seed003_2r_abs"], {"kind": "QuadratureOptions", "N": 4, "periodic": [True, True],
                                                  "N_period": 8}),
    ("lotfi_namvar", SEED_SOURCES["seed002_2r"], {"kind": "NonMinimalOptions", "rows": [1, 2, 3], "joints": [0, 1],
                                                  "g_o": [0.0, -9.81]}),
    ("ciccarella_germani", {"kind": "elastic", "rigid": SEED_SOURCES["seed000_2r"], "J": [1.0, 1.0],
                            "K": [100.0, 100.0]}, {"kind": "VariantOptions", "variant": "O3"}),
])
def test_configure_binds_options_without_touching_the_robot(name, source, options):
    """configure returns the family with the options bound as values; the robot is unchanged
    (nothing stored on it), and the bound sizes follow the options."""
    from codegen.core.options import options_from_dict
    robot = reference_robot(source)
    before = dict(vars(robot))
    family = _family_configure(name)(robot, options_from_dict(options))
    assert vars(robot).keys() == before.keys() and all(vars(robot)[k] is v for k, v in before.items())
    bound, sizes = {"ii_speed": ({"N": 4, "periodic": [True, True], "N_period": 8},
                                 {"nx": 7, "ny": 2, "nu": 2, "nest": 4}),
                    "lotfi_namvar": ({}, {"nx": 12, "ny": 5, "nu": 2, "nest": 8}),
                    "ciccarella_germani": ({"variant": "O3"}, {"nx": 8, "ny": 4, "nu": 2, "nest": 8})}[name]
    assert {k: getattr(family, k) for k in bound} == bound
    assert family.sizes(robot) == sizes
    if name == "lotfi_namvar":
        assert (family.nm.rows, family.nm.joints, list(family.nm.a)) == ([1, 2, 3], [0, 1], [-9.81, 0.0, -9.81])


def test_two_observers_of_one_robot_keep_their_options():
    """Two Ciccarella-Germani variants on the same reference robot object: each family keeps its
    own variant (the first is not overwritten by the second)."""
    from codegen.core.options import VariantOptions
    robot = reference_robot({"kind": "elastic", "rigid": SEED_SOURCES["seed000_2r"], "J": [1.0, 1.0],
                             "K": [100.0, 100.0]})
    configure = _family_configure("ciccarella_germani")
    o4, o3 = configure(robot, VariantOptions("O4")), configure(robot, VariantOptions("O3"))
    assert (o4.variant, o3.variant) == ("O4", "O3")
    assert o4.sizes(robot)["ny"] == 2 and o3.sizes(robot)["ny"] == 4


def test_bound_refuses_an_option_no_function_takes():
    from codegen.reference.families import _family, reduced_order
    family = _family.bound(reduced_order)
    assert family.rhs is reduced_order.rhs and family.P_NAMES == ("k0",)
    with pytest.raises(TypeError, match="variant"):
        _family.bound(reduced_order, variant="O1")


@pytest.mark.parametrize("name,source,options,match", [
    ("ciccarella_germani", {"kind": "elastic", "rigid": SEED_SOURCES["seed000_2r"], "J": [1.0, 1.0],
                            "K": [100.0, 100.0]}, {"kind": "VariantOptions", "variant": "O5"}, "variant 'O5'"),
    ("ciccarella_germani", {"kind": "elastic", "rigid": SEED_SOURCES["seed000_2r"], "J": [1.0, 1.0],
                            "K": [100.0, 100.0]}, {"kind": "Options"}, "variant None"),
    ("lotfi_namvar", SEED_SOURCES["seed002_2r"], {"kind": "Options"}, "NonMinimalOptions"),
    ("lotfi_namvar", SEED_SOURCES["seed002_2r"], {"kind": "NonMinimalOptions", "rows": [0], "joints": [0],
                                                  "g_o": [0.0, 9.81]}, "g_o"),
    ("lotfi_namvar", SEED_SOURCES["seed002_2r"], {"kind": "NonMinimalOptions", "rows": [4], "joints": [0],
                                                  "g_o": [0.0, -9.81]}, "out of range"),
    ("ii_speed", SEED_SOURCES["seed000_2r"], {"kind": "QuadratureOptions", "N": 4,
                                                                        "periodic": [True, True, True],
                                                                        "N_period": 4}, "^periodic: expected 2"),
])
def test_configure_refuses_bad_options(name, source, options, match):
    from codegen.core.options import options_from_dict
    with pytest.raises(ValueError, match=match):
        _family_configure(name)(reference_robot(source), options_from_dict(options))


def test_reference_params_check_covers_every_phase():
    """Issue 22 F1 in the reference's own check: a switched k0_final or a hybrid k_6 of 5000
    with RK4 (5000 dt_max = 10 > 2.785) is refused before the switch or at r = 1 (the check
    linearises at every phase the family gives), and the defaults are accepted."""
    from codegen.families import observers
    from codegen.reference import reference_observer
    from models import load_robot
    robot = load_robot("seed000_2r")
    y, u = np.array([0.3, -0.2]), np.array([1.0, 2.0])
    for family, slot in (("reduced_order_switched", "k0_final"), ("reduced_order_hybrid", "k_6")):
        spec = observers.build(family, robot)
        ref = reference_observer(spec, method="rk4")
        ref.reset(y)
        ref.step(y, u)
        ref.params = spec.p_default
        p = spec.p_default.copy()
        p[spec.p_names.index(slot)] = 5000.0
        with pytest.raises(ValueError, match="spectral radius .* phase"):
            ref.params = p
        assert np.array_equal(ref.params, spec.p_default)
