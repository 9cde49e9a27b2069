"""Spec -> discretize -> emit -> build -> ctypes, against the independent reference."""
import ctypes as ct
import filecmp
import json
import shutil

import numpy as np
import pytest

from codegen import compile_observer
from codegen.build import BuildError, build
from codegen.check import cross_check
from codegen.emit import emit
from codegen.runtime import ObserverError, load
from codegen.spec import sanitize
from conftest import CLOSED_FORM, DEFAULT

TOL = 1e-9


@pytest.mark.parametrize("name", DEFAULT)
def test_emitted_c_equals_reference(name, spec_of):
    """>= 1000 random inputs per default target: single steps (estimate and next state), the RHS,
    and a 1000-sample run; relative error <= 1e-9."""
    r = cross_check(spec_of(name), count=1000)
    assert r["samples"] >= 1000
    for key in ("step_est", "step_state", "rhs", "run"):
        assert r[key] <= TOL, (key, r)


@pytest.mark.parametrize("name,method,substeps,hold", [("seed000_2r", "euler", 1, "zoh"),
                                                       ("seed000_2r", "rk4", 3, "zoh"),
                                                       ("seed000_2r", "rk4", 2, "foh"),
                                                       ("ur5", "rk4", 1, "foh")])
def test_other_discretizations_match_reference(name, method, substeps, hold, spec_of):
    r = cross_check(spec_of(name), count=300, dt=2e-3, method=method, substeps=substeps, hold=hold)
    assert np.max([v for k, v in r.items() if k != "samples"]) <= TOL


def test_bad_input_raises_clear_errors(compiled):
    obs = compiled("seed000_2r")
    obs.reset([0.1, 0.2])
    with pytest.raises(ValueError, match=r"y: expected shape \(2,\)"):
        obs.step([1.0, 2.0, 3.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="u: contains NaN or Inf"):
        obs.step([1.0, 2.0], [np.nan, 0.0])
    with pytest.raises(ValueError, match="y: contains NaN or Inf"):
        obs.step([np.inf, 2.0], [0.0, 0.0])
    with pytest.raises(ValueError, match=r"U: expected shape \(3, 2\)"):
        obs.run(np.zeros((3, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="Y: NaN or Inf at row 1"):
        obs.run(np.array([[0, 0], [np.nan, 0.0]]), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="y0"):
        obs.reset([0.0])


def test_c_step_status_and_state_unchanged(compiled):
    """The C step returns its documented status and leaves the state untouched on error."""
    obs = compiled("seed000_2r")
    st = obs.meta["status"]
    obs.reset([0.1, 0.2])
    obs.step([0.1, 0.2], [1.0, 2.0])
    before = obs.state
    for y, u in (([np.nan, 0.0], [0.0, 0.0]), ([0.0, 0.0], [0.0, -np.inf])):
        status, _ = obs.c_step(y, u)
        assert status == st["ERR_NONFINITE_INPUT"]
        assert np.array_equal(obs.state, before)
    obs.state = [1e300, -1e300]                       # overflows in C(y, x2hat) x2hat
    status, _ = obs.c_step([0.1, 0.2], [0.0, 0.0])
    assert status == st["ERR_NONFINITE_RESULT"]
    assert np.array_equal(obs.state, [1e300, -1e300])
    with pytest.raises(ObserverError, match="ERR_NONFINITE_RESULT"):
        obs.step([0.1, 0.2], [0.0, 0.0])
    null = ct.POINTER(ct.c_double)()
    assert obs._step(obs._s, null, null, null) == st["ERR_BAD_ARG"]
    assert np.array_equal(obs.state, [1e300, -1e300])
    with pytest.raises(ValueError, match="x: contains NaN"):
        obs.state = [np.nan, 0.0]


def test_run_stops_at_first_bad_result_and_reports_it(compiled):
    obs = compiled("seed000_2r")
    obs.reset([0.0, 0.0])
    Y = np.zeros((5, 2))
    Y[3] = 1e306   # x2hat = z + k0 y overflows
    with pytest.raises(ObserverError, match="sample 3"):
        obs.run(Y, np.zeros((5, 2)))


def test_params_are_runtime_and_reset(compiled):
    obs = compiled("seed000_2r")
    assert obs.params == pytest.approx(obs.p_default)
    obs.reset([0.0, 0.0], p=[5.0])
    assert obs.params == pytest.approx([5.0])
    obs.reset([0.3, -0.2], est0=[1.0, -1.0])
    assert obs.state == pytest.approx(np.array([1.0, -1.0]) - obs.p_default[0] * np.array([0.3, -0.2]))


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


def test_two_targets_in_one_process(compiled, spec_of):
    from codegen.reference import reference_observer
    obs = {n: compiled(n) for n in ("seed000_2r", "seed002_2r")}
    y, u = np.array([0.3, -0.4]), np.array([2.0, 1.0])
    for n, o in obs.items():
        o.reset(y)
        ref = reference_observer(spec_of(n))
        ref.reset(y)
        for _ in range(3):
            assert np.allclose(o.step(y, u), ref.step(y, u), rtol=1e-12)
    assert obs["seed000_2r"].prefix != obs["seed002_2r"].prefix


@pytest.mark.parametrize("name", ["seed000_2r", "ur5"])
def test_strict_c99_compile(name, spec_of, tmp_path):
    """The emitted C compiles with -std=c99 -Wall -Wextra -Werror -pedantic."""
    target = emit(spec_of(name), tmp_path / "t")
    lib = build(target, strict=True, cache=tmp_path / "cache")
    assert lib.exists()


def test_compile_error_shows_compiler_message(spec_of, tmp_path):
    target = emit(spec_of("seed000_2r"), tmp_path / "t")
    c = target / f"{target.name}.c"
    c.write_text(c.read_text() + "\nint broken( {\n")
    with pytest.raises(BuildError) as e:
        build(target, cache=tmp_path / "cache")
    assert f"{target.name}.c" in str(e.value) and "error" in str(e.value)


def test_emit_failure_leaves_nothing_half_written(spec_of, tmp_path):
    spec = spec_of("seed000_2r")
    good = emit(spec, tmp_path)
    before = {p.name: p.read_bytes() for p in good.iterdir()}
    bad = type(spec)(**{**spec.__dict__, "p_default": [np.nan]})
    with pytest.raises(ValueError, match="non-finite"):
        emit(bad, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [good.name]
    assert {p.name: p.read_bytes() for p in good.iterdir()} == before


def test_metadata_and_header_describe_the_target(spec_of, tmp_path):
    spec = spec_of("seed000_2r")
    target = emit(spec.target(dt=2e-3, method="euler", substeps=2, hold="zoh"), tmp_path, spec=spec)
    meta = json.loads((target / f"{target.name}.json").read_text())
    assert meta["sizes"] == {"nx": 2, "ny": 2, "nu": 2, "np": 1, "nest": 2}
    assert meta["discretization"] == {"dt": 2e-3, "method": "euler", "substeps": 2, "hybrid": False,
                                      "hold": "zoh"}
    assert meta["p_default"] == [float(spec.p_default[0])]
    assert meta["robot"]["fingerprint"] == spec.robot.fingerprint
    h = (target / f"{target.name}.h").read_text()
    P = target.name.upper()
    assert f"#define {P}_NX 2" in h and f"#define {P}_P_K0 0" in h and f"{target.name}_step(" in h


def test_sanitized_identifiers():
    assert sanitize("UR5 robot/v2*/") == "ur5_robot_v2"
    assert sanitize("5dof") == "t_5dof"
    assert sanitize("*/") == "x"


def test_compile_observer_bad_arguments(spec_of):
    with pytest.raises(ValueError, match="method"):
        compile_observer(spec_of("seed000_2r"), method="rk45")
    with pytest.raises(ValueError, match="dt must be a positive"):
        compile_observer(spec_of("seed000_2r"), dt=-1.0)


def test_load_by_absolute_path_from_elsewhere(compiled, tmp_path, monkeypatch):
    obs = compiled("seed000_2r")
    copy = tmp_path / "lib" / obs.lib_path.name
    copy.parent.mkdir()
    shutil.copy(obs.lib_path, copy)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("LD_LIBRARY_PATH", raising=False)
    o2 = type(obs)(copy, obs.meta)
    o2.reset([0.0, 0.0])
    assert o2.step([0.0, 0.0], [0.0, 0.0]).shape == (2,)


def test_estimate_equals_step_without_advancing(compiled, spec_of):
    from codegen.reference import reference_observer
    obs, ref = compiled("ur5"), reference_observer(spec_of("ur5"))
    y, u = np.linspace(-0.5, 0.5, 6), np.linspace(1, 6, 6)
    obs.reset(y, est0=np.ones(6))
    ref.reset(y, est0=np.ones(6))
    x0 = obs.state
    e = obs.estimate(y, u)
    assert np.array_equal(obs.state, x0)
    assert np.allclose(e, ref.estimate(y, u), rtol=1e-12)
    assert np.array_equal(obs.step(y, u), e)


@pytest.mark.parametrize("name", ["seed000_2r", "ur5"])
def test_c_harness_csv_equals_ctypes(name, compiled, spec_of, tmp_path):
    """The standalone C program (no Python) gives the same estimates, bit for bit, as ctypes."""
    from codegen import harness
    from codegen.trajectory import demo_trajectory
    obs = compiled(name)
    target = emit(spec_of(name), tmp_path / "t")
    t, Q, QD, TAU = demo_trajectory(spec_of(name).robot, T=0.5)
    harness.write_csv(tmp_path / "in.csv", t, Q, TAU)
    est0 = np.full(obs.nest, 0.25)
    harness.run_csv(target, tmp_path / "in.csv", tmp_path / "out.csv", est0=est0)
    t_out, EST = harness.read_csv(tmp_path / "out.csv")
    obs.reset(Q[0], est0=est0)
    assert np.array_equal(t_out, t)
    assert np.array_equal(EST, obs.run(Q, TAU))



@pytest.mark.parametrize("name", ["seed000_2r", "ur5"])
def test_first_order_hold_removes_the_sampling_bias(name, spec_of):
    """With y held, an output-injection observer settles at a/(1 - exp(-a)) qd, a = k0 dt (ur5:
    k0 dt ~ 0.48, a 27 % overshoot); the first-order hold leaves only an O(dt qdd) bias."""
    from codegen.trajectory import demo_trajectory
    spec = spec_of(name)
    t, Q, QD, TAU = demo_trajectory(spec.robot, T=2.0)
    err = {}
    for hold in ("zoh", "foh"):
        obs = compile_observer(spec, hold=hold)
        obs.reset(Q[0])
        err[hold] = np.abs(obs.run(Q, TAU)[len(t) // 2:] - QD[len(t) // 2:]).max()
    a = spec.p_default[0] * 1e-3
    assert err["zoh"] > 0.5 * (a / (1 - np.exp(-a)) - 1) * np.abs(QD).max()
    assert err["foh"] < 2e-3


def test_generated_folder_builds_standalone(spec_of, tmp_path):
    """What an embedded user does: no Python, just the folder's Makefile or CMakeLists.txt."""
    import subprocess
    target = emit(spec_of("seed000_2r"), tmp_path)
    r = subprocess.run(["make", "-C", str(target)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (target / f"lib{target.name}.a").exists() and (target / f"lib{target.name}.so").exists()
    if shutil.which("cmake"):
        b = tmp_path / "cmake-build"
        for cmd in (["cmake", "-S", str(target), "-B", str(b)], ["cmake", "--build", str(b)]):
            r = subprocess.run(cmd, capture_output=True, text=True)
            assert r.returncode == 0, r.stdout + r.stderr
        assert (b / f"lib{target.name}.a").exists()


def test_rk4_calling_a_shared_rhs_equals_the_inlined_one(spec_of, tmp_path):
    """inline=False (the stages call one RHS routine, for big observers) gives the same numbers
    and strict C99."""
    from codegen.trajectory import demo_trajectory
    spec = spec_of("ur5")
    t, Q, QD, TAU = demo_trajectory(spec.robot, T=0.3)
    ests = []
    for inline in (True, False):
        target = emit(spec.target(hold="foh", substeps=2, inline=inline), tmp_path / str(inline), spec=spec)
        obs = load(target, build(target, strict=True, cache=tmp_path / "cache"))
        obs.reset(Q[0])
        ests.append(obs.run(Q, TAU))
    assert np.allclose(ests[0], ests[1], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("family,robot", [("reduced_order_hybrid", "seed000_2r"),
                                          ("nicosia_tomei", "seed000_2r"),
                                          ("lotfi_namvar", "seed002_2r"),
                                          ("su_nonsmooth", "seed002_2r"),
                                          ("ii_speed", "seed003_2r_abs"),
                                          ("ii_aov", "seed003_2r_abs")])
def test_cli_check_works_for_every_rigid_family(family, robot):
    """`python -m codegen check ROBOT --family F` (the generic cross-check with the family's own
    random inputs where it has them) for every rigid-robot family; elastic families are
    cross-checked in tests/papers/test_seed004.py."""
    from codegen.cli import main
    assert main(["check", robot, "--family", family, "--count", "100"]) == 0
