"""Gain design of the reduced-order observer for the seed-000 robot (docs/papers/seed000.md §1.2), and the
design package's place in the import graph (docs/architecture.md §1: no back-edges)."""
import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from codegen.families.design import c0_batch, reduced_order_gain, scheduled_gains
from models import load_robot


def test_kappa_of_planar_coriolis():
    """docs/papers/seed000.md §0: kappa = max_{|v|=1} ||N(v)||_2 = 1.64449 with N(v) = [[v2, v1+v2], [-v1, 0]]."""
    N = lambda v: np.array([[v[1], v[0] + v[1]], [-v[0], 0.0]])  # noqa: E731
    slices = np.hstack([N([1, 0]), N([0, 1])])[None]
    assert c0_batch(slices, 2)[0][0] == pytest.approx(1.64449, abs=1e-5)


def test_seed000_k0_eta1_vmax2():
    """[S000 (8),(12),(13), Remark 3] with eta = 1, v_max = 2: k0 = 16.037, Remark 3 = 48.36,
    c0bar = 24.667, min lambda_min(M) = 1.5280, max lambda_max(M) = 81.805, radius 0.137."""
    d = reduced_order_gain(load_robot("seed000_2r"), eta=1.0, v_max=2.0)
    assert d.k0 == pytest.approx(16.037, abs=5e-4)
    assert d.k0_remark3 == pytest.approx(48.36, abs=5e-3)
    assert d.c0bar == pytest.approx(24.667, abs=5e-4)
    assert 2 * d.lambda1 == pytest.approx(1.5280, abs=5e-4)
    assert 2 * d.lambda2 == pytest.approx(81.805, abs=5e-3)
    assert d.radius == pytest.approx(0.137, abs=5e-4)
    assert "k0 =" in str(d) and "(12)" in str(d)


def test_seed000_scheduled_gains_table():
    """[S000 (16)] for eta = 1, vbar = 2: k_r = 5.3214 + 10.7154 r (docs/papers/seed000.md §1.2 table)."""
    k = scheduled_gains(load_robot("seed000_2r"), eta=1.0, vbar=2.0, r_max=6)
    table = [16.037, 26.752, 37.468, 48.183, 58.899, 69.614]
    assert np.allclose(k, table, atol=1e-3)
    assert np.allclose(np.diff(k), 10.7154, atol=1e-3)


def test_design_rejects_bad_arguments():
    with pytest.raises(ValueError, match="eta and v_max"):
        reduced_order_gain(load_robot("seed000_2r"), eta=0.0)


def _imported_modules(path, package):
    """Absolute names of every module ``path`` imports, at any depth (lazy imports included)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            parts = package.split(".")
            base = parts[:len(parts) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            names += [mod] + [f"{mod}.{a.name}" for a in node.names]
    return names


def test_design_and_symbolic_never_import_observers():
    """design imports only symbolic and the disk cache (and numerics); neither reaches
    codegen.families.observers."""
    root = Path(__file__).parents[2] / "codegen"
    files = [(f, "codegen.families.design") for f in (root / "families" / "design").glob("*.py")] + \
        [(root / "core" / "symbolic.py", "codegen.core")]
    assert len(files) >= 6
    for f, package in files:
        bad = [m for m in _imported_modules(f, package)
               if m.startswith("codegen.") and not m.startswith(("codegen.families.design", "codegen.core.symbolic", "codegen.core.cache"))]
        assert not bad, f"{f.name} imports {bad}"
    code = ("import sys, codegen.families.design, codegen.core.symbolic; "
            "print([m for m in sys.modules if m.startswith('codegen.families.observers')])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).parents[2])
    assert out.stdout.strip() == "[]"


# ----------------------------------------------------------------------------- noise-aware gains
def test_sensor_sigma_and_default_encoder():
    from codegen.families.design.noise import DEFAULT_QUANTIZATION, sensor_sigma
    assert DEFAULT_QUANTIZATION == pytest.approx(9.587e-5, rel=1e-3)          # 2 pi / 2^16
    assert sensor_sigma() == pytest.approx(DEFAULT_QUANTIZATION / np.sqrt(12))
    assert sensor_sigma(noise=3e-4, quantization=1e-4) == pytest.approx(np.hypot(3e-4, 1e-4 / np.sqrt(12)))
    assert sensor_sigma(noise=0.0) == 0.0
    with pytest.raises(ValueError, match="quantization"):
        sensor_sigma(quantization=-1.0)


def test_smoother_noise_formula_matches_its_filter():
    """w_k+1 = E w_k + (1 - E)(y_k+1 - y_k)/dt on white noise: std = sigma (1-E)/dt sqrt(2/(1+E))."""
    from scipy.signal import lfilter

    from codegen.families.design.noise import smoother_noise
    dt, sigma = 1e-3, 1e-4
    n = np.random.default_rng(0).normal(scale=sigma, size=400_000)
    for k0 in (20.0, 500.0, 3000.0):
        E = np.exp(-k0 * dt)
        w = lfilter([1 - E], [1, -E], np.diff(n) / dt)
        assert np.std(w[1000:]) == pytest.approx(smoother_noise(k0, dt, sigma), rel=0.01)
        assert smoother_noise(k0, 1e-7, sigma) == pytest.approx(k0 * sigma, rel=1e-3)


def test_noise_aware_choices():
    """No uncertainty: the convergence floor ln(v_max/1e-2)/t_conv decides; 10 % uncertainty: an
    interior optimum; no noise at all: the guarantee gain (12)."""
    from codegen.families.design import reduced_order_design
    robot = load_robot("ur5")
    plain = reduced_order_design(robot, 1e-3)
    assert plain.choice == "convergence floor" and plain.k0 == pytest.approx(np.log(200) / 0.2)
    mism = reduced_order_design(robot, 1e-3, quantization=1e-4, uncertainty=0.1)
    assert mism.choice == "noise-aware optimum" and 100 < mism.k0 < 400
    assert mism.predicted_error["default"] < mism.predicted_error["guarantee (12)"]
    clean = reduced_order_design(robot, 1e-3, noise=0.0, quantization=0.0)
    assert clean.choice == "guarantee (12)" and clean.k0 == pytest.approx(clean.k0_guarantee)
    assert "k0 =" in str(mism) and "guarantee (12)" in str(mism)
    with pytest.raises(ValueError, match="uncertainty"):
        reduced_order_design(robot, 1e-3, uncertainty=1.5)


@pytest.mark.slow
@pytest.mark.parametrize("name,uncertainty", [("ur5", 0.1), ("panda", 0.1), ("ur5", 0.0)])
def test_predicted_error_matches_simulation(name, uncertainty):
    """The prediction of codegen.families.design.noise against the compiled observer on the built-in
    trajectory (torque held over each sample, plant masses and inertias x (1 + uncertainty),
    q quantised to 1e-4 rad): the predicted error within 25 % of the simulated one on a grid of
    gains, and the predicted optimum within a factor 2 of the simulated one (with uncertainty;
    without, both sit at the low end, where only the convergence floor stops the design)."""
    from codegen import compile_observer
    from codegen.families import observers
    from codegen.families.design import reduced_order_design
    from codegen.families.design.noise import reduced_order_error
    from codegen.verify.trajectory import demo_trajectory
    robot = load_robot(name)
    t, Q, QD, TAU = demo_trajectory(robot, T=3.0)
    F = np.asarray(robot.F)
    tau = (1 + uncertainty) * (TAU - QD @ F.T) + QD @ F.T
    U = np.vstack([0.5 * (tau[1:] + tau[:-1]), tau[-1:]])          # applied over [t_k, t_k+1]
    Y = np.round(Q / 1e-4) * 1e-4
    design = reduced_order_design(robot, 1e-3, quantization=1e-4, uncertainty=uncertainty)
    obs = compile_observer(observers.build("reduced_order", robot, k0=100.0))
    gains = np.geomspace(20, 2000, 11)
    simulated, predicted = [], []
    for k in gains:
        obs.reset(Y[0], est0=QD[0], p=[k])
        err = obs.run(Y, U)[t >= 1.0] - QD[t >= 1.0]
        simulated.append(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))
        predicted.append(reduced_order_error(k, 1e-3, robot.n, design.sigma, design.e_rms, design.G))
    assert np.allclose(predicted, simulated, rtol=0.25), (predicted, simulated)
    best = gains[int(np.argmin(simulated))]
    if uncertainty:
        assert 0.5 < design.k0_noise / best < 2.0, (design.k0_noise, best)
    else:
        assert best == gains[0] and design.k0_noise < gains[0]


def test_nicosia_tomei_noise_gains_meet_the_rate():
    from codegen.families.design import model_statistics, nicosia_tomei_noise_gains
    stats = model_statistics(load_robot("panda"))
    for unc in (0.0, 0.1):
        kd, kp, err = nicosia_tomei_noise_gains(1e-3, 3e-5, stats["g_rms"], unc, stats["trace_minv2"],
                                                stats["mu_min"], 4.6)
        slowest = kd / 2 - np.sqrt(max(0.0, kd ** 2 / 4 - kp * stats["mu_min"]))
        assert slowest >= 4.6 * (1 - 1e-3) and err > 0


def test_design_is_kept_on_disk(tmp_path, monkeypatch):
    """A second process (here: the in-memory cache cleared) reads (12) from the disk cache."""
    from codegen.families.design import reduced_order as ro
    monkeypatch.setenv("CODEGEN_CACHE", str(tmp_path))
    robot = load_robot("seed000_2r")
    ro._design_cached.cache_clear()
    first = reduced_order_gain(robot, eta=1.0, v_max=2.5)
    assert len(list((tmp_path / "design").glob("*.json"))) == 1
    ro._design_cached.cache_clear()
    monkeypatch.setattr(ro, "ConfigurationStats", None)          # a recomputation would fail
    assert reduced_order_gain(robot, eta=1.0, v_max=2.5).k0 == first.k0
    ro._design_cached.cache_clear()
