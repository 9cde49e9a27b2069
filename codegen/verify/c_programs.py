"""Standalone C harness: run a generated target over a CSV, time it, time pinocchio's peers.

Bytes only: this module compiles and runs the programs of ``c_harness/`` and knows nothing
of any particular observer.

    from codegen import harness
    exe = harness.compile_harness("generated/ur5_reduced_order")     # {"run_csv": Path, "time_step": Path}
    harness.write_csv("traj.csv", t, Y, U)
    harness.run_csv("generated/ur5_reduced_order", "traj.csv", "est.csv", est0=None)
    t, EST = harness.read_csv("est.csv")
    harness.time_target("generated/ur5_reduced_order")   # {"ns_per_step": ..., "ns_per_rhs": ..., ...}
    harness.time_pin("robots/ur_description/urdf/ur5_robot.urdf")  # {"ns_aba": ..., "ns_rnea": ..., ...}

Builds go through codegen.pipeline.compile's toolchain (``compiler``, ``c_flags``, ``cached_compile``) and
are cached in ``<work_dir>/<prefix>-<hash>/`` (default build dir ``build/harness`` in the working folder);
the hash covers the harness sources, every .c/.h file of the target, the flags and the
compiler, so repeated calls cost one process start only. Nothing is written into the target
folder. A failed compile raises codegen.pipeline.compile.CompileError carrying the compiler's command line
and message; a program that exits non-zero raises HarnessError (both are ToolError).

The pinocchio benchmark (``pin_aba``) is C++ built against the pin wheel's own headers and
libraries (``<site-packages>/cmeel.prefix``); it also needs Eigen's headers (PyPI package
``cmeel-eigen``) and urdfdom's headers (``cmeel-urdfdom-headers``). ``pin_bench_missing()``
says what is absent.
"""
from __future__ import annotations

import json
import os
import re
import sys
import warnings
from pathlib import Path

import numpy as np

from ..core.columns import read_columns, write_columns
from ..pipeline.compile import (CompileError, ToolError, c_flags, cached_compile, compiler, digest, package_data,
                    read_target, run_tool)
from ..pipeline.compile import work_dir as default_work_dir

HARNESS_SRC = package_data("c_harness")

CXX_FLAGS = ["-O3", "-DNDEBUG", "-std=c++17", "-Wall", "-Wextra"]

# From the wheel's lib/cmake/pinocchio/pinocchioTargets.cmake (targets pinocchio_headers,
# pinocchio_default, pinocchio_parsers).
PIN_DEFINES = [
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
    "-DPINOCCHIO_WITH_URDFDOM", "-DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3",
    "-DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0", "-DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0",
]
PIN_LIBS = ["pinocchio_parsers", "pinocchio_default"]
PIN_MODES = ("library", "header")

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class HarnessError(ToolError):
    """A harness program (run_csv, time_step, pin_aba) exited non-zero; the message holds the
    command and its stderr, ``returncode`` and ``stderr`` the rest."""


def _run(cmd, what):
    return run_tool(cmd, what, error=HarnessError)


def _compile_root(work_dir):
    return Path(work_dir).resolve() if work_dir is not None else default_work_dir() / "harness"


def target_info(target_dir):
    """(prefix, target_dir, sources) of a generated target folder.

    The prefix is the ``"prefix"`` key of the folder's ``<name>.json`` metadata when present
    (else of its only .json file), otherwise the folder's name. Sources are ``<prefix>.c``
    and ``<prefix>_kernels*.c``."""
    d = Path(target_dir).resolve()
    if not d.is_dir():
        raise FileNotFoundError(f"target_dir: {target_dir} is not a directory (expected a "
                                "generated/<prefix>/ folder)")
    prefix = d.name
    meta = d / f"{d.name}.json"
    if not meta.exists():
        others = sorted(d.glob("*.json"))
        meta = others[0] if len(others) == 1 else None
    if meta is not None:
        try:
            prefix = json.loads(meta.read_text()).get("prefix", prefix)
        except (ValueError, AttributeError):
            pass
    if not _IDENT.match(prefix):
        raise ValueError(f"target_dir: prefix {prefix!r} is not a C identifier")
    header, wrapper = d / f"{prefix}.h", d / f"{prefix}.c"
    for f in (header, wrapper):
        if not f.exists():
            raise FileNotFoundError(f"target_dir: {d} has no {f.name} (expected a generated target)")
    sources = [wrapper] + sorted(d.glob(f"{prefix}_kernels*.c"))
    return prefix, d, sources


# --------------------------------------------------------------------------------------------
# observer programs

HARNESS_FILES = ("obs_bind.h", "run_csv.c", "time_step.c")
PROGRAMS = ("run_csv", "time_step")


def compile_harness(target_dir, work_dir=None, native=False, cc=None, extra_flags=()):
    """Compile run_csv and time_step against a generated target.

    Parameters
    ----------
    target_dir : path of generated/<prefix>/
    work_dir : cache root (default build/harness in the working folder); binaries go to
        ``<work_dir>/<prefix>-<hash>/``
    native : add -march=native (default flags are the portable -O3)
    cc : C compiler (default $CC, else gcc)
    extra_flags : appended to the target's compile flags (e.g. ("-O2",) for a huge kernel)

    Returns
    -------
    dict(run_csv=Path, time_step=Path)
    """
    prefix, d, sources = target_info(target_dir)
    tool = compiler(cc)
    flags = c_flags(native)
    target_flags = c_flags(native, extra=extra_flags)
    harness_flags = c_flags(native, strict=True)   # -Werror on the harness's own files only
    # the target's sources are read once: what is hashed is what is compiled (from a private
    # copy), even if another process regenerates the folder meanwhile
    files = read_target(d, (".c", ".h"))
    key = [prefix, tool, target_flags, harness_flags,
           {name: digest((HARNESS_SRC / name).read_bytes()) for name in HARNESS_FILES}]

    def commands(work, out):
        objs = [work / f"{src.stem}.o" for src in sources]
        for src, obj in zip(sources, objs):
            yield [tool.path, *target_flags, "-I", work, "-c", work / src.name, "-o", obj], \
                f"compiling {src.name}"
        obs_defs = [f"-DOBS={prefix}", f"-DOBS_UPPER={prefix.upper()}",
                    f'-DOBS_HEADER="{prefix}.h"', "-I", work, "-I", HARNESS_SRC]
        for prog in PROGRAMS:
            obj = work / f"harness_{prog}.o"
            yield [tool.path, *harness_flags, *obs_defs, "-c", HARNESS_SRC / f"{prog}.c", "-o", obj], \
                f"compiling c_harness/{prog}.c for {prefix}"
            yield [tool.path, *flags, obj, *objs, "-lm", "-o", out / prog], f"linking {prog}"

    out = cached_compile(prefix, key, files, PROGRAMS, commands, _compile_root(work_dir), shown=d)
    return {prog: out / prog for prog in PROGRAMS}


def run_csv(target_dir, csv_in, csv_out, est0=None, work_dir=None, native=False):
    """Run the target in ``target_dir`` over ``csv_in`` (header, then rows t, y.., u..) into ``csv_out``.

    ``est0``: initial estimate (NEST numbers; default zeros); ``work_dir``, ``native``: as in
    :func:`compile_harness`. Returns Path(csv_out).
    Raises HarnessError with run_csv's message (row number, status name) on failure;
    ``csv_out`` is then not written."""
    exe = compile_harness(target_dir, work_dir, native=native)["run_csv"]
    cmd = [exe, Path(csv_in), Path(csv_out)]
    if est0 is not None:
        est0 = np.asarray(est0, dtype=float).ravel()
        cmd.append(",".join(repr(float(v)) for v in est0))
    _run(cmd, "run_csv")
    return Path(csv_out)


def time_target(target_dir, blocks=51, block_ms=15.0, work_dir=None, native=False, extra_flags=()):
    """ns per <prefix>_step and per <prefix>_rhs of the target in ``target_dir`` (medians over
    ``blocks`` blocks of ~``block_ms`` ms); ``work_dir``, ``native``, ``extra_flags``: as in
    :func:`compile_harness`.

    Returns the program's JSON line as a dict: target, ns_per_step, ns_per_rhs, blocks,
    calls_per_block, calls_per_block_rhs, nx, ny, nu, nest, dt, errors (step calls that
    returned a non-zero status; non-zero means the timing is not representative)."""
    exe = compile_harness(target_dir, work_dir, native=native, extra_flags=extra_flags)["time_step"]
    proc = _run([exe, f"--blocks={int(blocks)}", f"--block-ms={float(block_ms)!r}"], "time_step")
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    if res.get("errors"):
        warnings.warn(f"time_step: {res['errors']} step calls of {res['target']} returned a "
                      "non-zero status; the timing is not representative", RuntimeWarning)
    return res


def callgrind_calls(text, functions):
    """{function: (calls, inclusive instructions)} of a callgrind output file's ``text``: the call
    edges into each of the ``functions`` (C symbol names, matched exactly after callgrind's
    ``(id) name`` compression) summed over its callers (``calls=N`` lines and the cost line after
    each, callees included)."""
    names, out, callee = {}, {f: [0, 0] for f in functions}, None
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("cfn="):
            m = re.match(r"cfn=\((\d+)\)(?: (.*))?", line)
            if m.group(2):
                names[m.group(1)] = m.group(2)
            callee = names.get(m.group(1))
        elif line.startswith("calls=") and callee in out:
            out[callee][0] += int(line[6:].split()[0])
            out[callee][1] += int(lines[i + 1].split()[-1])
        elif line.startswith("fn="):
            m = re.match(r"fn=\((\d+)\)(?: (.*))?", line)
            if m and m.group(2):
                names[m.group(1)] = m.group(2)
    return {f: tuple(v) for f, v in out.items()}


def instructions_per_call(target_dir, work_dir=None, native=False):
    """Instructions per ``<prefix>_step`` and per ``<prefix>_rhs`` call of the target in
    ``target_dir`` (callgrind on the timing program at its smallest blocks, callees such as libm
    included; the inputs are the program's table of smooth signals); ``work_dir``, ``native``:
    as in :func:`compile_harness`. None without valgrind, else
    {"step": ..., "rhs": ..., "calls_step": ..., "calls_rhs": ...}."""
    import shutil
    import tempfile
    if shutil.which("valgrind") is None:
        return None
    prefix = target_info(target_dir)[0]
    exe = compile_harness(target_dir, work_dir, native=native)["time_step"]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "cg.out"
        _run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", str(exe), "--blocks=1",
              "--block-ms=0.001"], "time_step under callgrind")
        counts = callgrind_calls(out.read_text(), [f"{prefix}_step", f"{prefix}_rhs"])
    (ns, cs), (nr, cr) = counts[f"{prefix}_step"], counts[f"{prefix}_rhs"]
    if not ns or not nr:
        raise HarnessError(f"callgrind saw no call of {prefix}_step or {prefix}_rhs")
    return {"step": cs / ns, "rhs": cr / nr, "calls_step": ns, "calls_rhs": nr}


# --------------------------------------------------------------------------------------------
# pinocchio peer benchmark

def find_pin_prefix():
    """The pin wheel's ``cmeel.prefix`` folder (holding include/pinocchio and lib/), or None."""
    env = os.environ.get("PIN_PREFIX")
    if env:
        return Path(env)
    for p in map(Path, sys.path):
        cand = p / "cmeel.prefix"
        if (cand / "include" / "pinocchio").is_dir():
            return cand.resolve()
    return None


def find_eigen_include(pin_prefix=None):
    """Folder holding Eigen/Core: cmeel-eigen's (under ``pin_prefix``, default
    :func:`find_pin_prefix`), else the system's; None if absent."""
    pin_prefix = pin_prefix or find_pin_prefix()
    cands = ([Path(pin_prefix) / "include" / "eigen3"] if pin_prefix else []) + \
        [Path("/usr/include/eigen3"), Path("/usr/local/include/eigen3")]
    return next((c for c in cands if (c / "Eigen" / "Core").exists()), None)


def find_urdfdom_headers(pin_prefix=None):
    """Folder holding urdf_model/model.h (cmeel-urdfdom-headers under ``pin_prefix``, default
    :func:`find_pin_prefix`, else the system's) or None."""
    pin_prefix = pin_prefix or find_pin_prefix()
    cands = ([Path(pin_prefix) / "include" / "urdfdom_headers"] if pin_prefix else []) + \
        [Path("/usr/include/urdfdom_headers"), Path("/usr/include")]
    return next((c for c in cands if (c / "urdf_model" / "model.h").exists()), None)


def pin_bench_missing():
    """None when pin_aba can be built here, else the reason (what to install)."""
    pre = find_pin_prefix()
    if pre is None:
        return "pin wheel not found (no cmeel.prefix/include/pinocchio on sys.path): pip install pin"
    if not all((pre / "lib" / f"lib{lib}.so").exists() for lib in PIN_LIBS):
        return f"pinocchio libraries {PIN_LIBS} not found in {pre / 'lib'}"
    if find_eigen_include(pre) is None:
        return "Eigen headers not found: pip install 'observer-codegen[bench]' (cmeel-eigen)"
    if find_urdfdom_headers(pre) is None:
        return "urdfdom headers not found: pip install 'observer-codegen[bench]' (cmeel-urdfdom-headers)"
    return None


def compile_pin_bench(work_dir=None, mode="library", cxx=None):
    """Compile c_harness/pin_aba.cpp against the pin wheel; returns the executable's Path.

    mode "library" (default) calls the wheel's precompiled instantiations in
    libpinocchio_default.so (what a CMake user of pinocchio::pinocchio gets); "header"
    instantiates the algorithms from the headers with our -O3 (slow to compile, ~2 min).
    ``work_dir``: cache root (default build/harness); ``cxx``: C++ compiler (default $CXX, else g++)."""
    if mode not in PIN_MODES:
        raise ValueError(f"mode: expected one of {PIN_MODES}, got {mode!r}")
    missing = pin_bench_missing()
    if missing:
        raise CompileError(f"cannot build pin_aba: {missing}")
    pre = find_pin_prefix()
    tool = compiler(cxx, env="CXX", default="g++")
    lib = pre / "lib"
    inc = ["-isystem", pre / "include", "-isystem", find_eigen_include(pre),
           "-isystem", find_urdfdom_headers(pre)]
    defs = PIN_DEFINES + (["-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"] if mode == "library" else [])
    key = [tool, CXX_FLAGS, defs, [str(i) for i in inc], str(lib),
           digest((pre / "include" / "pinocchio" / "config.hpp").read_bytes())]

    def commands(work, out):
        yield [tool.path, *CXX_FLAGS, *defs, *inc, work / "pin_aba.cpp", f"-L{lib}", f"-Wl,-rpath,{lib}",
               *(f"-l{n}" for n in PIN_LIBS), "-o", out / "pin_aba"], "compiling pin_aba.cpp"

    files = {"pin_aba.cpp": (HARNESS_SRC / "pin_aba.cpp").read_bytes()}
    return cached_compile(f"pin_aba-{mode}", key, files, ["pin_aba"], commands, _compile_root(work_dir),
                        shown=HARNESS_SRC) / "pin_aba"


def resolve_urdf(urdf):
    """``urdf`` if it exists, else the same path inside example-robot-data's share folder
    (so "robots/ur_description/urdf/ur5_robot.urdf" works)."""
    p = Path(urdf)
    if p.exists():
        return p.resolve()
    pre = find_pin_prefix()
    if pre is not None:
        cand = pre / "share" / "example-robot-data" / p
        if cand.exists():
            return cand
    raise FileNotFoundError(f"urdf: {urdf} not found (neither as a path nor inside "
                            "example-robot-data)")


def time_pin(urdf, locked_joints=(), blocks=51, block_ms=15.0, work_dir=None, mode="library"):
    """ns per pinocchio aba, rnea and crba on ``urdf`` (medians over ``blocks`` blocks of
    ~``block_ms`` ms), pin_aba built by :func:`compile_pin_bench` with ``work_dir`` and ``mode``.

    ``locked_joints``: joint names (held at the neutral configuration, 0 for revolute and
    prismatic joints) or a dict {name: value} (one-coordinate joints held at value); they
    are removed with pinocchio's buildReducedModel. ``urdf`` may be a path inside
    example-robot-data (see resolve_urdf).

    Returns the JSON line of pin_aba as a dict: urdf, locked_joints, nq, nv, ns_aba,
    ns_rnea, ns_crba, blocks, calls_per_block_aba, pin_mode, pinocchio_version."""
    if isinstance(locked_joints, str):
        locked_joints = (locked_joints,)
    if isinstance(locked_joints, dict):
        args = [f"{name}={float(v)!r}" for name, v in locked_joints.items()]
    else:
        args = [str(name) for name in locked_joints]
    for a in args:
        if a.startswith("--"):
            raise ValueError(f"locked_joints: {a!r} is not a joint name")
    exe = compile_pin_bench(work_dir, mode=mode)
    proc = _run([exe, f"--blocks={int(blocks)}", f"--block-ms={float(block_ms)!r}",
                 resolve_urdf(urdf), *args], "pin_aba")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def pin_aba_instructions(urdf, locked_joints=(), calls=(200, 1200), work_dir=None):
    """Instructions per pinocchio ``aba`` call on ``urdf`` (valgrind's callgrind on
    ``pin_aba --calls=N`` at the two ``calls``: the difference of the totals over the
    difference of the calls, loading and start-up cancel); None without valgrind.
    ``locked_joints`` as :func:`time_pin`; ``work_dir``: as in :func:`compile_pin_bench`."""
    import re
    import shutil
    import tempfile
    if shutil.which("valgrind") is None:
        return None
    exe = compile_pin_bench(work_dir)
    args = ([f"{k}={float(v)!r}" for k, v in locked_joints.items()] if isinstance(locked_joints, dict)
            else [str(k) for k in ((locked_joints,) if isinstance(locked_joints, str) else locked_joints)])
    totals = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in calls:
            out = Path(tmp) / f"cg{n}.out"
            _run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", str(exe), f"--calls={int(n)}",
                  resolve_urdf(urdf), *args], "pin_aba under callgrind")
            totals.append(int(re.search(r"^summary:\s+(\d+)", out.read_text(), re.M).group(1)))
    return (totals[1] - totals[0]) / (calls[1] - calls[0])


# --------------------------------------------------------------------------------------------
# CSV files

def write_csv(path, t, Y, U, y_names=None, u_names=None):
    """Write the run_csv input: header, then rows t, y_1..y_NY, u_1..u_NU (exact decimal form;
    ``codegen.core.columns.write_columns``).

    path: the CSV written; t: (n,) s; Y: (n, NY) (a 1-D Y is one column); U: (n, NU) likewise
    (NU may be 0); y_names, u_names: column names (default y0.., u0..)."""
    t = np.asarray(t, dtype=float).ravel()
    n = t.size
    columns = {"t": t}
    for label, A, given in (("Y", Y, y_names), ("U", U, u_names)):
        A = np.asarray(A, dtype=float)
        if A.ndim == 1:
            A = A[:, None] if A.size == n else A.reshape(n, -1)
        if A.ndim != 2 or A.shape[0] != n:
            raise ValueError(f"{label}: expected shape ({n}, k) to match t of length {n}, "
                             f"got {np.shape(A)}")
        k = A.shape[1]
        base = label.lower()
        nm = list(given) if given is not None else [f"{base}{i}" for i in range(k)]
        if len(nm) != k:
            raise ValueError(f"{base}_names: expected {k} names, got {len(nm)}")
        columns.update({name: A[:, i] for i, name in enumerate(nm)})
    return write_columns(path, columns)


def read_csv(path):
    """Read run_csv's output file ``path``: returns (t of shape (n,), EST of shape (n, NEST))."""
    _, data = read_columns(path, error=ValueError)
    return data[:, 0].copy(), data[:, 1:].copy()


def _main(argv=None):
    """python -m codegen.verify.c_programs time <target_dir> | pin <urdf> [locked ...]"""
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) >= 2 and argv[0] == "time":
        print(json.dumps(time_target(argv[1])))
    elif len(argv) >= 2 and argv[0] == "pin":
        print(json.dumps(time_pin(argv[1], argv[2:])))
    else:
        print("usage: python -m codegen.verify.c_programs time <target_dir> | pin <urdf> [locked_joint ...]",
              file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(_main())
