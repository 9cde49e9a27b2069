"""Single precision and the embedded flow: float targets (one real type, float math, no double
promotion, the ctypes boundary), their error against the double reference, the example firmware
on emulated Cortex-M4F (float) and Cortex-M7 (double), and the generated Makefile/CMakeLists."""
import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

from codegen import compile_observer
from codegen.verify import cortex_m, newlib_libm
from codegen.pipeline.compile import compile_library
from codegen.pipeline.emit import emit

from conftest import DEFAULT, ROOT

EPS32 = float(np.finfo(np.float32).eps)
ARM_CFLAGS = "-mthumb -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard"


@pytest.fixture(scope="session")
def arm():
    """The ARM toolchain and QEMU, installed through `make arm-toolchain` (apt-get) when missing;
    the tests skip only when they are absent and cannot be installed (not root, no apt-get)."""
    missing = cortex_m.missing_packages()
    if missing and shutil.which("apt-get") and os.geteuid() == 0:
        subprocess.run(["make", "-s", "-C", str(ROOT), "arm-toolchain"], capture_output=True)
        missing = cortex_m.missing_packages()
    if missing:
        pytest.skip(f"ARM toolchain absent and not installable here: apt-get install {' '.join(missing)}")


@pytest.fixture(scope="module")
def seed000(spec_of, tmp_path_factory):
    """seed000_2r's reduced-order target in both precisions: {precision: folder}."""
    spec, out = spec_of("seed000_2r"), tmp_path_factory.mktemp("seed000")
    return {p: emit(spec.target(precision=p), out, spec=spec) for p in ("double", "float")}


def _sources(folder):
    return {f.name: f.read_text() for f in folder.iterdir() if f.suffix in (".c", ".h")}


def _undefined(folder, tmp_path, cc="gcc", nm="nm", cflags=()):
    """Symbols the target's objects need from outside (compiled with -Wdouble-promotion -Werror)."""
    need = set()
    for c in sorted(folder.glob("*.c")):
        obj = tmp_path / (c.stem + ".o")
        subprocess.run([cc, "-O2", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Wdouble-promotion",
                        "-Werror", *cflags, "-I", str(folder), "-c", str(c), "-o", str(obj)], check=True)
        need |= set(subprocess.run([nm, "-u", str(obj)], capture_output=True, text=True,
                                   check=True).stdout.split()) - {"U"}
    return {s for s in need if not s.startswith(folder.name)}


# ------------------------------------------------------------------ single precision
def test_float_target_has_one_real_type_and_float_math(seed000, tmp_path):
    f, d = seed000["float"], seed000["double"]
    meta = json.loads((f / f"{f.name}.json").read_text())
    assert meta["precision"] == "float" and meta["target"]["precision"] == "float"
    assert f.name == d.name + "_float"
    src = _sources(f)
    assert f"typedef float {f.name}_real;" in src[f"{f.name}.h"]
    assert not any(re.search(r"\bdouble\b", text) for text in src.values())   # one real type
    assert re.search(rf"#define {f.name.upper()}_DT 0\.001f", src[f"{f.name}.h"])
    k0 = meta["p_default"][0]                         # the designed default, as a float literal
    assert re.search(rf"p_default\[1\] = \{{{int(k0)}\.\d+f\}}", src[f"{f.name}.c"])
    for kernels in (f"{f.name}_kernels.c", f"{f.name}_kernels.h"):     # casadi_real from the header
        assert f'#include "{f.name}.h"' in src[kernels] and f"#define casadi_real {f.name}_real" in src[kernels]
    need = _undefined(f, tmp_path)
    assert need and not any(cortex_m.DOUBLE_ROUTINES.match(s) for s in need), need   # cosf, sincosf
    assert "double" in _sources(d)[f"{d.name}.h"]
    assert any(cortex_m.DOUBLE_ROUTINES.match(s) for s in _undefined(d, tmp_path))   # cos, sincos
    assert compile_library(f, strict=True, cache=tmp_path / "cache").exists()


def test_float_ii_quadrature_loops_stay_single_precision(tmp_path):
    """The I&I quadrature routines (CasADi maps: loops over the nodes, called routines) are
    emitted in float too: no double in the sources, float math only."""
    from models import load_robot

    from codegen.families.observers import build as build_observer
    spec = build_observer("ii_aov", load_robot("seed003_2r_abs"), N=4)
    f = emit(spec.target(precision="float"), tmp_path / "t", spec=spec)
    assert not any(re.search(r"\bdouble\b", text) for text in _sources(f).values())
    need = _undefined(f, tmp_path)
    assert {"sinf", "sqrtf"} <= need and not any(cortex_m.DOUBLE_ROUTINES.match(s) for s in need), need


def test_float_runtime_converts_at_the_boundary(spec_of):
    from codegen.pipeline.load import ObserverError
    obs = compile_observer(spec_of("seed000_2r"), precision="float")
    assert obs.precision == "float" and obs.dtype == np.float32
    assert obs.p_default.dtype == np.float64 and obs.p_default[0] == np.float32(spec_of("seed000_2r").p_default[0])
    obs.reset([0.1, 0.2])
    est = obs.step([0.1, 0.2], [1.0, 2.0])
    assert est.dtype == np.float64 and np.array_equal(est, est.astype(np.float32))
    assert obs.run(np.zeros((3, 2)), np.zeros((3, 2))).dtype == np.float64
    with pytest.raises(ValueError, match=r"y: value 1e\+39 outside the float32 range"):
        obs.step([1e39, 0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="U: value .* outside the float32 range"):
        obs.run(np.zeros((2, 2)), np.full((2, 2), -1e39))
    with pytest.raises(ValueError, match="need a C-contiguous float32 array"):
        obs.bind(np.zeros(2), np.zeros(2), np.zeros(2))
    y, u, e = (np.zeros(2, np.float32) for _ in range(3))
    step, _ = obs.bind(y, u, e)
    y[:] = 0.3
    step()
    assert np.all(np.isfinite(e)) and e.dtype == np.float32
    obs.state = [3e38, -3e38]                              # finite in float, overflows in the step
    with pytest.raises(ObserverError, match="ERR_NONFINITE_RESULT"):
        obs.step([0.1, 0.2], [0.0, 0.0])


def test_c_harness_runs_a_float_target(seed000, tmp_path):
    """run_csv (no Python) on a float target gives the ctypes loader's estimates bit for bit."""
    from codegen.verify import c_programs
    from codegen.pipeline.load import load
    folder = seed000["float"]
    t = np.arange(50) * 1e-3
    Y, U = np.column_stack([np.sin(t), np.cos(t)]), np.ones((50, 2))
    c_programs.write_csv(tmp_path / "in.csv", t, Y, U)
    c_programs.run_csv(folder, tmp_path / "in.csv", tmp_path / "out.csv", work_dir=tmp_path / "h")
    _, est = c_programs.read_csv(tmp_path / "out.csv")
    obs = load(folder, compile_library(folder))
    obs.reset(Y[0])
    assert np.array_equal(est, obs.run(Y, U))


# measured with margin: max err / (eps32 (1 + cond)) over the five targets was 1.6-4.4 for RK4 and
# 19.8-23.5 for ETD-RK4 (which rounds the gain term once more: N = f + a z, then E z); expmid (the
# default, ETD-RK4 on the gain terms with the model held) measured like ETD-RK4 in one run
# (12.8-13.6 for both); expmid1 (the default: the same with the model once per sub-step) 12.8-13.5,
# so expmid (measured alike, the same rounding of the gain terms) is no longer run here
FLOAT_FACTOR = {"rk4": 8, "etdrk4": 32, "expmid1": 32}


@pytest.mark.parametrize("method", sorted(FLOAT_FACTOR))
@pytest.mark.parametrize("name", DEFAULT)
def test_float_c_against_double_reference_over_10s(name, method, spec_of):
    """Float C vs the double (numpy) reference over a 10 s run of the built-in trajectory.

    Bound, per target and method: c eps32 (1 + k0 max|y| / max|est|). Its form is the first-order
    rounding error of the reduced-order estimate est = z + k0 y (rounding y and the sum loses
    eps32 k0 |y| against the size of est: the condition number of the cancellation); the factor c
    (FLOAT_FACTOR) is measured with margin for each integrator.
    """
    from codegen.reference import reference_observer
    from codegen.core.target import Discretization
    from codegen.verify.trajectory import demo_trajectory
    spec = spec_of(name)
    t, Q, QD, TAU = demo_trajectory(spec.robot, T=10.0)
    ref = reference_observer(spec, Discretization(method=method))
    obs = compile_observer(spec, precision="float", method=method)
    ref.reset(Q[0]), obs.reset(Q[0])
    want, got = ref.run(Q, TAU), obs.run(Q, TAU)
    err = cortex_m.run_relative_error(got, want)
    cond = spec.params["k0"] * np.max(np.abs(Q)) / np.max(np.abs(want))
    bound = FLOAT_FACTOR[method] * EPS32 * (1 + cond)
    assert EPS32 / 2 < err <= bound, (err, bound, cond)    # float indeed, and within the bound


# ------------------------------------------------------------------ Cortex-M
def test_firmware_runs_float_on_m4f_and_double_on_m7(arm, seed000, spec_of, tmp_path):
    """Both CPUs, a pass through step() and one through step_dt() with jittered elapsed times
    (0.7-1.6 dt; the 100th and 200th interval 10 dt: split into 5 kernel calls of 2 dt each)."""
    from codegen.verify import run_inputs
    from codegen.verify.inputs import jittered_stamps
    Y, U = run_inputs(spec_of("seed000_2r"), 200, 1e-3)
    H = np.concatenate([[1e-3], np.diff(jittered_stamps(200, 1e-3))])
    recs = {cpu: cortex_m.verify(seed000[prec], cpu, Y, U, work_dir=tmp_path, H=H)
            for cpu, (_, prec) in cortex_m.CPUS.items()}
    for cpu, rec in recs.items():
        assert rec["ok"] and rec["steps"] == 200
        assert rec["rel_diff_host"] <= rec["tolerance"] and rec["rel_diff_host_dt"] <= rec["tolerance"]
        assert rec["bit_identical_newlib"] is (None if newlib_libm.unavailable() else True)
        assert rec["bit_identical_newlib_dt"] is (None if newlib_libm.unavailable() else True)
        # one kernel call per sample, five for the two gaps: the mean is 1 + 2 * 4 / 200 times a step's
        per_step = rec["instructions_per_step"]
        assert 1.0 < rec["instructions_per_step_dt"] / per_step < 1.04 + 0.03
        # (the checks and copies of the wrapper are paid once per sample, not per kernel call)
        assert 4 * per_step < rec["instructions_per_step_dt_max"] < 5.5 * per_step
        assert rec["stack_peak_bytes"] <= rec["stack_peak_bytes_dt"] < rec["stack_size_bytes"]
        assert abs(rec["instructions_per_tick"] - 40.0) < 0.4     # -icount shift=0 at 25 MHz
        assert 100 < rec["instructions_per_step"] <= rec["instructions_per_step_max"] < 5000
        assert 0 < rec["stack_peak_bytes"] < rec["stack_size_bytes"]
        assert 1000 < rec["flash_bytes"] < 64 * 1024 and rec["static_ram_bytes"] > 0
    assert recs["m4f"]["double_routines"] == []
    elf = tmp_path / f"{seed000['float'].name}-m4f" / "firmware.elf"
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", str(elf)], capture_output=True, text=True).stdout
    called = set(re.findall(r"\tbl?\w*\s+[0-9a-f]+ <([\w.]+)>", dis))
    assert "sincosf" in called or "cosf" in called
    assert not {c for c in called if cortex_m.DOUBLE_ROUTINES.match(c)}
    assert not re.search(r"\bv\w+\.f64\b", dis)                     # no double FPU instruction
    with pytest.raises(ValueError, match="cpu: m4f runs float targets"):
        cortex_m.verify(seed000["double"], "m4f", Y, U, work_dir=tmp_path)


def test_host_build_with_newlibs_math_is_the_m7_bit_for_bit(arm, tmp_path):
    """The libm.a members the firmware linked, rebuilt for the host and linked into its build:
    the M7's estimates bit for bit over 300 steps, where the host build with glibc's math may
    differ in the last bits (newlib's sin and cos round some arguments differently: 3 % of them
    on this machine's glibc; whether a run meets one depends on the gains and on the glibc)."""
    from codegen.verify import run_inputs
    from codegen.pipeline.stages import resolve_substeps
    from codegen.pipeline.targets_file import build_spec, make_target
    reason = newlib_libm.unavailable()
    if reason:
        pytest.skip(reason)
    target, _ = make_target({"robot": "seed000_2r", "family": "nicosia_tomei"})
    spec = build_spec(target)
    target = resolve_substeps(target, spec)        # unstated substeps are "auto": here 1
    folder = emit(target, tmp_path / "gen", spec=spec)
    Y, U = run_inputs(spec, 300, target.discretization.dt)
    rec = cortex_m.verify(folder, "m7", Y, U, work_dir=tmp_path / "fw")
    assert {"s_sin", "k_sin", "s_cos", "k_cos", "e_rem_pio2"} <= set(rec["libm_members"])
    assert rec["bit_identical_newlib"] and rec["rel_diff_host_newlib"] == 0.0 and rec["ok"]
    assert rec["rel_diff_host"] <= cortex_m.TOLERANCE["double"]
    fw = cortex_m.firmware(folder, "m7", tmp_path / "fw")
    lib = compile_library(folder, extra_flags=[str(newlib_libm.host_libm(fw))])
    assert newlib_libm.glibc_calls(lib) == [] and newlib_libm.glibc_calls(compile_library(folder)) != []


def test_newlib_settings_follow_the_multilib(arm):
    """The M7's multilib (double-precision FPU) has newlib's new math, the M4F's the old fdlibm
    single-precision code; both FPUs fuse multiply-adds."""
    m7 = "-mthumb -mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard"
    assert newlib_libm.arm_config(m7) == ["-D__OBSOLETE_MATH=0", "-DHAVE_FAST_FMA=1"]
    assert newlib_libm.arm_config(ARM_CFLAGS) == ["-D__OBSOLETE_MATH=1", "-DHAVE_FAST_FMA=1"]


def test_firmware_reports_an_observer_failure(arm, seed000, tmp_path):
    """A finite double that overflows in the step (the observer built without input ranges, which
    would refuse it first: ERR_OUT_OF_RANGE, the test below) ends the run with ERR_NONFINITE_RESULT."""
    from codegen import observers
    from models import load_robot
    Y, U = np.zeros((5, 2)), np.zeros((5, 2))
    Y[3] = 1e306                                   # finite double, overflows in the step
    spec = observers.build("reduced_order", load_robot("seed000_2r"), limits="none")
    folder = emit(spec.target(precision="double"), tmp_path / "gen", spec=spec)
    fw = cortex_m.firmware(folder, "m7", tmp_path / "fw")
    with pytest.raises(cortex_m.EmbeddedError, match="ERR_NONFINITE_RESULT"):
        cortex_m.run(fw, Y, U, "double")


def test_firmware_refuses_a_sample_out_of_range(arm, seed000, tmp_path):
    Y, U = np.zeros((5, 2)), np.zeros((5, 2))
    Y[3] = 1e306
    fw = cortex_m.firmware(seed000["double"], "m7", tmp_path)
    with pytest.raises(cortex_m.EmbeddedError, match="ERR_OUT_OF_RANGE"):
        cortex_m.run(fw, Y, U, "double")


def test_ur5_float_on_m4f_within_budget(arm, spec_of, tmp_path):
    """ur5 reduced-order in float on the Cortex-M4F: <= 10,000 instructions per step, within
    1e-4 of the host float build, and recorded in the target's JSON."""
    from codegen.verify import run_inputs
    spec = spec_of("ur5")
    folder = emit(spec.target(precision="float"), tmp_path / "gen", spec=spec)
    Y, U = run_inputs(spec, 300, 1e-3)
    rec = cortex_m.verify(folder, "m4f", Y, U, work_dir=tmp_path / "fw")
    cortex_m.record(folder, rec)
    assert rec["instructions_per_step"] <= 10_000 and rec["rel_diff_host"] <= 1e-4 and rec["ok"]
    meta = json.loads((folder / f"{folder.name}.json").read_text())
    assert meta["embedded"]["cortex-m4f"]["instructions_per_step"] == rec["instructions_per_step"]
    assert oct((folder / f"{folder.name}.json").stat().st_mode & 0o777) == "0o644"


def test_cli_embedded_prints_a_table_and_records_both_cpus(arm, tmp_path, capsys):
    from codegen.cli import main
    assert main(["embedded", "seed002_2r", "--out", str(tmp_path), "--steps", "50"]) == 0
    out = capsys.readouterr().out
    assert "insn/step" in out and "vs newlib" in out and "cortex-m4f" in out and "cortex-m7" in out
    for name, cpu in (("seed002_2r_reduced_order", "cortex-m7"), ("seed002_2r_reduced_order_float", "cortex-m4f")):
        rec = json.loads((tmp_path / name / f"{name}.json").read_text())["embedded"][cpu]
        assert rec["ok"] and rec["steps"] == 50 and rec["bit_identical"] in (True, False)
        assert rec["bit_identical_newlib"] is (None if newlib_libm.unavailable() else True)


# ------------------------------------------------------------------ generated build files
def test_generated_makefile_builds_a_gc_sections_friendly_static_library(seed000, tmp_path):
    folder = shutil.copytree(seed000["float"], tmp_path / seed000["float"].name)
    name = folder.name
    subprocess.run(["make", "-s", "-C", str(folder)], check=True, capture_output=True)
    assert (folder / f"lib{name}.a").exists() and not (folder / f"lib{name}.so").exists()
    heads = subprocess.run(["objdump", "-h", str(folder / f"{name}.o")], capture_output=True, text=True).stdout
    assert f".text.{name}_step" in heads                           # one section per function
    subprocess.run(["make", "-s", "-C", str(folder), "shared"], check=True, capture_output=True)
    assert (folder / f"lib{name}.so").exists()


def test_generated_makefile_cross_compiles(arm, seed000, tmp_path):
    folder = shutil.copytree(seed000["float"], tmp_path / seed000["float"].name)
    subprocess.run(["make", "-s", "-C", str(folder), "CC=arm-none-eabi-gcc", "AR=arm-none-eabi-ar",
                    f"CFLAGS=-O2 -std=c99 -Wall -Wdouble-promotion -Werror {ARM_CFLAGS}"],
                   check=True, capture_output=True)
    arch = subprocess.run(["arm-none-eabi-readelf", "-A", str(folder / f"{folder.name}.o")],
                          capture_output=True, text=True).stdout
    assert "Tag_CPU_arch: v7E-M" in arch and "Tag_FP_arch: VFPv4-D16" in arch and "VFP registers" in arch


def _cmake(*args, cwd=None):
    r = subprocess.run(["cmake", *map(str, args)], capture_output=True, text=True, cwd=cwd)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


CONSUMER_C = """#include <stdio.h>
#include "{p}.h"
int main(void) {{
  {p}_state s;
  {p}_real y[{P}_NY] = {{0.1f, 0.2f}}, u[{P}_NU] = {{1.0f, 2.0f}}, est[{P}_NEST];
  if ({p}_init(&s, NULL, y, NULL) || {p}_step(&s, y, u, est) || {p}_step(&s, y, u, est)) return 1;
  printf("%.17g %.17g\\n", (double)est[0], (double)est[1]);
  return 0;
}}
"""


@pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake not installed")
def test_cmake_install_exports_a_package_found_by_find_package(seed000, tmp_path):
    """Install into a temporary prefix; a tiny consumer finds it with find_package, links (libm
    included through the exported target) and gives the estimates the ctypes loader gives."""
    from codegen.pipeline.load import load
    folder, name = seed000["float"], seed000["float"].name
    _cmake("-S", folder, "-B", tmp_path / "b", "-DCMAKE_BUILD_TYPE=Release")
    _cmake("--build", tmp_path / "b")
    _cmake("--install", tmp_path / "b", "--prefix", tmp_path / "prefix")
    cfg = (tmp_path / "prefix" / "lib" / "cmake" / name / f"{name}Config.cmake").read_text()
    assert 'INTERFACE_LINK_LIBRARIES "m"' in cfg
    app = tmp_path / "app"
    app.mkdir()
    (app / "main.c").write_text(CONSUMER_C.format(p=name, P=name.upper()))
    (app / "CMakeLists.txt").write_text(
        f"cmake_minimum_required(VERSION 3.13)\nproject(app C)\nfind_package({name} 0.1 REQUIRED)\n"
        f"add_executable(app main.c)\ntarget_link_libraries(app PRIVATE {name}::{name})\n")
    _cmake("-S", app, "-B", app / "b", f"-DCMAKE_PREFIX_PATH={tmp_path / 'prefix'}")
    _cmake("--build", app / "b")
    got = np.array(subprocess.run([str(app / "b" / "app")], capture_output=True, text=True,
                                  check=True).stdout.split(), float)
    obs = load(folder, compile_library(folder))
    obs.reset([0.1, 0.2])
    obs.step([0.1, 0.2], [1.0, 2.0])
    assert np.array_equal(got, obs.step([0.1, 0.2], [1.0, 2.0]))


@pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake not installed")
def test_cmake_cross_build_links_libm_of_the_toolchain(arm, seed000, tmp_path):
    """Cross-compiled with the shipped arm-none-eabi toolchain file, the library exports "m" (the
    toolchain's libm, which find_library cannot see) and a firmware consumer links against it
    with find_package: sinf/cosf resolve from newlib's libm."""
    folder, name = seed000["float"], seed000["float"].name
    toolchain = ROOT / "c_harness" / "cortex_m" / "arm-none-eabi.cmake"
    _cmake("-S", folder, "-B", tmp_path / "b", f"-DCMAKE_TOOLCHAIN_FILE={toolchain}")
    _cmake("--build", tmp_path / "b")
    _cmake("--install", tmp_path / "b", "--prefix", tmp_path / "prefix")
    fw = ROOT / "c_harness" / "cortex_m"
    app = tmp_path / "fw"
    app.mkdir()
    (app / "CMakeLists.txt").write_text(
        f"cmake_minimum_required(VERSION 3.13)\nproject(fw C)\nfind_package({name} REQUIRED)\n"
        f"add_executable(fw.elf {fw}/firmware.c {fw}/startup.c)\n"
        f"target_include_directories(fw.elf PRIVATE {fw} {fw.parent})\n"
        f"target_compile_definitions(fw.elf PRIVATE OBS={name} OBS_UPPER={name.upper()} "
        f"OBS_HEADER=\"{name}.h\")\n"
        f"target_link_options(fw.elf PRIVATE -nostartfiles -T{fw}/mps2.ld -Wl,--gc-sections "
        "--specs=nano.specs)\n"
        f"target_link_libraries(fw.elf PRIVATE {name}::{name} nosys)\n")
    _cmake("-S", app, "-B", app / "b", f"-DCMAKE_TOOLCHAIN_FILE={toolchain}",
           f"-DCMAKE_PREFIX_PATH={tmp_path / 'prefix'}")
    _cmake("--build", app / "b")
    syms = subprocess.run(["arm-none-eabi-nm", str(app / "b" / "fw.elf")], capture_output=True, text=True).stdout
    assert re.search(r" T (sincosf|cosf)$", syms, re.M) and f"{name}_step" in syms
