"""c_harness/ programs (run_csv, time_step, pin_aba) through codegen.verify.c_programs.

The observer programs are exercised on a hand-made FAKE target that follows the generated
C API exactly (x' = -p x + y + u, Euler, est = (x1, x2, x1 x2), a zero-order hold: step_dt
advances over the time to the next sample), so these tests depend on nothing but the harness
and a C compiler."""
import json
import subprocess
import shutil

import numpy as np
import pytest

from codegen.verify import c_programs
from codegen.pipeline.compile import CompileError

FAKE_H = """\
#ifndef FAKEOBS_H
#define FAKEOBS_H
#define FAKEOBS_NX 2
#define FAKEOBS_NY 2
#define FAKEOBS_NU 1
#define FAKEOBS_NP 1
#define FAKEOBS_NEST 3
#define FAKEOBS_DT 0.001
#define FAKEOBS_HOLD_FOH 0
#define FAKEOBS_STAMP_ULPS 4
enum { FAKEOBS_OK = 0, FAKEOBS_ERR_BAD_ARG = 1, FAKEOBS_ERR_NONFINITE_INPUT = 2,
       FAKEOBS_ERR_NONFINITE_RESULT = 3, FAKEOBS_ERR_KERNEL = 4, FAKEOBS_ERR_OUT_OF_RANGE = 5,
       FAKEOBS_SKIPPED = 6 };
typedef double fakeobs_real;
typedef struct { double x[FAKEOBS_NX]; double p[FAKEOBS_NP]; double w[4]; } fakeobs_state;
void fakeobs_default_params(double *p);
int fakeobs_init(fakeobs_state *s, const double *p, const double *y0, const double *est0);
int fakeobs_step(fakeobs_state *s, const double *y, const double *u, double *est);
int fakeobs_step_dt(fakeobs_state *s, double dt, const double *y, const double *u, double *est);
int fakeobs_run(fakeobs_state *s, long n, const double *Y, const double *U, double *EST,
                long *n_done);
int fakeobs_rhs(fakeobs_state *s, const double *x, const double *y, const double *u,
                double *xdot);
#endif
"""

FAKE_C = """\
#include <math.h>
#include <stddef.h>
#include "fakeobs.h"
int fakeobs_kernel(const double *p, const double *x, const double *y, const double *u,
                   double *xdot);
void fakeobs_default_params(double *p) { p[0] = 2.0; }
int fakeobs_init(fakeobs_state *s, const double *p, const double *y0, const double *est0) {
  int i;
  if (!s || !y0) return FAKEOBS_ERR_BAD_ARG;
  for (i = 0; i < FAKEOBS_NY; ++i) if (!isfinite(y0[i])) return FAKEOBS_ERR_NONFINITE_INPUT;
  if (p) s->p[0] = p[0]; else fakeobs_default_params(s->p);
  for (i = 0; i < FAKEOBS_NX; ++i) s->x[i] = est0 ? est0[i] : 0.0;
  return FAKEOBS_OK;
}
int fakeobs_rhs(fakeobs_state *s, const double *x, const double *y, const double *u,
                double *xdot) {
  if (!s || !x || !y || !u || !xdot) return FAKEOBS_ERR_BAD_ARG;
  return fakeobs_kernel(s->p, x, y, u, xdot);
}
int fakeobs_step(fakeobs_state *s, const double *y, const double *u, double *est) {
  return fakeobs_step_dt(s, FAKEOBS_DT, y, u, est);
}
int fakeobs_step_dt(fakeobs_state *s, double dt, const double *y, const double *u, double *est) {
  double xd[FAKEOBS_NX], xn[FAKEOBS_NX];
  int i, st;
  if (!s || !y || !u || !est || !(dt > 0) || !(dt <= 1.0)) return FAKEOBS_ERR_BAD_ARG;
  for (i = 0; i < FAKEOBS_NY; ++i) if (!isfinite(y[i])) return FAKEOBS_ERR_NONFINITE_INPUT;
  for (i = 0; i < FAKEOBS_NU; ++i) if (!isfinite(u[i])) return FAKEOBS_ERR_NONFINITE_INPUT;
  st = fakeobs_rhs(s, s->x, y, u, xd);
  if (st) return st;
  for (i = 0; i < FAKEOBS_NX; ++i) {
    xn[i] = s->x[i] + dt * xd[i];
    if (!isfinite(xn[i])) return FAKEOBS_ERR_NONFINITE_RESULT;
  }
  est[0] = s->x[0]; est[1] = s->x[1]; est[2] = s->x[0] * s->x[1];
  for (i = 0; i < FAKEOBS_NX; ++i) s->x[i] = xn[i];
  return FAKEOBS_OK;
}
int fakeobs_run(fakeobs_state *s, long n, const double *Y, const double *U, double *EST,
                long *n_done) {
  long k; int st = FAKEOBS_OK;
  for (k = 0; k < n; ++k) {
    st = fakeobs_step(s, Y + k * FAKEOBS_NY, U + k * FAKEOBS_NU, EST + k * FAKEOBS_NEST);
    if (st) break;
  }
  if (n_done) *n_done = k;
  return st;
}
"""

FAKE_KERNELS_C = """\
int fakeobs_kernel(const double *p, const double *x, const double *y, const double *u,
                   double *xdot);
int fakeobs_kernel(const double *p, const double *x, const double *y, const double *u,
                   double *xdot) {
  int i;
  for (i = 0; i < 2; ++i) xdot[i] = -p[0] * x[i] + y[i] + u[0];
  return 0;
}
"""

DT = 0.001


def fake_reference(Y, U, est0=None, p=2.0, H=None):
    """The fake observer in plain Python floats, same operations in the same order; H: the
    interval each sample advances over (default DT)."""
    x = [0.0, 0.0] if est0 is None else [float(est0[0]), float(est0[1])]
    out = []
    for k, (y, u) in enumerate(zip(Y, U)):
        out.append([x[0], x[1], x[0] * x[1]])
        xd = [-p * x[i] + float(y[i]) + float(u[0]) for i in range(2)]
        h = DT if H is None else H[k]
        x = [x[i] + h * xd[i] for i in range(2)]
    return np.array(out)


@pytest.fixture(scope="module")
def fake(tmp_path_factory):
    root = tmp_path_factory.mktemp("harness")
    d = root / "fakeobs"
    d.mkdir()
    (d / "fakeobs.h").write_text(FAKE_H)
    (d / "fakeobs.c").write_text(FAKE_C)
    (d / "fakeobs_kernels.c").write_text(FAKE_KERNELS_C)
    (d / "fakeobs.json").write_text(json.dumps({"prefix": "fakeobs"}))
    return d, root / "build"


@pytest.fixture(scope="module")
def exe(fake):
    d, build = fake
    return c_programs.compile_harness(d, work_dir=build)


def trajectory(n=400, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    Y = np.column_stack([np.sin(7 * t), np.cos(3 * t)]) + 0.05 * rng.standard_normal((n, 2))
    U = rng.uniform(-1, 1, (n, 1))
    return t, Y, U


def run(prog, *args):
    return subprocess.run([str(prog), *map(str, args)], capture_output=True, text=True)


def test_build_is_cached_and_outside_target(fake, exe):
    d, build = fake
    assert exe["run_csv"].is_file() and exe["time_step"].is_file()
    assert build in exe["run_csv"].parents
    before = exe["run_csv"].stat().st_mtime_ns
    again = c_programs.compile_harness(d, work_dir=build)
    assert again == exe and again["run_csv"].stat().st_mtime_ns == before
    assert sorted(p.name for p in d.iterdir()) == ["fakeobs.c", "fakeobs.h", "fakeobs.json",
                                                   "fakeobs_kernels.c"]


def test_run_csv_matches_python(fake, exe, tmp_path):
    d, build = fake
    t, Y, U = trajectory()
    c_programs.write_csv(tmp_path / "in.csv", t, Y, U)
    for est0 in (None, [0.5, -0.25, 7.0]):
        out = c_programs.run_csv(d, tmp_path / "in.csv", tmp_path / "out.csv", est0=est0,
                              work_dir=build)
        t2, EST = c_programs.read_csv(out)
        assert out.read_text().splitlines()[0] == "t,est0,est1,est2"
        np.testing.assert_array_equal(t2, t)
        assert EST.shape == (len(t), 3)
        ref = fake_reference(Y, U, est0)
        np.testing.assert_allclose(EST, ref, rtol=1e-15, atol=1e-15)


def test_run_csv_uses_the_time_stamps(fake, exe, tmp_path):
    """A jittered t column: each row advances over the interval to the next one (the fake's
    zero-order hold), the last over DT; stamps k DT shifted by 1e4 s (rounded) count as DT; stamps
    that do not increase are ERR_BAD_ARG, naming the row and the interval."""
    d, build = fake
    t, Y, U = trajectory(200)
    rng = np.random.default_rng(4)
    tj = np.cumsum(DT * rng.uniform(0.7, 1.6, len(t)))
    c_programs.write_csv(tmp_path / "in.csv", tj, Y, U)
    _, EST = c_programs.read_csv(c_programs.run_csv(d, tmp_path / "in.csv", tmp_path / "out.csv", work_dir=build))
    H = np.append(np.diff(tj), DT)
    np.testing.assert_allclose(EST, fake_reference(Y, U, H=H), rtol=1e-15, atol=1e-15)
    c_programs.write_csv(tmp_path / "in.csv", 1e4 + t, Y, U)
    _, EST = c_programs.read_csv(c_programs.run_csv(d, tmp_path / "in.csv", tmp_path / "out.csv", work_dir=build))
    np.testing.assert_array_equal(EST, fake_reference(Y, U))
    (tmp_path / "in.csv").write_text("t,y1,y2,u\n0,1,2,0\n0.001,1,2,0\n0.001,1,2,0\n0.003,1,2,0\n")
    r = run(exe["run_csv"], tmp_path / "in.csv", tmp_path / "out.csv")
    assert r.returncode == 3 and "data row 2 (t=0.001): fakeobs_step_dt returned 1: ERR_BAD_ARG" in r.stderr
    assert "(dt = 0, from the t column)" in r.stderr


def test_run_csv_tolerant_formatting(exe, tmp_path):
    (tmp_path / "in.csv").write_text("time,a,b,c\r\n0, 1 ,2,0.5\r\n\n1e-3,\t1.5,2,5e-1\n")
    r = run(exe["run_csv"], tmp_path / "in.csv", tmp_path / "out.csv")
    assert r.returncode == 0, r.stderr
    t, EST = c_programs.read_csv(tmp_path / "out.csv")
    np.testing.assert_array_equal(t, [0.0, 1e-3])
    np.testing.assert_allclose(EST, fake_reference([[1, 2], [1.5, 2]], [[0.5], [0.5]]),
                               rtol=1e-15, atol=1e-15)


@pytest.mark.parametrize("text, message", [
    ("t,y1,y2\n0,1,2\n", "header has 3 columns, target 'fakeobs' expects 4"),
    ("t,y1,y2,u\n0,1,2,0\n0.001,1,2\n", ":3: row has 3 columns, expected 4"),
    ("t,y1,y2,u\n0,1,abc,0\n", ":2: column 3 ('abc') is not a number"),
    ("t,y1,y2,u\n0,1,2,\n", ":2: column 4 ('') is empty"),
    ("", "empty file"),
    ("t,y1,y2,u\n", "no data rows"),
])
def test_run_csv_bad_input(exe, tmp_path, text, message):
    (tmp_path / "in.csv").write_text(text)
    r = run(exe["run_csv"], tmp_path / "in.csv", tmp_path / "out.csv")
    assert r.returncode == 1
    assert message in r.stderr
    assert not (tmp_path / "out.csv").exists() and not (tmp_path / "out.csv.tmp").exists()


def test_run_csv_missing_file_and_usage(exe, tmp_path):
    r = run(exe["run_csv"], tmp_path / "nope.csv", tmp_path / "out.csv")
    assert r.returncode == 1 and "cannot open input" in r.stderr and "nope.csv" in r.stderr
    r = run(exe["run_csv"])
    assert r.returncode == 2 and "usage" in r.stderr
    (tmp_path / "in.csv").write_text("t,y1,y2,u\n0,1,2,0\n")
    r = run(exe["run_csv"], tmp_path / "in.csv", tmp_path / "out.csv", "1,2")
    assert r.returncode == 2 and "est0 must have 3" in r.stderr


@pytest.mark.parametrize("row, status", [
    ("0.001,1,nan,0", "returned 2: ERR_NONFINITE_INPUT"),
    ("0.001,1e308,1e308,1e308", "returned 3: ERR_NONFINITE_RESULT"),
])
def test_run_csv_status_error(exe, fake, tmp_path, row, status):
    d, build = fake
    (tmp_path / "in.csv").write_text(f"t,y1,y2,u\n0,1,2,0\n{row}\n0.002,1,2,0\n")
    r = run(exe["run_csv"], tmp_path / "in.csv", tmp_path / "out.csv")
    assert r.returncode == 3
    assert "in.csv:3: data row 2 (t=0.001): fakeobs_step " + status in r.stderr
    assert not (tmp_path / "out.csv").exists()
    with pytest.raises(c_programs.HarnessError, match="data row 2") as e:
        c_programs.run_csv(d, tmp_path / "in.csv", tmp_path / "out.csv", work_dir=build)
    assert e.value.returncode == 3


def test_time_step_json(fake, exe):
    d, build = fake
    r = run(exe["time_step"], "--blocks=5", "--block-ms=2")
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    assert res["target"] == "fakeobs" and res["blocks"] == 5 and res["errors"] == 0
    assert (res["nx"], res["ny"], res["nu"], res["nest"], res["dt"]) == (2, 2, 1, 3, DT)
    for key in ("ns_per_step", "ns_per_rhs", "calls_per_block", "calls_per_block_rhs"):
        assert np.isfinite(res[key]) and res[key] > 0, key
    res = c_programs.time_target(d, blocks=3, block_ms=1, work_dir=build)
    assert res["ns_per_step"] > 0 and res["ns_per_rhs"] > 0 and res["blocks"] == 3


def test_time_step_keeps_its_inputs_in_the_declared_ranges(tmp_path):
    """A target whose declared range excludes 0 (panda's joint 4: [-3.07, -0.07] rad) and bounds
    |u| below the table's amplitudes: the timing program's inputs stay inside, so init and every
    step succeed (they were sinusoids about 0: init refused with ERR_OUT_OF_RANGE, the bench
    stopped)."""
    ranges = ("#define FAKEOBS_CHECK_RANGES 1\n#define FAKEOBS_Y_LOWER {0.5, -3.0}\n"
              "#define FAKEOBS_Y_UPPER {2.0, -1.0}\n#define FAKEOBS_U_MAX {0.1}\n#endif\n")
    check = ("  for (i = 0; i < FAKEOBS_NY; ++i) if (!(y{0}[i] >= y_lo[i] && y{0}[i] <= y_hi[i])) "
             "return FAKEOBS_ERR_OUT_OF_RANGE;\n")
    c = FAKE_C.replace('#include "fakeobs.h"\n', '#include "fakeobs.h"\nstatic const double '
                       'y_lo[] = FAKEOBS_Y_LOWER, y_hi[] = FAKEOBS_Y_UPPER, u_max[] = FAKEOBS_U_MAX;\n')
    c = c.replace("  if (p) s->p[0]", check.format("0") + "  if (p) s->p[0]")
    c = c.replace("  st = fakeobs_rhs(", check.format("") + "  if (fabs(u[0]) > u_max[0]) return "
                  "FAKEOBS_ERR_OUT_OF_RANGE;\n  st = fakeobs_rhs(")
    d = tmp_path / "fakeobs"
    d.mkdir()
    (d / "fakeobs.h").write_text(FAKE_H.replace("#endif\n", ranges))
    (d / "fakeobs.c").write_text(c)
    (d / "fakeobs_kernels.c").write_text(FAKE_KERNELS_C)
    res = c_programs.time_target(d, blocks=3, block_ms=1, work_dir=tmp_path / "build")
    assert res["errors"] == 0 and res["ns_per_step"] > 0


def test_compile_error_is_reported(tmp_path):
    d = tmp_path / "broken"
    d.mkdir()
    (d / "broken.h").write_text(FAKE_H.replace("fakeobs", "broken").replace("FAKEOBS", "BROKEN"))
    (d / "broken.c").write_text("int broken_step(void) { return syntax error; }\n")
    with pytest.raises(CompileError, match=r"compiling broken\.c failed[\s\S]*error") as e:
        c_programs.compile_harness(d, work_dir=tmp_path / "build")
    assert e.value.returncode != 0 and "error" in e.value.stderr
    assert str(d / "broken.c") in str(e.value)          # the source folder, not the private copy
    assert sorted(p.name for p in (tmp_path / "build").iterdir()) == []   # nothing half-built


def test_csv_helpers_round_trip(tmp_path):
    t, Y, U = trajectory(50)
    path = c_programs.write_csv(tmp_path / "x.csv", t, Y, U, y_names=["q1", "q2"])
    assert path.read_text().splitlines()[0] == "t,q1,q2,u0"
    t2, rest = c_programs.read_csv(path)
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(rest, np.hstack([Y, U]))
    with pytest.raises(ValueError, match="Y: expected shape"):
        c_programs.write_csv(tmp_path / "y.csv", t, Y[:-1], U)


# ---- pinocchio peer benchmark -----------------------------------------------------------------

PIN_MISSING = c_programs.pin_bench_missing()


@pytest.mark.long  # experiment-scale: `make test-long`
@pytest.mark.skipif(PIN_MISSING is not None, reason=f"pin_aba cannot be built: {PIN_MISSING}")
def test_pin_bench():
    exe = c_programs.compile_pin_bench()
    assert exe.is_file()
    res = c_programs.time_pin("robots/ur_description/urdf/ur5_robot.urdf", blocks=3, block_ms=2)
    assert res["nv"] == 6 and res["pin_mode"] == "library"
    for key in ("ns_aba", "ns_rnea", "ns_crba"):
        assert np.isfinite(res[key]) and res[key] > 0, key
    res = c_programs.time_pin("robots/panda_description/urdf/panda.urdf",
                           ["panda_finger_joint1", "panda_finger_joint2"], blocks=3, block_ms=2)
    assert res["nv"] == 7 and res["locked_joints"] == ["panda_finger_joint1",
                                                       "panda_finger_joint2"]
    res = c_programs.time_pin("robots/panda_description/urdf/panda.urdf",
                           {"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.02},
                           blocks=1, block_ms=1)
    assert res["nv"] == 7
    with pytest.raises(c_programs.HarnessError, match="no joint named 'nope'"):
        c_programs.time_pin("robots/panda_description/urdf/panda.urdf", ["nope"], blocks=1,
                         block_ms=1)


@pytest.mark.long  # experiment-scale: `make test-long`
@pytest.mark.skipif(PIN_MISSING is not None or shutil.which("valgrind") is None,
                    reason="pin_aba cannot be built or no valgrind")
def test_pin_aba_instructions_per_call():
    """callgrind's count per aba call does not depend on the numbers of calls it is taken from
    (the program's loading cancels), and grows with the joints (panda 7, ur5 6)."""
    panda = "robots/panda_description/urdf/panda.urdf"
    fingers = ["panda_finger_joint1", "panda_finger_joint2"]
    a = c_programs.pin_aba_instructions(panda, fingers, calls=(50, 250))
    b = c_programs.pin_aba_instructions(panda, fingers, calls=(250, 650))
    assert a == pytest.approx(b, rel=0.01)
    assert c_programs.pin_aba_instructions("robots/ur_description/urdf/ur5_robot.urdf", calls=(50, 250)) < a


def test_callgrind_calls_reads_compressed_call_edges():
    """Call edges into a function are summed over its callers, names given once and then
    referred to by their (id), the cost line after ``calls=`` being the inclusive cost."""
    text = "\n".join([
        "events: Ir", "fn=(1) main", "0 10",
        "cfn=(2) obs_step", "calls=3 0", "0 300",
        "cfn=(3) obs_rhs", "calls=2 0", "0 50",
        "fn=(2)", "0 40", "cfn=(3)", "calls=3 0", "0 75",
        "fn=(4) other", "cfn=(2)", "calls=1 0", "0 100"])
    got = c_programs.callgrind_calls(text, ["obs_step", "obs_rhs", "absent"])
    assert got == {"obs_step": (4, 400), "obs_rhs": (5, 125), "absent": (0, 0)}


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="no valgrind")
def test_instructions_per_call(fake, exe):
    """The fake observer's step evaluates its RHS once (inlined by the compiler, so only the
    timing loop's RHS calls are edges): per call, the step costs more than the RHS."""
    d, build = fake
    got = c_programs.instructions_per_call(d, work_dir=build)
    assert got["calls_step"] > 0 and got["calls_rhs"] > 0
    assert 0 < got["rhs"] < got["step"]
