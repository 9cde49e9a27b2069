"""Cortex-M verification: a generated target cross-compiled into the example firmware of
``c_harness/cortex_m/``, run on QEMU's mps2 boards, compared with the host build, measured.

Bytes only: this module knows CPUs, boards and files, nothing of any particular observer.

    from codegen import embedded
    cortex_m.missing_packages()                       # Debian packages still to install
    rec = cortex_m.verify("generated/ur5_reduced_order_float", "m4f", Y, U, H=H)   # H: elapsed times
    rec["instructions_per_step"], rec["instructions_per_step_dt"], rec["rel_diff_host"], rec["stack_peak_bytes"]

The firmware (``firmware.c``, ``startup.c``, ``mps2.ld``) is built, and its QEMU command line
made, by ``c_harness/cortex_m/Makefile`` (flags and boards live there only: ``make info``); it
reads the inputs from the host through semihosting and prints each estimate as its IEEE bit
pattern, so the comparison with the host is exact: against the host build with newlib's math
(``codegen.verify.newlib_libm``: the libm members the firmware linked, rebuilt for the host) it must be
bit-identical; against the usual host build (glibc's math) it differs in the last bits where the
two libms round sin, cos, expm1, tanh differently, and is bounded by ``TOLERANCE``. Instructions are
counted with QEMU's ``-icount shift=0`` (one instruction = 1 ns of virtual time) read through the
board's 25 MHz timer, scaled by a loop of known length the firmware times first (TCG plugins would
count them too, but Debian's qemu-system-arm ships none, nor the header to build one).
"""
from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from . import newlib_libm
from ..pipeline.compile import CompileError, ToolError, compile_library, package_data, run_tool
from ..pipeline.compile import work_dir as default_work_dir
from ..pipeline.emit import MATH_FUNCTIONS
from ..pipeline.load import load
from .measure import run_relative_error

FIRMWARE_SRC = package_data("c_harness") / "cortex_m"
# CPU of the firmware Makefile -> (name, the precision its FPU runs)
CPUS = {"m4f": ("cortex-m4f", "float"), "m7": ("cortex-m7", "double")}
# Debian package -> how to tell it is installed
PACKAGES = {"gcc-arm-none-eabi": "arm-none-eabi-gcc", "libnewlib-arm-none-eabi": "libc.a",
            "qemu-system-arm": "qemu-system-arm", "newlib-source": "newlib-*.tar.xz"}
# relative to the host build with glibc's math over the run (the one with newlib's must be
# bit-identical). double: glibc's and newlib's sin/cos/expm1/tanh differ by an ulp on some
# arguments; over the 12 default targets at 100, 300, 1,000, 3,000 and 10,000 steps it was 4.0e-14
# at most (I&I speed, 256 ulps of its largest estimate, within the first 100 steps and not growing
# after; the others 2.0e-14 at most): 1e-13 bounds it with a factor 2.5 of margin
TOLERANCE = {"double": 1e-13, "float": 1e-4}
# double-precision routines (soft-float helpers, double libm; gcc fuses sin and cos into sincos):
# a single-precision firmware links none
DOUBLE_ROUTINES = re.compile(rf"^(?:__aeabi_(?:c?d\w+|\w*2d)|{MATH_FUNCTIONS}|sincos)$")


class EmbeddedError(ToolError):
    """The firmware failed on the emulator (exit status, fault, or an observer status)."""


def missing_packages():
    """Debian packages of the ARM flow not installed yet (list of names)."""
    missing = []
    for pkg, probe in PACKAGES.items():
        if probe.endswith(".tar.xz"):
            ok = bool(sorted(newlib_libm.NEWLIB_SOURCE.glob(probe)))
        elif probe == "libc.a":
            gcc = shutil.which("arm-none-eabi-gcc")
            ok = gcc and Path(subprocess.run([gcc, "-print-file-name=libc.a"], capture_output=True,
                                             text=True).stdout.strip()).is_file()
        else:
            ok = shutil.which(probe) is not None
        if not ok:
            missing.append(pkg)
    return missing


def _cpu(cpu):
    """(name, precision) of a CPU of the firmware Makefile, or ValueError."""
    if cpu not in CPUS:
        raise ValueError(f"cpu must be one of {sorted(CPUS)}, got {cpu!r}")
    return CPUS[cpu]


def _make(target_dir, cpu, work_dir, goal):
    _cpu(cpu)
    missing = missing_packages()
    if missing:
        raise CompileError(f"ARM toolchain missing: apt-get install {' '.join(missing)} (or `make embedded`)")
    work_dir = Path(work_dir or default_work_dir() / "embedded").resolve()
    cmd = ["make", "-s", "-C", FIRMWARE_SRC, f"TARGET={Path(target_dir).resolve()}",
           f"PREFIX={_meta(target_dir)['prefix']}", f"CPU={cpu}", f"BUILD={work_dir}", goal]
    return run_tool(cmd, f"{goal} of the firmware of {Path(target_dir).name} for {cpu}").stdout


def _meta_path(target_dir):
    path = next(iter(sorted(Path(target_dir).glob("*.json"))), None)
    if path is None:
        raise CompileError(f"target_dir: {target_dir} is not a generated target (no metadata .json)")
    return path


def _meta(target_dir):
    return json.loads(_meta_path(target_dir).read_text())


def firmware(target_dir, cpu, work_dir=None):
    """Cross-compile and link the example firmware of a target.

    Parameters
    ----------
    target_dir : path
        A folder written by ``codegen.pipeline.emit`` ("float" targets for "m4f").
    cpu : {"m4f", "m7"}
    work_dir : path, optional
        Default ``build/embedded`` in the working folder; the ELF is ``<work_dir>/<prefix>-<cpu>/firmware.elf``.

    Returns
    -------
    dict
        ``elf`` (Path), ``board`` (QEMU machine), ``cflags`` and ``qemu`` (argv running the ELF),
        from the firmware Makefile. Raises CompileError with the compiler's message.
    """
    _make(target_dir, cpu, work_dir, "all")
    info = dict(line.split("=", 1) for line in _make(target_dir, cpu, work_dir, "info").splitlines())
    return {"elf": Path(info["elf"]), "board": info["board"], "cflags": info["cflags"],
            "qemu": shlex.split(info["qemu"])}


def memory(elf):
    """(flash, static RAM) of a linked ELF in bytes: flash = code, constants and the initial
    values of .data; static RAM = .data + .bss (the stack region is reported separately).

    Parameters
    ----------
    elf : path
        A linked firmware (``firmware(...)["elf"]``), read with ``arm-none-eabi-size -A``.

    Returns
    -------
    (int, int)
        Flash and static RAM [bytes]."""
    out = run_tool(["arm-none-eabi-size", "-A", elf], "arm-none-eabi-size").stdout
    size = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\.\S+)\s+(\d+)\s+\d+$", out, re.M)}
    flash = sum(size.get(s, 0) for s in (".text", ".ARM.exidx", ".data"))
    return flash, size.get(".data", 0) + size.get(".bss", 0)


def linked_double_routines(elf):
    """Names of double-precision routines (soft-float helpers, double libm) linked into an ELF.

    Parameters
    ----------
    elf : path
        A linked firmware, read with ``arm-none-eabi-nm``.

    Returns
    -------
    list of str
        Sorted symbol names matching ``DOUBLE_ROUTINES`` (none for a clean float firmware)."""
    out = run_tool(["arm-none-eabi-nm", elf], "arm-none-eabi-nm").stdout
    return sorted({line.split()[-1] for line in out.splitlines()
                   if DOUBLE_ROUTINES.match(line.split()[-1])})


def run(fw, Y, U, precision, timeout=120, H=None):
    """Run a firmware on QEMU over the inputs of a run and read back its estimates.

    Parameters
    ----------
    fw : dict
        What ``firmware`` returns (``elf``, ``board``, ``qemu`` argv).
    Y, U : array_like, shapes (N, ny), (N, nu)
        Measurements and inputs, passed to the firmware by semihosting.
    precision : {"double", "float"}
        Precision of the target (the width of the values exchanged).
    timeout : float
        Seconds of wall time before the emulator is given up (EmbeddedError).
    H : array_like (N,), optional
        Elapsed time of each sample (s): the firmware replays the run a second time with
        ``<prefix>_step_dt`` (a jittered loop).

    Returns
    -------
    dict
        ``est`` (N, nest) float64 estimates, ``steps``, ``ticks``, ``max_ticks``, ``calib_ticks``,
        ``calib_insns``, ``stack`` and ``stack_size`` (bytes), as printed by the firmware; with
        ``H`` also ``est_dt`` (N, nest), ``steps_dt``, ``ticks_dt``, ``max_ticks_dt`` and
        ``stack_dt`` (the peak over both passes) of the step_dt pass. Raises EmbeddedError if it exits non-zero or stops early.
    """
    size = 4 if precision == "float" else 8
    rows = np.hstack([np.asarray(Y, float), np.asarray(U, float).reshape(len(Y), -1)])
    with tempfile.TemporaryDirectory(prefix="obs-qemu-") as work:
        rows.astype(f"<f{size}").tofile(Path(work) / "obs_in.bin")
        if H is not None:
            np.asarray(H, float).reshape(len(rows)).astype(f"<f{size}").tofile(Path(work) / "obs_dt.bin")
        try:
            proc = subprocess.run(fw["qemu"], cwd=work, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise EmbeddedError(f"{fw['elf']} on {fw['board']}: no exit after {timeout} s") from None
    done = re.search(r"^done (.*)$", proc.stdout, re.M)
    if proc.returncode != 0 or done is None:
        raise EmbeddedError(f"{fw['elf']} on {fw['board']} failed (exit {proc.returncode}):\n"
                            + "\n".join(proc.stdout.splitlines()[-3:] + [proc.stderr.strip()]),
                            proc.returncode, proc.stderr)
    rec = {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", done.group(1))}
    rec["est"] = _estimates(proc.stdout, "e", size)
    if rec["steps"] != len(rows) or len(rec["est"]) != len(rows):
        raise EmbeddedError(f"{fw['elf']}: {rec['steps']} of {len(rows)} steps ran")
    if H is not None:
        done = re.search(r"^done_dt (.*)$", proc.stdout, re.MULTILINE)
        rec.update({f"{k}_dt": int(v) for k, v in re.findall(r"(\w+)=(\d+)", done.group(1) if done else "")})
        rec["est_dt"] = _estimates(proc.stdout, "d", size)
        if rec.get("steps_dt") != len(rows) or len(rec["est_dt"]) != len(rows):
            raise EmbeddedError(f"{fw['elf']}: {rec.get('steps_dt')} of {len(rows)} step_dt calls ran")
    return rec


def _estimates(stdout, tag, size):
    """The (N, nest) estimates of the firmware's lines ``<tag> <hex> ...`` (bit patterns of
    ``size``-byte reals, big-endian hex) as float64."""
    est = re.findall(rf"^{tag}((?: [0-9a-f]+)*)$", stdout, re.MULTILINE)
    bits = bytes.fromhex("".join(est).replace(" ", ""))
    return np.frombuffer(bits, f">f{size}").astype(float).reshape(len(est), -1)


def verify(target_dir, cpu, Y, U, host=None, double=None, work_dir=None, H=None):
    """Build, run and measure a target on an emulated Cortex-M; compare with the host build.

    Parameters
    ----------
    target_dir : path
        A generated folder whose precision the CPU runs natively (m4f: float, m7: double).
    cpu : {"m4f", "m7"}
    Y, U : array_like, shapes (N, ny), (N, nu)
        Inputs of the run (the firmware starts from Y[0], default parameters, zero estimate).
    host : array_like (N, nest), optional
        The host build's estimates over the same run (glibc's math; computed when not given).
    double : array_like (N, nest), optional
        Double-precision estimates over the same run: recorded as ``rel_diff_double``.
    work_dir : path, optional
        Where the firmware is built (default ``<repo>/build/embedded``).
    H : array_like (N,), optional
        Elapsed times (s) of a second, jittered pass through ``<prefix>_step_dt`` (``run``).

    Returns
    -------
    dict
        The record ``record`` writes into the metadata: cpu, board, cflags, steps, flash_bytes,
        static_ram_bytes, stack_peak_bytes, instructions_per_step (mean over the steps),
        instructions_per_step_max, instructions_per_tick (measured), rel_diff_host and
        bit_identical (against the host build with glibc's math), tolerance, libm_members (the
        libm.a members linked), rel_diff_host_newlib and bit_identical_newlib (against the host
        build with those members: None, and newlib_unavailable saying why, when they cannot be
        built here), double_routines (linked double-precision routines of a float firmware: must
        be none), rel_diff_double (when ``double`` is given), ok (bit-identical to the newlib host
        build, within tolerance of the glibc one, stack not exhausted, no double routine); with
        ``H``: instructions_per_step_dt (mean over the step_dt pass; intervals above dt_max cost
        one step per sub-interval), instructions_per_step_dt_max, stack_peak_bytes_dt (both
        passes), rel_diff_host_dt,
        bit_identical_newlib_dt (against host builds stepped with the same elapsed times), part
        of ok too.
    """
    meta = _meta(target_dir)
    name, native = _cpu(cpu)
    precision = meta.get("precision", "double")
    if precision != native:
        raise ValueError(f"cpu: {cpu} runs {native} targets, {meta['prefix']} is {precision}")
    if host is None:
        host = host_run(target_dir, Y, U)
    fw = firmware(target_dir, cpu, work_dir)
    flash, ram = memory(fw["elf"])
    out = run(fw, Y, U, precision, H=H)
    per_tick = out["calib_insns"] / out["calib_ticks"]
    rec = {"cpu": name, "board": fw["board"], "cflags": fw["cflags"], "steps": out["steps"],
           "flash_bytes": flash, "static_ram_bytes": ram,
           "stack_peak_bytes": out["stack"], "stack_size_bytes": out["stack_size"],
           "instructions_per_step": round(out["ticks"] * per_tick / out["steps"]),
           "instructions_per_step_max": round(out["max_ticks"] * per_tick),
           "instructions_per_tick": per_tick,
           "rel_diff_host": run_relative_error(out["est"], host), "tolerance": TOLERANCE[precision],
           "bit_identical": bool(np.array_equal(out["est"], host)),
           "double_routines": linked_double_routines(fw["elf"]) if precision == "float" else [],
           "libm_members": newlib_libm.linked_members(fw["elf"].parent / "firmware.map"),
           "rel_diff_host_newlib": None, "bit_identical_newlib": None}
    reason = newlib_libm.unavailable()
    if reason:
        rec["newlib_unavailable"] = reason
    else:
        newlib = host_run(target_dir, Y, U, libm=newlib_libm.host_libm(fw))
        rec["rel_diff_host_newlib"] = run_relative_error(out["est"], newlib)
        rec["bit_identical_newlib"] = bool(np.array_equal(out["est"], newlib))
    if double is not None:
        rec["rel_diff_double"] = run_relative_error(out["est"], double)
    ok_dt = True
    if H is not None:
        rec["instructions_per_step_dt"] = round(out["ticks_dt"] * per_tick / out["steps_dt"])
        rec["instructions_per_step_dt_max"] = round(out["max_ticks_dt"] * per_tick)
        rec["stack_peak_bytes_dt"] = out["stack_dt"]
        rec["rel_diff_host_dt"] = run_relative_error(out["est_dt"], host_run(target_dir, Y, U, H=H))
        rec["bit_identical_newlib_dt"] = None
        if not reason:
            newlib_dt = host_run(target_dir, Y, U, libm=newlib_libm.host_libm(fw), H=H)
            rec["bit_identical_newlib_dt"] = bool(np.array_equal(out["est_dt"], newlib_dt))
        ok_dt = (rec["bit_identical_newlib_dt"] is not False and rec["rel_diff_host_dt"] <= rec["tolerance"]
                 and out["stack_dt"] < out["stack_size"])
    rec["ok"] = bool(rec["bit_identical_newlib"] is not False and rec["rel_diff_host"] <= rec["tolerance"]
                     and out["stack"] < out["stack_size"] and not rec["double_routines"] and ok_dt)
    return rec


def host_run(target_dir, Y, U, libm=None, H=None):
    """Estimates of the host build of a target over a run, started as the firmware is (from
    Y[0], default parameters, zero estimate); with the elapsed times ``H`` (N,) (s), one
    ``step(y, u, dt)`` (the C's step_dt) per sample, as the firmware's second pass.

    Parameters
    ----------
    target_dir : path
        A generated folder (built with gcc for the host and loaded with ctypes).
    Y, U : array_like, shapes (N, ny), (N, nu)
        Measurements and inputs.
    libm : path, optional
        An object serving the math functions instead of the system's libm
        (``newlib_libm.host_libm``); CompileError if the build still calls a rounding one of glibc.

    Returns
    -------
    ndarray (N, nest)"""
    lib = compile_library(target_dir, extra_flags=[str(libm)] if libm else ())
    leaked = newlib_libm.glibc_calls(lib) if libm else []
    if leaked:
        raise CompileError(f"{lib} still calls the system's {', '.join(leaked)} (not in {libm})")
    obs = load(target_dir, lib)
    obs.reset(Y[0])
    if H is None:
        return obs.run(Y, U)
    return np.array([obs.step(y, u, h) for y, u, h in zip(Y, U, np.asarray(H, float))]).reshape(len(Y), obs.nest)


def record(target_dir, rec):
    """Write ``rec`` into the target's metadata JSON under "embedded" -> rec["cpu"] (atomically).

    Parameters
    ----------
    target_dir : path
        A generated folder (its metadata .json is rewritten).
    rec : dict
        A record of ``verify`` (its "cpu" is the key).

    Returns
    -------
    Path
        The metadata file."""
    path = _meta_path(target_dir)
    meta = json.loads(path.read_text())
    meta.setdefault("embedded", {})[rec["cpu"]] = rec
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    with os.fdopen(fd, "w") as f:
        f.write(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)
    return path


def verify_target(spec, target, out, steps=300, work_dir=None):
    """A target in double on the Cortex-M7 and in float on the Cortex-M4F: emit both into
    ``out``, run ``steps`` samples of ``check.run_inputs`` on each and on the host, record the
    measurements in each folder's metadata.

    Parameters
    ----------
    spec : codegen.core.spec.ObserverSpec
    target : codegen.core.target.Target
        The target (its precision is replaced by each CPU's).
    out : path
        Parent folder of the generated targets.
    steps : int
        Samples of the run (a few hundred: the emulator counts every instruction).
    work_dir : path, optional
        Where the firmware is built (default ``<repo>/build/embedded``).

    Returns
    -------
    list of (prefix, record)
        Each record also holds the cost of ``<prefix>_step_dt`` over the same samples with
        jittered elapsed times (``jittered_stamps``), see ``verify``.
    """
    from dataclasses import replace

    from . import run_inputs
    from ..pipeline.emit import emit
    from .inputs import jittered_stamps

    def named(prec):   # an explicit name gets the precision suffix of the default names
        return target.name if target.name is None or prec == "double" else f"{target.name}_{prec}"
    folders = {cpu: emit(replace(target, precision=prec, name=named(prec)), out, spec=spec)
               for cpu, (_, prec) in CPUS.items()}
    dt = target.discretization.dt
    Y, U = run_inputs(spec, steps, dt)
    H = np.concatenate([[dt], np.diff(jittered_stamps(steps, dt))])   # 0.7-1.6 dt, every 100th 10 dt
    host = {cpu: host_run(folder, Y, U) for cpu, folder in folders.items()}
    rows = []
    for cpu, folder in folders.items():
        rec = verify(folder, cpu, Y, U, host=host[cpu], double=host["m7"], work_dir=work_dir, H=H)
        record(folder, rec)
        rows.append((folder.name, rec))
    return rows
