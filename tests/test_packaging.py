"""The installable package: a wheel installed in a fresh venv generates,
builds and loads a target from a temp folder through the console script, with the C harness
shipped as package data, and writes nothing inside site-packages.

Offline and quick: the wheel is built without isolation (setuptools and wheel of this venv),
installed with --no-deps, and the fresh venv sees this venv's dependencies through a .pth file
(a path line, so this checkout's editable install is not loaded)."""
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parent.parent
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "models", "codegen", "c_harness")


def _files(folder):
    """{relative path: (size, mtime_ns)} of every file under ``folder``."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in Path(folder).rglob("*") if p.is_file()}


def _sh(*cmd, **kw):
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


def test_listed_packages_are_every_package():
    """pyproject.toml lists the packages (c_harness maps into codegen): none missing."""
    import tomllib
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for pkg in ("models", "codegen")
             for p in (ROOT / pkg).rglob("__init__.py")}
    assert found | {"codegen.c_harness"} == listed


def test_the_repository_is_bsd_2_clause_licensed():
    """Issue 24: a LICENSE at the root (BSD-2-Clause, as pinocchio and acados) and the same
    licence in the package metadata."""
    import tomllib
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("BSD 2-Clause License\n") and "the observer-codegen authors" in text
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["license"] == {"text": "BSD-2-Clause"}
    assert "License :: OSI Approved :: BSD License" in project["classifiers"]


@pytest.mark.slow
def test_wheel_in_fresh_venv_writes_nothing_in_site_packages(tmp_path):
    src, dist, venv, work = (tmp_path / d for d in ("src", "dist", "venv", "work"))
    src.mkdir()
    for name in SOURCES:                     # a clean copy: the build writes build/ and *.egg-info
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(ROOT / name, src / name)
    _sh(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q",
        "-w", dist, src)
    [wheel] = dist.glob("observer_codegen-*.whl")
    _sh(sys.executable, "-m", "venv", "--without-pip", venv)
    py = venv / "bin" / "python"
    _sh(sys.executable, "-m", "pip", "--python", py, "install", "--no-deps", "--no-index", "-q", wheel)
    site = Path(_sh(py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").strip())
    deps = sysconfig.get_paths()["purelib"]
    (site / "deps_of_the_test_venv.pth").write_text(f"{deps}\nimport cmeel_pth\n")
    before = _files(site)

    work.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CODEGEN_", "PYTHON"))}
    where = _sh(py, "-c", "import codegen, models; print(codegen.__file__); print(models.__file__)",
                cwd=work, env=env).split()
    assert all(Path(w).is_relative_to(site) for w in where), where     # the wheel, not this checkout
    assert (site / "codegen" / "c_harness" / "run_csv.c").is_file()
    [info] = site.glob("observer_codegen-*.dist-info")          # the licence travels with it
    assert "License: BSD-2-Clause" in (info / "METADATA").read_text()
    assert (info / "LICENSE").read_text() == (ROOT / "LICENSE").read_text()
    (work / "my.toml").write_text('[[target]]\nrobot = "seed002_2r"\nfamily = "su_nonsmooth"\n'
                                  'name = "two_link"\nout = "c"\n')
    out = _sh(venv / "bin" / "observer-codegen", "generate", "-c", "my.toml", "--T", "0.2", cwd=work, env=env)
    assert "two_link " in out and "C harness == ctypes: True" in out, out
    load = ("from codegen.pipeline.load import load; from codegen.pipeline.compile import compile_library; import numpy as np; "
            "o = load('c/two_link', compile_library('c/two_link')); o.reset(np.zeros(o.ny)); "
            "print(o.prefix, o.step(np.zeros(o.ny), np.zeros(o.nu)).shape == (o.nest,), o.lib_path)")
    prefix, shape_ok, lib = _sh(py, "-c", load, cwd=work, env=env).split()
    assert (prefix, shape_ok) == ("two_link", "True") and Path(lib).is_relative_to(work / "build")
    assert _files(site) == before            # nothing written (nor rewritten) in site-packages
