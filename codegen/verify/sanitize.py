"""The generated C under sanitizers and a fuzzer, run by ``make test``.

    python -m codegen sanitize [--runs N] [--seconds S]      (codegen.verify.sanitize.run)

For each target of ``SAMPLE``: the CSV harness (c_harness/run_csv.c) and the target built with
``-fsanitize=address,undefined -fno-sanitize-recover=all`` (the C compiler, gcc by default)
run over ``edge_cases`` (NaN, +-Inf, 1e300, denormals, empty and malformed rows; time stamps that
repeat, go back, are NaN or Inf, a dropped sample and a gap beyond the target's split limit: the
elapsed time of step_dt), each with the exit code and message run_csv documents; then a libFuzzer campaign (clang, ``$FUZZ_CC``) of
c_harness/fuzz_step.c, which asserts the documented status and an unchanged state on every
failure of step, step_dt (dt 0, negative, NaN, Inf, huge), run, run_t, estimate, estimate_dt,
rhs, set_state and set_params, a sample outside the declared ranges (ERR_OUT_OF_RANGE, or SKIPPED
in the skip mode: the held sample's step, bit for bit) and a wild sample in a long run (one sample
later, within the clean run's error of it). A sanitizer report, an
unexpected exit code or a fuzzer finding fails the run. Prints its figures (targets, inputs,
fuzz runs) and ends with the line ``sanitize: N passed, M failed``.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ..pipeline.compile import cache_dir, cached_compile, compiler, package_data, read_target

HARNESS = package_data("c_harness")
SAN_FLAGS = ["-g", "-O1", "-fno-omit-frame-pointer", "-fsanitize=address,undefined",
             "-fno-sanitize-recover=all", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror"]
SAN_EXIT = 99            # exit code of a sanitizer report (ASan and UBSan)
SAN_ENV = {"ASAN_OPTIONS": f"exitcode={SAN_EXIT}:detect_leaks=1",
           "UBSAN_OPTIONS": f"exitcode={SAN_EXIT}:print_stacktrace=1"}
# (robot, family, build arguments, precision): small and large, URDF, hybrid, non-smooth,
# elastic, and single-precision twins (one real type, float math)
SAMPLE = [("seed000_2r", "reduced_order", {}, "double"), ("ur5", "reduced_order", {}, "double"),
          ("seed000_2r", "reduced_order_hybrid", {}, "double"), ("seed002_2r", "su_nonsmooth", {}, "double"),
          ("seed002_2r", "lotfi_namvar", {}, "double"),
          ("seed004_2r", "ciccarella_germani", {"variant": "O2"}, "double"),
          ("ur5", "reduced_order", {}, "float"), ("seed002_2r", "su_nonsmooth", {}, "float")]
# a huge finite input per precision (1e300 is Inf once a float target reads it)
HUGE = {"double": "1e300", "float": "1e38"}


@dataclass
class Case:
    """One run of run_csv: the CSV text, the exit codes run_csv documents for it, a pattern
    its stderr must hold when it fails, and an optional est0 argument."""
    name: str
    text: str
    exits: tuple
    stderr: str = ""
    est0: str | None = None


def edge_cases(ny, nu, nest, dt, precision="double", limits=None):
    """The edge-case CSVs of a target with ``ny`` measurements, ``nu`` inputs and ``nest``
    estimates (for the est0 case), rows ``dt`` (s) apart: a list of :class:`Case`. run_csv
    parses doubles and hands the target its own real type, ``precision``. ``limits``: the declared
    ranges of its metadata (codegen.core.limits): a value just outside the first declared one
    must give ERR_OUT_OF_RANGE."""
    header = ",".join(["t"] + [f"y{i}" for i in range(ny)] + [f"u{i}" for i in range(nu)])

    def rows(n=8, y="0.1", u="0.5", at=None, where="y", t=None):
        out = []
        for k in range(n):
            ys, us = [y] * ny, [u] * nu
            if at is not None and k == at[0]:
                (ys if where == "y" or nu == 0 else us)[0] = at[1]
            out.append(",".join([repr(k * dt) if t is None else t[k]] + ys + us))
        return out

    def stamps(**changes):      # k dt, with stamp k replaced by a text
        return [changes.get(f"t{k}", repr(k * dt)) for k in range(8)]

    def csv(lines, end="\n"):
        return end.join([header] + lines) + end
    ok, res = (0,), r"ERR_NONFINITE_RESULT|ERR_OUT_OF_RANGE"
    bad_in = r"ERR_NONFINITE_INPUT"
    bad_dt = r"step_dt returned 1: ERR_BAD_ARG"
    big = HUGE[precision]
    cases = [
        Case("plain", csv(rows()), ok),
        Case("nan in y", csv(rows(at=(3, "nan"))), (3,), bad_in),
        Case("-nan in y", csv(rows(at=(0, "-nan"))), (3,), bad_in),
        Case("+inf in u", csv(rows(at=(2, "+inf"), where="u")), (3,), bad_in),
        Case("-inf in y", csv(rows(at=(5, "-inf"))), (3,), bad_in),
        Case("1e999 (overflows to inf)", csv(rows(at=(1, "1e999"))), (3,), bad_in),
        Case(f"{big} everywhere", csv(rows(y=big, u=big)), (0, 3), res),
        Case(f"{big} in one row", csv(rows(at=(4, big))), (0, 3), res),
        Case(f"-{big} inputs", csv(rows(at=(4, "-" + big), where="u")), (0, 3), res),
        Case("denormals", csv(rows(y="4.9e-324", u="-2.2250738585072014e-308")), ok),
        Case("-0 and hex floats", csv(rows(y="-0.0", u="0x1p-3")), ok),
        Case("blank rows, CRLF", csv(rows()[:3] + ["", "  "] + rows()[3:], end="\r\n"), ok),
        Case("no final newline", csv(rows()).rstrip("\n"), ok),
        Case("empty file", "", (1,), r"empty file"),
        Case("header only", header + "\n", (1,), r"no data rows"),
        Case("not a number", csv(rows(at=(2, "abc"))), (1,), r"is not a number"),
        Case("empty field", csv(rows(at=(2, ""))), (1,), r"is empty"),
        Case("missing column", csv([r.rsplit(",", 1)[0] for r in rows()]), (1,), r"columns"),
        Case("extra column", csv([r + ",1" for r in rows()]), (1,), r"columns"),
        Case("wrong header", "t\n" + "\n".join(rows()) + "\n", (1,), r"header has"),
        Case("a 200000-character row", csv(rows()[:2] + ["1" * 200000]), (1,), r"columns"),
        Case("NUL byte", csv(rows()[:2] + ["0.1\0" + rows()[2]]), (1,), r"columns|not a number"),
        Case("est0 with nan", csv(rows()), (3,), bad_in, est0=",".join(["nan"] + ["0"] * (nest - 1))),
        Case("jittered stamps", csv(rows(t=[repr(dt * (k + 0.3 * (-1) ** k)) for k in range(8)])), ok),
        Case("a dropped sample (10 dt)", csv(rows(t=stamps(t4=repr(13 * dt), t5=repr(14 * dt),
                                                          t6=repr(15 * dt), t7=repr(16 * dt)))), ok),
        Case("repeated stamp (dt = 0)", csv(rows(t=stamps(t3=repr(2 * dt)))), (3,), bad_dt),
        Case("stamp going back (dt < 0)", csv(rows(t=stamps(t3=repr(-dt)))), (3,), bad_dt),
        Case("nan stamp", csv(rows(t=stamps(t3="nan"))), (3,), bad_dt),
        Case("inf stamp", csv(rows(t=stamps(t3="inf"))), (3,), bad_dt),
        Case("a gap beyond split_max dt_max (1e300)", csv(rows(t=stamps(t3="1e300"))), (3,), bad_dt),
    ]
    if precision == "float":
        cases.append(Case("1e300 (Inf as a float)", csv(rows(at=(4, "1e300"))), (3,), bad_in))
    upper = (limits or {}).get("y_upper") or []
    if upper and upper[0] is not None:          # y0's declared range, 0.1 y beyond its upper end
        beyond = repr(upper[0] + 0.1 + abs(upper[0]) * 1e-3)
        cases.append(Case(f"y0 = {beyond}, beyond its declared range", csv(rows(at=(4, beyond))), (3,),
                          r"ERR_OUT_OF_RANGE"))
    return cases


def _sample_targets(out):
    """Emit the targets of ``SAMPLE`` into ``out``; returns their folders."""
    from models.catalog import load_elastic, load_robot

    from ..families import observers
    from ..pipeline.emit import emit
    folders = []
    for robot, family, kwargs, precision in SAMPLE:
        model = load_elastic(robot) if family == "ciccarella_germani" else load_robot(robot)
        spec = observers.build(family, model, **kwargs)
        folders.append(emit(spec.target(precision=precision), out, spec=spec))
    return folders


def sanitized(target_dir, program, tool, flags, cache):
    """``c_harness/<program>.c`` and the target's C compiled and linked in one command.

    Parameters
    ----------
    target_dir : pathlib.Path
        Folder of an emitted target.
    program : str
        Harness stem: "run_csv" or "fuzz_step".
    tool : codegen.pipeline.compile.Compiler
        The C compiler (``codegen.pipeline.compile.compiler``).
    flags : list of str
        Compiler flags (sanitizers, libFuzzer).
    cache : pathlib.Path
        Cache folder; the build is cached by content (``codegen.pipeline.compile.cached_compile``).

    Returns
    -------
    pathlib.Path
        The executable.
    """
    files = read_target(target_dir)
    prefix = target_dir.name
    sources = sorted(n for n in files if n.endswith(".c") and n.startswith(prefix))
    files.update({n: (HARNESS / n).read_bytes() for n in ("obs_bind.h", f"{program}.c")})

    def commands(work, out):
        yield ([tool.path, *flags, f"-DOBS={prefix}", f"-DOBS_UPPER={prefix.upper()}",
                f'-DOBS_HEADER="{prefix}.h"', "-I", work, "-o", out / program, work / f"{program}.c",
                *(work / s for s in sources), "-lm"], f"compiling {program} for {prefix} ({tool.path})")
    return cached_compile(f"{prefix}-{program}", [tool, flags], files, [program], commands, cache,
                        shown=target_dir) / program


def _env():
    return {**os.environ, **SAN_ENV}


def run_case(exe, case, work):
    """Run the run_csv executable ``exe`` on one Case ``case`` in the scratch folder ``work``;
    returns None if it behaved as documented, else why not (str)."""
    src, dst = work / "in.csv", work / "out.csv"
    src.write_bytes(case.text.encode())
    dst.unlink(missing_ok=True)
    cmd = [str(exe), str(src), str(dst)] + ([case.est0] if case.est0 is not None else [])
    p = subprocess.run(cmd, capture_output=True, text=True, env=_env(), timeout=120)
    if p.returncode not in case.exits:
        return f"exit {p.returncode}, expected {case.exits}: {p.stderr.strip()[-2000:]}"
    if p.returncode != 0:
        if not re.search(case.stderr, p.stderr):
            return f"exit {p.returncode} without /{case.stderr}/ on stderr: {p.stderr.strip()[-500:]}"
        return "out.csv written on failure" if dst.exists() else None
    rows = [r for r in case.text.replace("\r", "").split("\n")[1:] if r.strip()]
    got = dst.read_text().strip().split("\n")[1:]
    if len(got) != len(rows) or any(v in ("nan", "-nan", "inf", "-inf") for r in got for v in r.split(",")):
        return f"out.csv has {len(got)} rows for {len(rows)} (or a non-finite estimate)"
    return None


def fuzz(exe, runs, seconds, work, seed=1):
    """A libFuzzer campaign of the fuzzer executable ``exe``.

    Parameters
    ----------
    exe : pathlib.Path
        The fuzz_step executable (``sanitized``).
    runs : int
        Number of inputs to run.
    seconds : float
        Time limit, s.
    work : pathlib.Path
        Folder for libFuzzer's artifacts (a crashing input).
    seed : int
        libFuzzer's ``-seed``.

    Returns
    -------
    tuple
        (runs done, seconds taken, None or the finding: what fuzz_step or a sanitizer reported
        and the input, code coverage reached: libFuzzer's "cov").
    """
    t0 = time.perf_counter()
    p = subprocess.run([str(exe), f"-runs={runs}", f"-max_total_time={seconds}", f"-seed={seed}",
                        "-max_len=2048", f"-artifact_prefix={work}/", "-print_final_stats=1"],
                       capture_output=True, text=True, env=_env(), timeout=seconds + 300)
    done = re.search(r"stat::number_of_executed_units:\s*(\d+)", p.stderr)
    finding = None
    if p.returncode != 0:
        lines = [ln for ln in p.stderr.splitlines()
                 if re.search(r"fuzz_step\(|ERROR: |runtime error|^SUMMARY|^Base64", ln)]
        finding = "\n".join(lines) or p.stderr.strip()[-3000:]
    cov = re.findall(r"cov: (\d+)", p.stderr)
    return (int(done.group(1)) if done else 0, time.perf_counter() - t0, finding,
            int(cov[-1]) if cov else 0)


def run(runs=100000, seconds=60):
    """Build, run and fuzz the targets of ``SAMPLE`` (``runs`` libFuzzer runs each, at most
    ``seconds``); print the figures; 0 if every check passed, else 1."""
    cc, fuzz_cc = compiler(), compiler(None, env="FUZZ_CC", default="clang")
    cache = cache_dir() / "sanitize"
    passed, failed, n_inputs, n_runs, n_secs = 0, 0, 0, 0, 0
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for folder in _sample_targets(work / "targets"):
            meta = json.loads(read_target(folder)[f"{folder.name}.json"])
            s = meta["sizes"]
            cases = edge_cases(s["ny"], s["nu"], s["nest"], meta["discretization"]["dt"],
                               meta.get("precision", "double"), meta.get("limits"))
            run_csv = sanitized(folder, "run_csv", cc, SAN_FLAGS, cache)
            bad = [(c.name, why) for c in cases if (why := run_case(run_csv, c, work))]
            exe = sanitized(folder, "fuzz_step", fuzz_cc, ["-fsanitize=fuzzer", *SAN_FLAGS], cache)
            n, secs, finding, cov = fuzz(exe, runs, seconds, work)
            passed += len(cases) - len(bad) + (finding is None)
            failed += len(bad) + (finding is not None)
            n_inputs, n_runs, n_secs = n_inputs + len(cases), n_runs + n, n_secs + secs
            print(f"{folder.name:36s} nx {s['nx']:2d} ny {s['ny']} nu {s['nu']}  edge CSVs "
                  f"{len(cases) - len(bad)}/{len(cases)} as documented  fuzz {n} runs in {secs:.1f} s, cov {cov} "
                  f"{'OK' if finding is None else 'FINDING'}", flush=True)
            for name, why in bad:
                print(f"  edge case {name!r}: {why}")
            if finding:
                print("  fuzz_step finding:\n" + finding)
    print(f"{len(SAMPLE)} targets, {n_inputs} edge-case CSV runs under ASan+UBSan ({cc.version}), "
          f"{n_runs} libFuzzer runs in {n_secs:.0f} s ({fuzz_cc.version})")
    print(f"sanitize: {passed} passed, {failed} failed")
    return 0 if failed == 0 else 1
