"""gcc -> shared library, cached by content hash (DESIGN §4 "Build and runtime").

Default flags -O3 (portable); ``native=True`` adds -march=native; never -ffast-math.
A failed compile raises BuildError carrying the compiler's message.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import tempfile
from functools import lru_cache
from pathlib import Path

# -fno-semantic-interposition: let gcc inline CasADi's non-static helpers (casadi_sq) under -fPIC
BASE_FLAGS = ["-O3", "-std=c99", "-fPIC", "-shared", "-fno-semantic-interposition", "-Wall", "-Wextra",
              "-pedantic"]
STRICT_FLAGS = ["-Werror"]


class BuildError(RuntimeError):
    """The C compiler failed; the message holds its command line and output."""


def repo_root():
    return Path(__file__).resolve().parent.parent


def cache_dir():
    """$CODEGEN_CACHE, else <repo>/build/cache."""
    return Path(os.environ.get("CODEGEN_CACHE", repo_root() / "build" / "cache"))


@lru_cache(maxsize=4)
def compiler_version(cc):
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        raise BuildError(f"C compiler {cc!r} not usable: {e}") from None
    return out.splitlines()[0]


def build(target_dir, native=False, strict=False, cc=None, extra_flags=(), cache=None):
    """Compile generated/<prefix>/ into lib<prefix>.so; returns its absolute Path.

    The library lands in <cache>/<prefix>-<hash>/ where the hash covers the sources, the
    flags and the compiler version, so an unchanged target is never rebuilt."""
    target_dir = Path(target_dir).resolve()
    meta_file = next(iter(sorted(target_dir.glob("*.json"))), None)
    if meta_file is None:
        raise BuildError(f"{target_dir} is not a generated target (no metadata .json)")
    prefix = json.loads(meta_file.read_text())["prefix"]
    cc = cc or os.environ.get("CC", "gcc")
    flags = BASE_FLAGS + (["-march=native"] if native else []) + (STRICT_FLAGS if strict else []) \
        + list(extra_flags)
    # read the sources once: the hash and the compiled code are the same bytes, even if another
    # process regenerates the folder meanwhile (the cache can never hold a library whose
    # content differs from its key)
    files = {f.name: f.read_bytes() for f in sorted(target_dir.iterdir()) if f.suffix in (".c", ".h")}
    missing = {f"{prefix}.c", f"{prefix}_kernels.c"} - set(files)
    if missing:
        raise BuildError(f"{target_dir}: missing {', '.join(sorted(missing))}")
    h = hashlib.sha256()
    for name, data in files.items():
        h.update(name.encode() + b"\0" + data + b"\0")
    h.update(json.dumps([cc, compiler_version(cc), flags]).encode())
    out_dir = Path(cache or cache_dir()) / f"{prefix}-{h.hexdigest()[:16]}"
    lib = out_dir / f"lib{prefix}.so"
    if lib.exists():
        return lib
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out_dir) as work:
        work = Path(work)
        for name, data in files.items():
            (work / name).write_bytes(data)
        tmp = work / f"lib{prefix}.so"
        cmd = [cc, *flags, "-I", str(work), "-o", str(tmp), str(work / f"{prefix}.c"),
               str(work / f"{prefix}_kernels.c"), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            msg = proc.stderr.strip().replace(str(work), str(target_dir))
            raise BuildError(f"compiling {prefix} failed (exit {proc.returncode}):\n  "
                             f"{' '.join(cmd).replace(str(work), str(target_dir))}\n{msg}")
        os.replace(tmp, lib)
    return lib


def clear_cache():
    shutil.rmtree(cache_dir(), ignore_errors=True)
