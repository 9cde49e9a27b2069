"""Runtime: the ctypes CompiledObserver (bad input, C status codes, parameters, several targets)
and the standalone C harness agreeing with it."""
import ctypes as ct
import shutil

import numpy as np
import pytest

from codegen.pipeline.emit import emit
from codegen.pipeline.load import ObserverError


def test_bad_input_raises_clear_errors(compiled):
    obs = compiled("seed000_2r")
    obs.reset([0.1, 0.2])
    with pytest.raises(ValueError, match=r"y: expected shape \(2,\)"):
        obs.step([1.0, 2.0, 3.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="u: expected .* finite numbers.*NaN or Inf"):
        obs.step([1.0, 2.0], [np.nan, 0.0])
    with pytest.raises(ValueError, match="y: expected .* finite numbers.*NaN or Inf"):
        obs.step([np.inf, 2.0], [0.0, 0.0])
    with pytest.raises(ValueError, match=r"U: expected shape \(3, 2\)"):
        obs.run(np.zeros((3, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="Y: NaN or Inf at row 1"):
        obs.run(np.array([[0, 0], [np.nan, 0.0]]), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="y0"):
        obs.reset([0.0])


def test_c_step_status_and_state_unchanged(unranged):
    """The C step returns its documented status and leaves the state untouched on error."""
    obs = unranged
    st = obs.meta["status"]
    obs.reset([0.1, 0.2])
    obs.step([0.1, 0.2], [1.0, 2.0])
    before = obs.state
    for y, u in (([np.nan, 0.0], [0.0, 0.0]), ([0.0, 0.0], [0.0, -np.inf])):
        status, _ = obs.c_step(y, u)
        assert status == st["ERR_NONFINITE_INPUT"]
        assert np.array_equal(obs.state, before)
    # a huge state no longer overflows (the model sees the estimate saturated to its velocity
    # bound, codegen.families.observers._bound); a measurement with k0 y beyond a double does
    obs.state = [1e300, -1e300]
    status, _ = obs.c_step([0.1, 0.2], [0.0, 0.0])
    assert status == 0
    obs.state = [1e300, -1e300]
    huge = [1.7e308, 0.2]                             # x2hat = z + k0 y overflows
    status, _ = obs.c_step(huge, [0.0, 0.0])
    assert status == st["ERR_NONFINITE_RESULT"]
    assert np.array_equal(obs.state, [1e300, -1e300])
    with pytest.raises(ObserverError, match="ERR_NONFINITE_RESULT"):
        obs.step(huge, [0.0, 0.0])
    null = ct.POINTER(ct.c_double)()
    assert obs._step(obs._s, null, null, null) == st["ERR_BAD_ARG"]
    assert np.array_equal(obs.state, [1e300, -1e300])
    with pytest.raises(ValueError, match="x: expected 2 finite numbers.*NaN"):
        obs.state = [np.nan, 0.0]


def test_run_stops_at_first_bad_result_and_reports_it(unranged):
    obs = unranged
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
    from codegen.verify import c_programs
    from codegen.verify.trajectory import demo_trajectory
    obs = compiled(name)
    target = emit(spec_of(name), tmp_path / "t")
    t, Q, QD, TAU = demo_trajectory(spec_of(name).robot, T=0.5)
    c_programs.write_csv(tmp_path / "in.csv", t, Q, TAU)
    est0 = np.full(obs.nest, 0.25)
    c_programs.run_csv(target, tmp_path / "in.csv", tmp_path / "out.csv", est0=est0)
    t_out, EST = c_programs.read_csv(tmp_path / "out.csv")
    obs.reset(Q[0], est0=est0)
    assert np.array_equal(t_out, t)
    assert np.array_equal(EST, obs.run(Q, TAU))


@pytest.mark.parametrize("family", ["reduced_order", "reduced_order_hybrid", "reduced_order_switched",
                                    "nicosia_tomei", "extended_state"])
def test_retuning_is_bumpless_in_c_and_reference(family, tmp_path):
    """At rest at q = (1, 0.5), a gain change mid-run moves the estimate by <= 1e-12 (the state
    is transformed: z += (k_old - k_new) y), in the C and in the reference; without the
    transform the estimate would jump by (k_new - k_old) q."""
    from codegen import compile_observer
    from codegen.core.estimator import full_estimate
    from codegen.families import observers
    from codegen.reference import reference_observer
    from models import load_robot
    robot = load_robot("seed000_2r")
    spec = observers.build(family, robot)
    q = np.array([1.0, 0.5])
    g = np.asarray(robot.g(q)).ravel()
    p_new = spec.p_default.copy()
    p_new[0] *= 3.0                                 # k0, k_1 or kd
    for o in (compile_observer(spec, out_dir=tmp_path), reference_observer(spec)):
        o.reset(q)
        for _ in range(20):
            o.step(q, g)
        before = o.estimate(q, g)
        o.params = p_new
        assert np.abs(o.estimate(q, g) - before).max() <= 1e-12
        assert np.abs(o.step(q, g) - before).max() <= 1e-12
        est0 = full_estimate(spec.est_names, [0.3, -0.2])   # extended_state: tau_d_hat(0) = 0
        o.reset(q, est0=est0)                       # right after init: the last y is y0
        o.params = p_new
        assert np.abs(o.estimate(q, g) - est0).max() <= 1e-12


def test_load_a_folder_the_cli_built(tmp_path, capsys):
    """`build` then ``codegen.load("<out>/<target>")``: the observer of that folder, its library
    from the compile cache (no library path to find)."""
    import codegen
    from codegen import cli
    assert cli.main(["build", "seed000_2r", "--out", str(tmp_path)]) == 0
    obs = codegen.load(tmp_path / "seed000_2r_reduced_order")
    assert obs.prefix == "seed000_2r_reduced_order" and obs.nest == 2
    obs.reset(np.zeros(2))
    assert np.all(np.isfinite(obs.step(np.full(2, 1e-3), np.zeros(2))))


def test_params_check_all_gains_jointly_and_every_phase(tmp_path):
    """Issue 22 F5, F1: without the spec (load() of a built folder), new parameters moving two gains
    run the full check on the spec rebuilt from the metadata: nicosia_tomei (RK4) with kd and kp
    each at 0.98 of its recorded bound is refused (jointly unstable), each alone passes; the
    switched observer's k0_final = 5000 with RK4 is refused through obs.params and load()."""
    from codegen import compile_observer
    from codegen.discrete.stability import UnstableDiscretization
    from codegen.families import observers
    from codegen.pipeline.load import load
    from models import load_robot
    robot = load_robot("seed000_2r")
    obs = compile_observer(observers.build("nicosia_tomei", robot), method="rk4", substeps=1, out_dir=tmp_path)
    loaded = load(tmp_path / obs.prefix, obs.lib_path)
    assert loaded.spec is None
    bounds = loaded.meta["stability"]["gains"]
    names = loaded.meta["names"]["p"]
    p = np.array(loaded.p_default)
    both = p.copy()
    for g in ("kd", "kp"):
        alone = p.copy()
        alone[names.index(g)] = both[names.index(g)] = 0.98 * bounds[g]["max_stable"]
        loaded.params = alone
    with pytest.raises(UnstableDiscretization, match="spectral radius"):
        loaded.params = both
    switched = observers.build("reduced_order_switched", robot)
    k0, _, t_switch = switched.p_default
    obs = compile_observer(switched, method="rk4", out_dir=tmp_path)
    loaded = load(tmp_path / obs.prefix, obs.lib_path)
    for o in (obs, loaded):
        with pytest.raises(UnstableDiscretization, match="k0_final = 5000.*0 <= k0_final <= [0-9]"):
            o.params = [k0, 5000.0, t_switch]
        with pytest.raises(UnstableDiscretization, match="k0_final = 5000"):
            o.reset(np.zeros(2), p=[k0, 5000.0, t_switch])
    assert np.array_equal(loaded.params, switched.p_default)


def test_parameters_accepted_by_the_verdict_alone(tmp_path, monkeypatch):
    """obs.params = p, checked in full (two gains moved), asks the check for its verdict only: no
    search for the largest stable gains (a third of the check for kalman_model; tune and compare
    check many candidates), which a refusal still names (the test above), unless asked not to
    explain itself (``check_params(p, explain=False)``: a tuning's refused candidate)."""
    import codegen.discrete.stability as stability
    from codegen import compile_observer
    from codegen.families import observers
    from models import load_robot
    spec = observers.build("reduced_order_switched", load_robot("seed000_2r"))
    obs = compile_observer(spec, method="rk4", out_dir=tmp_path)

    def searched(*args, **kwargs):
        raise AssertionError("searched for the bounds")
    monkeypatch.setattr(stability, "_max_stable", searched)
    p = spec.p_default * [0.5, 0.5, 1.0]
    obs.params = p
    assert np.array_equal(obs.params, p)
    # a tuning's candidate, refused without the ranges (explain=False): the verdict alone still
    with pytest.raises(stability.UnstableDiscretization, match="k0_final = 5000"):
        obs.check_params(spec.p_default * [1.0, 0.0, 1.0] + [0.0, 5000.0, 0.0], explain=False)


@pytest.mark.parametrize("size", ["ny", "nest"])
def test_metadata_sizes_checked_against_the_library(size, spec_of, tmp_path):
    """Issue 22, F16: sizes.ny or sizes.nest edited to 1 in the metadata made the steps read and
    write past the buffers. The library exports its own sizes (<prefix>_sizes); the loader checks
    the metadata against them before passing any buffer, and load() checks the metadata kept
    beside the library against its build record."""
    import json

    from codegen.pipeline.compile import CompileError, compile_library
    from codegen.pipeline.load import CompiledObserver, LibraryMismatch, load
    folder = emit(spec_of("seed000_2r"), tmp_path / "t")
    lib = compile_library(folder, cache=tmp_path / "cache")
    obs = load(folder, lib)
    sizes = ("nx", "ny", "nu", "np", "nest")      # (nm, the step's memory, lives in the C state alone)
    assert {k: getattr(obs, k) for k in sizes} == {k: obs.meta["sizes"][k] for k in sizes}
    meta = json.loads((folder / f"{folder.name}.json").read_text())
    meta["sizes"][size] = 1
    with pytest.raises(LibraryMismatch, match=rf"sizes differ from the library's own: {size} = 1 \(library: 2\)"):
        CompiledObserver(lib, meta)
    kept = lib.parent / f"{folder.name}.json"
    kept.write_text(json.dumps(meta))                       # the copy beside the library, edited
    with pytest.raises(CompileError, match=f"{kept.name} is corrupt or unverified: .*recorded at build"):
        load(folder, lib)
    kept.unlink()                                           # then the folder's own, edited
    (folder / f"{folder.name}.json").write_text(json.dumps(meta))
    with pytest.raises(LibraryMismatch, match=f"{size} = 1"):
        load(folder, lib)
