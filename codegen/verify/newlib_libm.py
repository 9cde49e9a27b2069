"""Newlib's libm on the host: the math a Cortex-M firmware linked, rebuilt for the host, so that a
host build of a target rounds sin, cos, exp, ... exactly as the firmware does.

The firmware's estimates differ from the usual host build (glibc's libm) in the last bits: newlib's
``sin``, ``cos``, ``expm1``, ``tanh`` (fdlibm) round some arguments differently from glibc's (about
3 % of sin/cos arguments in [-3.2, 3.2] by one ulp). The arithmetic of the generated C is the same
on both (``-std=c99``: no contraction; SSE2 and the FPU round each operation alike). So
``host_libm`` takes the members of newlib's ``libm.a`` that the firmware's link map names,
compiles their sources (Debian's ``newlib-source``) for the host as Debian compiled them for the
Cortex-M, and links them, hidden, into the host build: its estimates are then the firmware's bit
for bit (``codegen.verify.cortex_m.verify`` checks it).

    obj = host_libm(fw)                 # fw: codegen.verify.cortex_m.firmware(...)
    compile_library(target_dir, extra_flags=[obj])
"""
from __future__ import annotations

import platform
import re
import shutil
import subprocess
import tarfile
import tempfile
from pathlib import Path

from ..pipeline.compile import CompileError, cached_compile, compiler, digest, run_tool
from ..core.cache import cache_dir

# Debian's newlib-source: the sources of the libnewlib-arm-none-eabi it builds
NEWLIB_SOURCE = Path("/usr/src/newlib")
# libm.a member lib_a-<stem>.o comes from libm/<dir>/<stem>.c; the members of libm/machine/arm
# (sqrt, floor, ceil, rint, round, trunc, nearbyint: exact in IEEE 754, any implementation gives
# the same result) are taken from the portable source of the same name
SOURCE_DIRS = ("common", "math")
# Debian compiled libm.a as "GNU C17 12.2.1 -march=armv7e-m+fp.dp -g -O2 -fno-builtin" (its
# DW_AT_producer): GNU C contracts a*b + c into the FPU's fused multiply-add (vfma.f64 in
# __kernel_sin); -mfma -ffp-contract=fast contract the same expressions on x86-64 (without, 0.7 %
# of sin arguments round differently). Hidden: the host build's calls bind to these, not glibc's.
HOST_FLAGS = ["-O2", "-std=gnu17", "-fno-builtin", "-ffp-contract=fast", "-fPIC", "-fvisibility=hidden", "-w"]
ARCH_FLAGS = {"x86_64": ["-mfma"], "aarch64": []}
# gcc fuses sin(x) and cos(x) into sincos on the host (glibc has it), not for newlib: newlib's
# sincos (sin, then cos) serves the fused call where the firmware linked both
SINCOS = {"w_sincos": {"s_sin", "s_cos"}, "wf_sincos": {"sf_sin", "sf_cos"}}
# math functions exact in IEEE 754 (any libm gives the same result): glibc's may serve them
EXACT = re.compile(r"^(?:fabs|floor|ceil|trunc|round|rint|nearbyint|fmax|fmin|copysign|sqrt|fdim|fma"
                   r"|fmod|remainder)f?$")
# newlib's <machine/ieeefp.h> for a little-endian host, with what the old wrappers (w_sqrt.c,
# wf_exp.c, s_lib_ver.c) need of newlib's <math.h> and glibc's lacks; the other headers are the host's
IEEEFP_H = """#ifndef NEWLIB_HOST_IEEEFP_H
#define NEWLIB_HOST_IEEEFP_H
#define __IEEE_LITTLE_ENDIAN
enum __fdlibm_version { __fdlibm_ieee = -1, __fdlibm_posix };
#define _LIB_VERSION_TYPE enum __fdlibm_version
#define _LIB_VERSION __fdlib_version
extern _LIB_VERSION_TYPE _LIB_VERSION;
#define _IEEE_ __fdlibm_ieee
#define _POSIX_ __fdlibm_posix
#endif
"""
# newlib's settings that differ between the Cortex-M multilibs, read from the ARM compiler
CONFIG_PROBE = "#include <machine/ieeefp.h>\n__OBSOLETE_MATH __ARM_FEATURE_FMA\n"


def unavailable():
    """Why newlib's libm cannot be built for this host (str), or None when it can."""
    if not sorted(NEWLIB_SOURCE.glob("newlib-*.tar.xz")):
        return f"no newlib sources in {NEWLIB_SOURCE} (apt-get install newlib-source)"
    arch = platform.machine()
    if arch not in ARCH_FLAGS:
        return f"host {arch}: only x86_64 and aarch64 are set up"
    cpuinfo = Path("/proc/cpuinfo")
    if arch == "x86_64" and not (cpuinfo.exists() and re.search(r"^flags\s*:.* fma\b", cpuinfo.read_text(), re.M)):
        return "host CPU has no fused multiply-add (the Cortex-M build of libm uses it)"
    return None


def linked_members(map_file):
    """Stems of the members of newlib's ``libm.a`` a firmware linked (``s_sin``, ``k_sin``, ...).

    Parameters
    ----------
    map_file : path
        The linker's map file of the firmware (``-Wl,-Map``).

    Returns
    -------
    list of str
    """
    return sorted(set(re.findall(r"libm\.a\(lib_a-(\w+)\.o\)", Path(map_file).read_text())))


def sources():
    """newlib's libm sources, extracted once from Debian's tarball into the cache.

    Returns
    -------
    Path
        A folder with ``common/`` and ``math/`` (libm's) and ``include/machine/ieeefp.h``.
    """
    reason = unavailable()
    if reason:
        raise CompileError(f"newlib's libm for the host: {reason}")
    tarball = sorted(NEWLIB_SOURCE.glob("newlib-*.tar.xz"))[-1]
    out = cache_dir() / f"newlib-src-{digest(tarball.read_bytes() + IEEEFP_H.encode())[:16]}"
    if (out / "include" / "machine" / "ieeefp.h").exists():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".newlib-src-", dir=out.parent))
    try:
        with tarfile.open(tarball) as tar:
            for m in tar:
                parts = Path(m.name).parts
                if m.isfile() and len(parts) == 5 and parts[1:3] == ("newlib", "libm") \
                        and parts[3] in SOURCE_DIRS and parts[4].endswith((".c", ".h")):
                    (tmp / parts[3]).mkdir(exist_ok=True)
                    (tmp / parts[3] / parts[4]).write_bytes(tar.extractfile(m).read())
        (tmp / "include" / "machine").mkdir(parents=True)
        (tmp / "include" / "machine" / "ieeefp.h").write_text(IEEEFP_H)
        try:
            tmp.rename(out)
        except OSError:          # a concurrent extraction got there first
            pass
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def arm_config(cflags):
    """newlib's ``-D`` settings of the multilib a firmware links: ``__OBSOLETE_MATH`` (the old
    fdlibm single-precision code unless the FPU has double precision) and ``HAVE_FAST_FMA``.

    Parameters
    ----------
    cflags : str
        The firmware's compiler flags (``firmware(...)["cflags"]``: CPU, FPU, float ABI).

    Returns
    -------
    list of str
    """
    cmd = ["arm-none-eabi-gcc", *cflags.split(), "-E", "-P", "-x", "c", "-"]
    proc = subprocess.run(cmd, input=CONFIG_PROBE, capture_output=True, text=True)
    words = proc.stdout.split()
    if proc.returncode != 0 or len(words) != 2:
        raise CompileError(f"reading newlib's settings failed: {' '.join(cmd)}\n{proc.stderr.strip()}")
    obsolete, fma = (w if w.isdigit() else "0" for w in words)
    return [f"-D__OBSOLETE_MATH={obsolete}", f"-DHAVE_FAST_FMA={fma}"]


def host_libm(fw, cache=None):
    """The libm members a firmware linked, compiled for the host into one relocatable object.

    Parameters
    ----------
    fw : dict
        What ``codegen.verify.cortex_m.firmware`` returns (its ``elf``, beside ``firmware.map``, and
        ``cflags``).
    cache : path, optional
        Cache root (default ``cache_dir()``).

    Returns
    -------
    Path
        ``<cache>/newlib-libm-<hash>/newlib_libm.o``: pass it to ``codegen.pipeline.compile.build`` in
        ``extra_flags``. Raises CompileError (sources missing, a member without a source).
    """
    src = sources()
    linked = set(linked_members(Path(fw["elf"]).parent / "firmware.map"))
    stems = sorted(linked | {w for w, pair in SINCOS.items() if pair <= linked})
    files = {}
    for stem in stems:
        path = next((src / d / f"{stem}.c" for d in SOURCE_DIRS if (src / d / f"{stem}.c").exists()), None)
        if path is None:
            raise CompileError(f"libm.a member lib_a-{stem}.o: no {stem}.c in newlib's libm/{{common,math}}")
        files[path.name] = path.read_bytes()
    files.update({p.name: p.read_bytes() for p in sorted((src / "common").glob("*.h"))})
    tool = compiler()
    flags = [*HOST_FLAGS, *ARCH_FLAGS[platform.machine()], *arm_config(fw["cflags"])]

    def commands(work, out):
        for stem in stems:
            yield ([tool.path, *flags, "-I", src / "include", "-I", work, "-c", work / f"{stem}.c",
                    "-o", work / f"{stem}.o"], f"compiling newlib's {stem}.c for the host")
        yield ([tool.path, "-r", "-nostdlib", "-o", out / "newlib_libm.o",
                *(work / f"{stem}.o" for stem in stems)], "linking newlib's libm for the host")

    out = cached_compile("newlib-libm", [tool, flags, IEEEFP_H], files, ["newlib_libm.o"], commands,
                       cache or cache_dir())
    return out.resolve() / "newlib_libm.o"


def glibc_calls(lib):
    """Math functions a host library still takes from the system's libm that round (not
    ``EXACT``): empty when newlib's serve them all.

    Parameters
    ----------
    lib : path
        A shared library (``nm -D --undefined-only``).

    Returns
    -------
    list of str
    """
    from ..pipeline.emit import MATH_FUNCTIONS
    out = run_tool(["nm", "-D", "--undefined-only", lib], "nm").stdout
    names = {line.split()[-1].split("@")[0] for line in out.splitlines() if line.strip()}
    math = re.compile(rf"^(?:{MATH_FUNCTIONS}|sincos)f?$")
    return sorted(n for n in names if math.match(n) and not EXACT.match(n))
