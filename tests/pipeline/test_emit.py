"""Emit: the generated folder (templates filled from the metadata, CasADi kernels), deterministic,
all or nothing, rebuildable from its metadata, and never changing the working directory."""
import copy
import filecmp
import json
import os
import threading
import tomllib
from dataclasses import replace
from fnmatch import fnmatch
from importlib import resources

import numpy as np
import pytest

from codegen import build_spec
from codegen.pipeline.emit import TEMPLATES, emit, render
from codegen.core.spec import sanitize
from codegen.core.target import Target
from conftest import ROOT


def test_generation_is_deterministic(tmp_path, spec_of):
    for name in ("seed000_2r", "ur5"):
        a = emit(spec_of(name), tmp_path / "a")
        b = emit(spec_of(name), tmp_path / "b")
        files = sorted(p.name for p in a.iterdir())
        assert files == sorted(p.name for p in b.iterdir())
        assert {f"{a.name}.h", f"{a.name}.c", f"{a.name}_kernels.c", f"{a.name}_kernels.h",
                "Makefile", "CMakeLists.txt", f"{a.name}.json"} <= set(files)
        match, mismatch, errors = filecmp.cmpfiles(a, b, files, shallow=False)
        assert not mismatch and not errors
        # regenerating over an existing target also gives the same bytes
        c = emit(spec_of(name), tmp_path / "a")
        assert filecmp.cmpfiles(c, b, files, shallow=False)[1] == []


def test_emit_failure_leaves_nothing_half_written(spec_of, tmp_path):
    spec = spec_of("seed000_2r")
    good = emit(spec, tmp_path)
    before = {p.name: p.read_bytes() for p in good.iterdir()}
    bad = copy.copy(spec)
    bad.p_default = np.array([np.nan])     # past the spec's own check: emit still refuses it
    with pytest.raises(ValueError, match="non-finite"):
        emit(bad, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [good.name]
    assert {p.name: p.read_bytes() for p in good.iterdir()} == before


def test_metadata_and_header_describe_the_target(spec_of, tmp_path):
    spec = spec_of("seed000_2r")
    target = emit(spec.target(dt=2e-3, method="euler", substeps=2, hold="zoh"), tmp_path, spec=spec)
    meta = json.loads((target / f"{target.name}.json").read_text())
    assert meta["sizes"] == {"nx": 2, "ny": 2, "nu": 2, "np": 1, "nest": 2, "nm": 0}
    assert meta["discretization"] == {"dt": 2e-3, "method": "euler", "substeps": 2, "hybrid": False,
                                      "hold": "zoh", "dt_min": 2e-3 / 4, "dt_max": 2 * 2e-3,
                                      "split_max": 1000, "stamp_tol": 4 * 2.0 ** -52}
    assert meta["p_default"] == [float(spec.p_default[0])]
    assert meta["robot"]["fingerprint"] == spec.robot.fingerprint
    h = (target / f"{target.name}.h").read_text()
    P = target.name.upper()
    assert f"#define {P}_NX 2" in h and f"#define {P}_P_K0 0" in h and f"{target.name}_step(" in h
    assert f"#define {P}_DT_MIN 0.0005" in h and f"#define {P}_DT_MAX 0.004" in h
    assert f"{target.name}_step_dt(" in h and f"{target.name}_run_t(" in h
    # the default method keeps the model's last value (2 entries) in the state struct
    default = emit(spec.target(name="with_memory"), tmp_path, spec=spec)
    assert json.loads((default / "with_memory.json").read_text())["sizes"]["nm"] == 2
    assert "#define WITH_MEMORY_NM 2" in (default / "with_memory.h").read_text()


def test_sanitized_identifiers():
    assert sanitize("UR5 robot/v2*/") == "ur5_robot_v2"
    assert sanitize("5dof") == "t_5dof"
    assert sanitize("*/") == "x"


def _same_files(a, b):
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    assert not mismatch and not errors, mismatch + errors


def _rebuild_cases(spec_of):
    from codegen.families import observers
    from models.catalog import load_elastic
    s = spec_of("seed000_2r")
    lotfi = observers.build("lotfi_namvar", spec_of("seed002_2r").robot)
    cg = observers.build("ciccarella_germani", load_elastic("seed004_2r"), variant="O2")
    return [(s, replace(s.target(dt=2e-3, method="euler", substeps=2, hold="zoh"),
                        params={s.p_names[0]: 7.5})),
            (lotfi, lotfi.target()), (cg, cg.target())]


def test_metadata_is_enough_to_rebuild_the_target(spec_of, tmp_path):
    """Target.from_dict(meta["target"]) is the target, and building its spec from that data alone
    (robot source, family, variant, build arguments, params, discretisation) gives the same bytes."""
    for spec, target in _rebuild_cases(spec_of):
        a = emit(target, tmp_path / "a", spec=spec)
        meta = json.loads((a / f"{a.name}.json").read_text())
        again = Target.from_dict(meta["target"])
        assert again == target
        _same_files(a, emit(again, tmp_path / "b", spec=build_spec(again)))


def test_emit_never_changes_the_working_directory(spec_of, tmp_path, monkeypatch):
    """CasADi writes into a directory prefix: emitting from a thread leaves the process's cwd alone."""
    spec = spec_of("seed000_2r")
    cwd = os.getcwd()

    def no_chdir(path):
        raise AssertionError(f"emit called os.chdir({path!r})")
    monkeypatch.setattr(os, "chdir", no_chdir)
    out, errors = [], []

    def work():
        try:
            out.append(emit(spec, tmp_path / "thread"))
        except BaseException as e:  # reported in the main thread
            errors.append(e)
    t = threading.Thread(target=work)
    t.start()
    t.join()
    assert not errors, errors
    assert os.getcwd() == cwd
    monkeypatch.undo()
    _same_files(out[0], emit(spec, tmp_path / "main"))


def test_templates_are_package_data():
    """Every template emit fills is declared in pyproject.toml's package data (so a wheel has it)."""
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    for name in TEMPLATES:
        assert (resources.files("codegen.pipeline") / "templates" / name).is_file(), name
        assert any(fnmatch(f"templates/{name}", g) for g in globs["codegen.pipeline"]), name


def test_render_names_a_missing_placeholder():
    with pytest.raises(ValueError, match=r"\['prefix'\] of template Makefile.in"):
        render("Makefile.in", {})
    assert render("Makefile.in", {"prefix": "abc"}).startswith("# Build libabc.a from the generated sources")
