"""One BLAS thread per process (codegen/__init__.py, models/__init__.py): set before numpy loads
unless the caller chose another count."""
import os
import subprocess
import sys

import pytest


@pytest.mark.parametrize("package", ["codegen", "models"])
@pytest.mark.parametrize("given", [None, "2"])
def test_importing_the_package_sets_one_blas_thread_unless_given(package, given):
    """A fresh process importing ``package`` then numpy sees OPENBLAS_NUM_THREADS = 1, or the
    caller's own value when it set one."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    code = f"import {package}, numpy, os; print(os.environ['OPENBLAS_NUM_THREADS'])"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == (given or "1")
