"""Standalone C harness: run a generated target over a CSV, time it, time pinocchio's peers.

Bytes room: this module compiles and runs the programs of ``c_harness/`` and knows nothing
of any particular observer.

    from codegen import harness
    exe = harness.build_harness("generated/ur5_reduced_order")     # {"run_csv": Path, "time_step": Path}
    harness.write_csv("traj.csv", t, Y, U)
    harness.run_csv("generated/ur5_reduced_order", "traj.csv", "est.csv", est0=None)
    t, EST = harness.read_csv("est.csv")
    harness.time_target("generated/ur5_reduced_order")   # {"ns_per_step": ..., "ns_per_rhs": ..., ...}
    harness.time_pin("robots/ur_description/urdf/ur5_robot.urdf")  # {"ns_aba": ..., "ns_rnea": ..., ...}

Builds are cached in ``<build_dir>/<prefix>-<hash>/`` (default build dir
``<repo>/build/harness``); the hash covers the harness sources, every .c/.h file of the target,
the flags and the compiler version, so repeated calls cost one process start only. Nothing
is written into the target folder. A failed compile raises HarnessError (a RuntimeError)
carrying the compiler's command line and message; so does a program that exits non-zero.

The pinocchio benchmark (``pin_aba``) is C++ built against the pin wheel's own headers and
libraries (``<site-packages>/cmeel.prefix``); it also needs Eigen's headers (PyPI package
``cmeel-eigen``) and urdfdom's headers (``cmeel-urdfdom-headers``). ``pin_bench_missing()``
says what is absent.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
HARNESS_SRC = REPO / "c_harness"
DEFAULT_BUILD_DIR = REPO / "build" / "harness"

C_FLAGS = ["-O3", "-std=c99", "-Wall", "-Wextra", "-pedantic"]
HARNESS_STRICT = ["-Werror"]          # the harness's own files; target files get C_FLAGS only
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


class HarnessError(RuntimeError):
    """A harness build or run failed; the message holds the command and its stderr."""

    def __init__(self, message, returncode=None, stderr=""):
        super().__init__(message)
        self.returncode = returncode
        self.stderr = stderr


# --------------------------------------------------------------------------------------------
# helpers

@lru_cache(maxsize=8)
def _compiler_version(cc):
    exe = shutil.which(cc)
    if exe is None:
        raise HarnessError(f"compiler {cc!r} not found on PATH")
    try:
        out = subprocess.run([exe, "--version"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        raise HarnessError(f"compiler {cc!r} not usable: {e}") from None
    return exe, out.splitlines()[0] if out else ""


def _run_tool(cmd, what):
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if proc.returncode != 0:
        raise HarnessError(f"{what} failed (exit {proc.returncode}):\n  {' '.join(map(str, cmd))}\n"
                           f"{proc.stderr.strip()}", proc.returncode, proc.stderr)
    return proc


def _build_root(build_dir):
    return Path(build_dir).resolve() if build_dir is not None else DEFAULT_BUILD_DIR


def _cached_build(out_dir: Path, products, build_into):
    """Return out_dir if every product exists; else build into a temp sibling and rename."""
    if all((out_dir / p).exists() for p in products):
        return out_dir
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}-", dir=out_dir.parent))
    try:
        build_into(tmp)
        try:
            os.replace(tmp, out_dir)
        except OSError:
            # a concurrent build got there first (non-empty out_dir): keep theirs if complete
            if not all((out_dir / p).exists() for p in products):
                shutil.rmtree(out_dir, ignore_errors=True)
                os.replace(tmp, out_dir)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out_dir


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


def build_harness(target_dir, build_dir=None, native=False, cc=None, extra_flags=()):
    """Compile run_csv and time_step against a generated target.

    Parameters
    ----------
    target_dir : path of generated/<prefix>/
    build_dir : cache root (default <repo>/build/harness); binaries go to
        ``<build_dir>/<prefix>-<hash>/``
    native : add -march=native (default flags are the portable -O3)
    cc : C compiler (default $CC, else gcc)
    extra_flags : appended to the target's compile flags (e.g. ("-O2",) for a huge kernel)

    Returns
    -------
    dict(run_csv=Path, time_step=Path)
    """
    prefix, d, sources = target_info(target_dir)
    cc = cc or os.environ.get("CC", "gcc")
    cc_exe, cc_version = _compiler_version(cc)
    flags = C_FLAGS + (["-march=native"] if native else [])
    target_flags = flags + list(extra_flags)
    h = hashlib.sha256()
    h.update(json.dumps([prefix, cc_exe, cc_version, target_flags, HARNESS_STRICT]).encode())
    for name in HARNESS_FILES:
        h.update(name.encode() + b"\0" + (HARNESS_SRC / name).read_bytes() + b"\0")
    # the target's sources are read once: what is hashed is what is compiled (from a private
    # copy), even if another process regenerates the folder meanwhile
    files = {f.name: f.read_bytes() for f in sorted(d.iterdir()) if f.suffix in (".c", ".h")}
    for name, data in files.items():
        h.update(b"T" + name.encode() + b"\0" + data + b"\0")
    out_dir = _build_root(build_dir) / f"{prefix}-{h.hexdigest()[:16]}"

    def build_into(tmp):
        src_dir = tmp / "src"
        src_dir.mkdir()
        for name, data in files.items():
            (src_dir / name).write_bytes(data)
        obs_defs = [f"-DOBS={prefix}", f"-DOBS_UPPER={prefix.upper()}",
                    f'-DOBS_HEADER="{prefix}.h"', "-I", src_dir, "-I", HARNESS_SRC]
        objs = []
        for src in sources:
            obj = tmp / f"{src.stem}.o"
            _run_tool([cc_exe, *target_flags, "-I", src_dir, "-c", src_dir / src.name, "-o", obj],
                      f"compiling {src.name}")
            objs.append(obj)
        for prog in ("run_csv", "time_step"):
            obj = tmp / f"harness_{prog}.o"
            _run_tool([cc_exe, *flags, *HARNESS_STRICT, *obs_defs, "-c", HARNESS_SRC / f"{prog}.c",
                       "-o", obj], f"compiling c_harness/{prog}.c for {prefix}")
            _run_tool([cc_exe, *flags, obj, *objs, "-lm", "-o", tmp / prog], f"linking {prog}")
        for o in tmp.glob("*.o"):
            o.unlink()
        shutil.rmtree(src_dir)

    out_dir = _cached_build(out_dir, ("run_csv", "time_step"), build_into)
    return {"run_csv": out_dir / "run_csv", "time_step": out_dir / "time_step"}


def run_csv(target_dir, csv_in, csv_out, est0=None, build_dir=None, native=False):
    """Run the target over ``csv_in`` (header, then rows t, y.., u..) into ``csv_out``.

    ``est0``: initial estimate (NEST numbers; default zeros). Returns Path(csv_out).
    Raises HarnessError with run_csv's message (row number, status name) on failure;
    ``csv_out`` is then not written."""
    exe = build_harness(target_dir, build_dir, native=native)["run_csv"]
    cmd = [exe, Path(csv_in), Path(csv_out)]
    if est0 is not None:
        est0 = np.asarray(est0, dtype=float).ravel()
        cmd.append(",".join(repr(float(v)) for v in est0))
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if proc.returncode != 0:
        raise HarnessError(f"run_csv failed (exit {proc.returncode}): {proc.stderr.strip()}",
                           proc.returncode, proc.stderr)
    return Path(csv_out)


def time_target(target_dir, blocks=51, block_ms=15.0, build_dir=None, native=False, extra_flags=()):
    """ns per <prefix>_step and per <prefix>_rhs (medians over ``blocks`` blocks of ~block_ms).

    Returns the program's JSON line as a dict: target, ns_per_step, ns_per_rhs, blocks,
    calls_per_block, calls_per_block_rhs, nx, ny, nu, nest, dt, errors (step calls that
    returned a non-zero status; non-zero means the timing is not representative)."""
    exe = build_harness(target_dir, build_dir, native=native, extra_flags=extra_flags)["time_step"]
    proc = _run_tool([exe, f"--blocks={int(blocks)}", f"--block-ms={float(block_ms)!r}"],
                     "time_step")
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    if res.get("errors"):
        warnings.warn(f"time_step: {res['errors']} step calls of {res['target']} returned a "
                      "non-zero status; the timing is not representative", RuntimeWarning)
    return res


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
    """Folder holding Eigen/Core: cmeel-eigen's, else the system's; None if absent."""
    pin_prefix = pin_prefix or find_pin_prefix()
    cands = ([Path(pin_prefix) / "include" / "eigen3"] if pin_prefix else []) + \
        [Path("/usr/include/eigen3"), Path("/usr/local/include/eigen3")]
    return next((c for c in cands if (c / "Eigen" / "Core").exists()), None)


def find_urdfdom_headers(pin_prefix=None):
    """Folder holding urdf_model/model.h (cmeel-urdfdom-headers, else the system's) or None."""
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
        return "Eigen headers not found: pip install cmeel-eigen"
    if find_urdfdom_headers(pre) is None:
        return "urdfdom headers not found: pip install cmeel-urdfdom-headers"
    return None


def build_pin_bench(build_dir=None, mode="library", cxx=None):
    """Compile c_harness/pin_aba.cpp against the pin wheel; returns the executable's Path.

    mode "library" (default) calls the wheel's precompiled instantiations in
    libpinocchio_default.so (what a CMake user of pinocchio::pinocchio gets); "header"
    instantiates the algorithms from the headers with our -O3 (slow to compile, ~2 min)."""
    if mode not in PIN_MODES:
        raise ValueError(f"mode: expected one of {PIN_MODES}, got {mode!r}")
    missing = pin_bench_missing()
    if missing:
        raise HarnessError(f"cannot build pin_aba: {missing}")
    pre = find_pin_prefix()
    cxx = cxx or os.environ.get("CXX", "g++")
    cxx_exe, cxx_version = _compiler_version(cxx)
    lib = pre / "lib"
    inc = ["-isystem", pre / "include", "-isystem", find_eigen_include(pre),
           "-isystem", find_urdfdom_headers(pre)]
    defs = PIN_DEFINES + (["-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"] if mode == "library" else [])
    src = HARNESS_SRC / "pin_aba.cpp"
    h = hashlib.sha256()
    h.update(json.dumps([cxx_exe, cxx_version, CXX_FLAGS, defs, [str(i) for i in inc],
                         str(lib)]).encode())
    h.update(src.read_bytes())
    h.update((pre / "include" / "pinocchio" / "config.hpp").read_bytes())
    out_dir = _build_root(build_dir) / f"pin_aba-{mode}-{h.hexdigest()[:16]}"

    def build_into(tmp):
        _run_tool([cxx_exe, *CXX_FLAGS, *defs, *inc, src, f"-L{lib}", f"-Wl,-rpath,{lib}",
                   *(f"-l{n}" for n in PIN_LIBS), "-o", tmp / "pin_aba"], "compiling pin_aba.cpp")

    return _cached_build(out_dir, ("pin_aba",), build_into) / "pin_aba"


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


def time_pin(urdf, locked_joints=(), blocks=51, block_ms=15.0, build_dir=None, mode="library"):
    """ns per pinocchio aba, rnea and crba on ``urdf``.

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
    exe = build_pin_bench(build_dir, mode=mode)
    proc = _run_tool([exe, f"--blocks={int(blocks)}", f"--block-ms={float(block_ms)!r}",
                      resolve_urdf(urdf), *args], "pin_aba")
    return json.loads(proc.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------------------------
# CSV files

def write_csv(path, t, Y, U, y_names=None, u_names=None):
    """Write the run_csv input: header, then rows t, y_1..y_NY, u_1..u_NU (%.17g, exact).

    t: (n,); Y: (n, NY) (a 1-D Y is one column); U: (n, NU) likewise (NU may be 0)."""
    t = np.asarray(t, dtype=float).ravel()
    n = t.size
    cols = [t[:, None]]
    names = ["t"]
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
        cols.append(A)
        names += nm
    data = np.hstack(cols)
    with open(path, "w") as f:
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, fmt="%.17g", delimiter=",")
    return Path(path)


def read_csv(path):
    """Read run_csv's output: returns (t of shape (n,), EST of shape (n, NEST))."""
    with open(path) as f:
        header = f.readline()
        if not header:
            raise ValueError(f"{path}: empty file")
        ncol = header.count(",") + 1
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    if data.size == 0:
        data = np.zeros((0, ncol))
    return data[:, 0].copy(), data[:, 1:].copy()


def _main(argv=None):
    """python -m codegen.harness time <target_dir> | pin <urdf> [locked ...]"""
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) >= 2 and argv[0] == "time":
        print(json.dumps(time_target(argv[1])))
    elif len(argv) >= 2 and argv[0] == "pin":
        print(json.dumps(time_pin(argv[1], argv[2:])))
    else:
        print("usage: python -m codegen.harness time <target_dir> | pin <urdf> [locked_joint ...]",
              file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(_main())
