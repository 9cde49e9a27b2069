import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

CLOSED_FORM = ["seed000_2r", "seed002_2r", "seed003_2r_abs"]
DEFAULT = CLOSED_FORM + ["ur5", "panda"]


@pytest.fixture(scope="session")
def spec_of():
    """Cached default (reduced-order) spec per catalog robot."""
    from codegen.targets import default_spec
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
    from codegen.targets import default_spec
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = compile_observer(default_spec(name), dt=1e-3)
        return cache[name]
    return get
