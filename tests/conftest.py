"""Shared fixtures. The packages are imported as installed (``pip install -e .``), never through
sys.path edits.

No test writes into the repository: unless the caller set them, ``CODEGEN_BUILD`` and
``CODEGEN_CACHE`` point to a folder of the system's temporary directory, one per user and
checkout, kept between runs (the compile cache is keyed by content and written atomically, so the
parallel workers of ``pytest -n`` share it safely and a second run reuses the libraries).
"""
import hashlib
import os
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent



def pytest_configure(config):
    """Outputs and caches outside the repository (set before xdist starts its workers, which
    inherit the environment)."""
    if not os.environ.get("CODEGEN_BUILD"):
        tag = hashlib.sha256(str(ROOT).encode()).hexdigest()[:8]
        os.environ["CODEGEN_BUILD"] = str(Path(tempfile.gettempdir()) / f"codegen-tests-{os.getuid()}-{tag}")
    os.environ.setdefault("CODEGEN_CACHE", str(Path(os.environ["CODEGEN_BUILD"]) / "cache"))
    # one BLAS thread per worker, as importing codegen sets (a test module may import numpy first)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


CLOSED_FORM = ["seed000_2r", "seed002_2r", "seed003_2r_abs"]
DEFAULT = CLOSED_FORM + ["ur5", "panda"]


@pytest.fixture(scope="session")
def spec_of():
    """Cached default (reduced-order) spec per catalog robot."""
    from codegen.pipeline.targets_file import default_spec
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = default_spec(name)
        return cache[name]
    return get


@pytest.fixture(scope="session")
def compiled():
    """Cached CompiledObserver per catalog robot (the default discretisation, dt = 1e-3)."""
    from codegen import compile_observer
    from codegen.pipeline.targets_file import default_spec
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = compile_observer(default_spec(name), dt=1e-3)
        return cache[name]
    return get


@pytest.fixture(scope="session")
def unranged():
    """seed000_2r's default observer compiled without input ranges (``limits="none"``): a huge
    measurement reaches the step and overflows its result (ERR_NONFINITE_RESULT), where the
    default range (codegen.core.limits) would refuse it first."""
    from codegen import compile_observer, observers
    from models import load_robot
    return compile_observer(observers.build("reduced_order", load_robot("seed000_2r"), limits="none"), dt=1e-3)


def ur5_source(**extra):
    """The plain-data robot source of example-robot-data's ur5 (for the reference tests)."""
    import pinocchio as pin

    from codegen.reference.robots.urdf import file_sha256
    for parent in Path(pin.__file__).resolve().parents:      # <cmeel.prefix>/share/example-robot-data
        path = parent / "share" / "example-robot-data" / "robots" / "ur_description" / "urdf" / "ur5_robot.urdf"
        if path.is_file():
            return dict({"kind": "urdf", "path": str(path), "sha256": file_sha256(path),
                         "locked_joints": {}, "snap_tol": 1e-9}, **extra)
    pytest.skip("example-robot-data's ur5 not found")
