"""The sanitizer and fuzz run (codegen.verify.sanitize, `python -m codegen sanitize` in make test)
can fail: faults put back into a generated target are found. The clean run over the sample of
targets is `make test`'s own step; here one small target, with its C edited."""
import os
import re
import shutil
import subprocess

import pytest

from codegen.pipeline.compile import CompileError, compiler
from codegen.verify import sanitize
from codegen.pipeline.emit import emit


def _libfuzzer(tmp_path):
    """clang with libFuzzer, or skip outside CI (make test installs it: c_harness/install-tools.sh)."""
    probe = tmp_path / "probe.c"
    probe.write_text("int LLVMFuzzerTestOneInput(const unsigned char *d, unsigned long n)"
                     " { (void)d; (void)n; return 0; }\n")
    try:
        tool = compiler(None, env="FUZZ_CC", default="clang")
        r = subprocess.run([tool.path, "-fsanitize=fuzzer,address,undefined", str(probe), "-o",
                            str(tmp_path / "probe")], capture_output=True, text=True)
        why = r.stderr if r.returncode else None
    except CompileError as e:
        tool, why = None, str(e)
    if why is None:
        return tool
    if os.environ.get("CI") == "true":
        pytest.fail(f"clang with libFuzzer is required in CI: {why}")
    pytest.skip(f"clang with libFuzzer not available (run make c-tools): {why}")


@pytest.fixture
def target(spec_of, tmp_path):
    return emit(spec_of("seed000_2r"), tmp_path / "t")


@pytest.fixture
def float_target(spec_of, tmp_path):
    spec = spec_of("seed000_2r")
    return emit(spec.target(precision="float"), tmp_path / "t", spec=spec)


# the roll-back on error of run() (followed by run_t's interval helper) and of run_t() (the last function
# before rhs()): group 1 the end of the loop, group 2 the restore
RUN_ROLLBACK = (r"(    if \(n_done\) \*n_done = k \+ 1;\n  \}\n)  if \(status != \w+_OK\) "
                r"(\w+_restore\(s, &entry\);\n  return status[^\n]*;\n\}\n\n/\* b - a)")
RUN_T_ROLLBACK = (r"(    if \(n_done\) \*n_done = k \+ 1;\n  \}\n)  if \(status != \w+_OK\) "
                  r"(\w+_restore\(s, &entry\);\n  return status[^\n]*;\n\}\n\nint \w+_rhs)")


def _put_back(folder, pattern, replacement):
    """Edit the target's wrapper C: ``pattern`` (a regex that must match) -> ``replacement``."""
    c = folder / f"{folder.name}.c"
    text, n = re.subn(pattern, replacement, c.read_text())
    assert n == 1, pattern
    c.write_text(text)


@pytest.mark.parametrize("fault, pattern, replacement", [
    ("run() not rolled back (item 5)", RUN_ROLLBACK, r"\1  if (0) \2"),
    ("run_t() not rolled back", RUN_T_ROLLBACK, r"\1  if (0) \2"),
    ("step_dt() takes dt = 0", r"if \(!\(dt > 0\) \|\| ", "if ("),
    ("rhs() on NaN input (item 6)",
     r"  if \(!\w+_finite\(x, \w+_NX\).*\n +return \w+_ERR_NONFINITE_INPUT;\n", ""),
    ("step() writes the state before checking the result",
     r"(  status = \w+_sample\(s, [^;]*s->x_next, s->m_next, s->est, s->w,\s+s->iw, \w+\);)",
     r"  s->x[0] = s->x_next[0];\n\1"),
], ids=["run-not-rolled-back", "run-t-not-rolled-back", "step-dt-zero", "rhs-nan", "step-writes-early"])
def test_fuzzer_finds_a_fault_put_back(target, tmp_path, fault, pattern, replacement):
    tool = _libfuzzer(tmp_path)
    _put_back(target, pattern, replacement)
    exe = sanitize.sanitized(target, "fuzz_step", tool, ["-fsanitize=fuzzer", *sanitize.SAN_FLAGS],
                             tmp_path / "cache")
    runs, _, finding, _ = sanitize.fuzz(exe, 200000, 120, tmp_path)
    assert finding is not None and runs < 200000, fault
    assert re.search(r"fuzz_step\(seed000_2r_reduced_order\): .*(state|status)", finding), finding


def test_edge_cases_as_documented_and_sanitizers_report_a_fault(target, tmp_path):
    """The clean target passes every edge case; an out-of-bounds write put into its copy loop
    is reported by AddressSanitizer (exit 99), a NaN let through is an undocumented exit."""
    cases = sanitize.edge_cases(2, 2, 2, 1e-3)
    exe = sanitize.sanitized(target, "run_csv", compiler(), sanitize.SAN_FLAGS, tmp_path / "cache")
    assert [c.name for c in cases if sanitize.run_case(exe, c, tmp_path)] == []
    bad = tmp_path / "bad"
    shutil.copytree(target, bad / target.name)
    _put_back(bad / target.name, r"for \(i = 0; i < n; \+\+i\) dst\[i\] = src\[i\];",
              "for (i = 0; i <= n; ++i) dst[i] = src[i];")
    exe = sanitize.sanitized(bad / target.name, "run_csv", compiler(), sanitize.SAN_FLAGS, tmp_path / "cache")
    why = sanitize.run_case(exe, cases[0], tmp_path)
    assert why is not None and why.startswith(f"exit {sanitize.SAN_EXIT}") and "AddressSanitizer" in why


def test_float_target_edge_cases_and_fuzzer(float_target, tmp_path):
    """A single-precision twin passes the edge cases (1e300 is Inf once read as a float: a
    documented ERR_NONFINITE_INPUT), and the fuzzer, drawing float specials and raw floats,
    finds run() not rolled back there too."""
    cases = sanitize.edge_cases(2, 2, 2, 1e-3, "float")
    exe = sanitize.sanitized(float_target, "run_csv", compiler(), sanitize.SAN_FLAGS, tmp_path / "cache")
    assert [c.name for c in cases if sanitize.run_case(exe, c, tmp_path)] == []
    tool = _libfuzzer(tmp_path)
    _put_back(float_target, RUN_ROLLBACK, r"\1  if (0) \2")
    exe = sanitize.sanitized(float_target, "fuzz_step", tool, ["-fsanitize=fuzzer", *sanitize.SAN_FLAGS],
                             tmp_path / "cache")
    runs, _, finding, _ = sanitize.fuzz(exe, 200000, 120, tmp_path)
    assert finding is not None and runs < 200000
    assert re.search(r"fuzz_step\(seed000_2r_reduced_order_float\): .*run", finding), finding
