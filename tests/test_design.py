"""Gain design of the reduced-order observer for the seed-000 robot (SPEC §1.2), and the
design package's place in the import graph (DESIGN §1: no back-edges)."""
import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from codegen.design import c0_batch, reduced_order_gain, scheduled_gains
from models import load_robot


def test_kappa_of_planar_coriolis():
    """SPEC §0: kappa = max_{|v|=1} ||N(v)||_2 = 1.64449 with N(v) = [[v2, v1+v2], [-v1, 0]]."""
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
    """[S000 (16)] for eta = 1, vbar = 2: k_r = 5.3214 + 10.7154 r (SPEC §1.2 table)."""
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
    codegen.observers."""
    root = Path(__file__).parents[1] / "codegen"
    files = [(f, "codegen.design") for f in (root / "design").glob("*.py")] + [(root / "symbolic.py", "codegen")]
    assert len(files) >= 6
    for f, package in files:
        bad = [m for m in _imported_modules(f, package)
               if m.startswith("codegen.") and not m.startswith(("codegen.design", "codegen.symbolic", "codegen.cache"))]
        assert not bad, f"{f.name} imports {bad}"
    code = ("import sys, codegen.design, codegen.symbolic; "
            "print([m for m in sys.modules if m.startswith('codegen.observers')])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).parents[1])
    assert out.stdout.strip() == "[]"
