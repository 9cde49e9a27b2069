"""The toolchain: compiler lookup, flags, content-hash cached compiles (docs/architecture.md §4 "Build and runtime").

``compile_library`` turns generated/<prefix>/ into lib<prefix>.so; ``codegen.verify.c_programs`` compiles its
programs through the same ``compiler``, ``c_flags`` and ``cached_compile``. Default flags -O3
(portable); ``native=True`` adds -march=native; never -ffast-math. A failed compile raises
CompileError carrying the compiler's command line and message.
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import subprocess
import tempfile
from collections import namedtuple
from functools import lru_cache
from pathlib import Path

from ..core.atomic import replace_dir, write_error
from ..core.cache import work_dir, cache_dir, package_data  # noqa: F401  (re-exported: one place for the paths)

# -ffp-contract=off: never fuse a*b+c into an FMA (gcc's default in ISO C mode, not Clang's; the
# generated Makefile and CMakeLists.txt pass it too, so every route builds the same bits)
C_FLAGS = ["-O3", "-std=c99", "-ffp-contract=off", "-Wall", "-Wextra", "-pedantic", "-Wdouble-promotion"]
# -fno-semantic-interposition: let gcc inline CasADi's non-static helpers (casadi_sq) under -fPIC
SHARED_FLAGS = ["-fPIC", "-shared", "-fno-semantic-interposition"]
NATIVE_FLAGS = ["-march=native"]
STRICT_FLAGS = ["-Werror"]

Compiler = namedtuple("Compiler", "path version")


class ToolError(RuntimeError):
    """An external program failed; the message holds its command line and output.

    Attributes ``returncode`` (None when it could not be started) and ``stderr``."""

    def __init__(self, message, returncode=None, stderr=""):
        super().__init__(message)
        self.returncode = returncode
        self.stderr = stderr


class CompileError(ToolError):
    """The C (or C++) compiler failed or is missing."""


def compiler(cc=None, env="CC", default="gcc"):
    """The compiler ``cc``, else ``$<env>``, else ``default``, found on PATH.

    Returns
    -------
    Compiler
        (path, version): absolute path and the first line of ``--version``; CompileError if absent.
    """
    return _probe(cc or os.environ.get(env, default))


@lru_cache(maxsize=8)
def _probe(name):
    path = shutil.which(name)
    if path is None:
        raise CompileError(f"compiler {name!r} not found on PATH")
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        raise CompileError(f"compiler {name!r} not usable: {e}") from None
    return Compiler(path, out.splitlines()[0] if out else "")


def c_flags(native=False, strict=False, shared=False, extra=()):
    """C flags: C_FLAGS [+ SHARED_FLAGS if ``shared``] [+ -march=native if ``native``] [+ -Werror if
    ``strict``] + the list ``extra`` (last, so they win)."""
    return C_FLAGS + (SHARED_FLAGS if shared else []) + (NATIVE_FLAGS if native else []) \
        + (STRICT_FLAGS if strict else []) + list(extra)


def digest(data):
    """sha256 hex digest of the bytes ``data`` (for ``cached_compile`` keys)."""
    return hashlib.sha256(data).hexdigest()


def run_tool(cmd, what, error=CompileError, shown=()):
    """Run ``cmd``; on a non-zero exit raise ``error`` with ``what``, the command and its stderr.

    ``shown``: (private path, path to show instead) pairs rewritten in the message."""
    cmd = [str(c) for c in cmd]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        msg = f"{what} failed (exit {proc.returncode}):\n  {' '.join(cmd)}\n{proc.stderr.strip()}"
        for private, public in shown:
            msg = msg.replace(str(private), str(public))
        raise error(msg, proc.returncode, proc.stderr)
    return proc


CACHE_ELSEWHERE = "or set CODEGEN_CACHE to a folder elsewhere"   # the fix of a WriteError of the cache
MANIFEST = "manifest.json"   # beside the products of a cache folder: name -> size, sha256


def _manifest(folder):
    """The folder's manifest, name -> {"size": int, "sha256": hex str}, or None when it is missing,
    unreadable or not of that form (e.g. ``{"libx.so": 5}``): then nothing in the folder is trusted."""
    try:
        m = json.loads((Path(folder) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(m, dict) or not all(_record_ok(r) for r in m.values()):
        return None
    return m


def _record_ok(record):
    """True when ``record`` is {"size": int >= 0, "sha256": 64 hex digits}."""
    return (isinstance(record, dict) and isinstance(record.get("size"), int) and not isinstance(record["size"], bool)
            and record["size"] >= 0 and isinstance(record.get("sha256"), str) and len(record["sha256"]) == 64)


def _mismatch(path, record):
    """None if the file has the recorded size and sha256, else what differs."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        return f"unreadable ({e.strerror})"
    if len(data) != record["size"]:
        return f"{len(data)} bytes, {record['size']} recorded at build"
    return None if digest(data) == record["sha256"] else "sha256 differs from the one recorded at build"


def _complete(folder, names):
    """Every file of ``names`` is in the folder's manifest and matches it."""
    m = _manifest(folder)
    return m is not None and set(names) <= set(m) and not any(
        _mismatch(Path(folder) / n, m[n]) for n in names)


def _elf_short(path):
    """None when the ELF file ``path`` holds every byte its headers point to (program headers,
    segments, section headers), else what is missing: a segment past the end of the file is a
    SIGBUS when the loader touches it."""
    import struct
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        return f"unreadable ({e.strerror})"
    if len(data) < 52 or data[:4] != b"\x7fELF" or data[4] not in (1, 2) or data[5] not in (1, 2):
        return f"not a whole ELF shared library ({len(data)} bytes)"
    wide, end = data[4] == 2, "<" if data[5] == 1 else ">"
    head = f"{end}16xHHI" + ("QQQ" if wide else "III") + "IHHHHHH"
    if len(data) < struct.calcsize(head):
        return f"ELF header cut at {len(data)} bytes"
    *_, phoff, shoff, _, _, phentsize, phnum, shentsize, shnum, _ = struct.unpack_from(head, data)
    need = max(phoff + phnum * phentsize, shoff + shnum * shentsize)
    ph = f"{end}IIQQQQQQ" if wide else f"{end}IIIIIIII"
    for i in range(phnum if phoff + phnum * phentsize <= len(data) else 0):
        fields = struct.unpack_from(ph, data, phoff + i * phentsize)
        offset, filesz = (fields[2], fields[5]) if wide else (fields[1], fields[4])
        need = max(need, offset + filesz)
    return None if need <= len(data) else f"{len(data)} bytes, its ELF headers point up to byte {need}"


def verify(path):
    """``path`` if it matches the size and sha256 recorded when it was built (the manifest of
    its cache folder), else CompileError (one line): a truncated library must never be mapped
    (SIGBUS), so a file of a cache folder its manifest does not record (a corrupt manifest, or
    no entry for it) is not trusted either. A library with no manifest beside it (a copy
    outside the cache) has no record to match: it is checked to be a whole ELF file."""
    path = Path(path)
    m = _manifest(path.parent)
    if not (path.parent / MANIFEST).exists():
        why = _elf_short(path)
        if why:
            why += f"; no build record ({MANIFEST}) beside it"
    elif m is None:
        why = f"its build record {path.parent / MANIFEST} is corrupt"
    elif path.name not in m:
        why = f"its build record {path.parent / MANIFEST} does not list it"
    else:
        why = _mismatch(path, m[path.name])
    if why:
        raise CompileError(f"{path} is corrupt or unverified: {why}; compile_library() rebuilds it "
                           f"(or delete {path.parent})")
    return path


def cached_compile(name, key, files, products, commands, cache, shown=None, keep=(), beside=None):
    """Compile once per content: ``<cache>/<name>-<hash>/`` holding ``products``.

    Parameters
    ----------
    name : str
        Stem of the cache folder (e.g. the target's prefix).
    key : JSON-able
        Everything else the products depend on: compiler path and version, flags, digests of
        sources compiled in place.
    files : dict
        File name -> bytes, read once by the caller: hashed, written into a private work folder
        and compiled from there (what is hashed is what is compiled, even if the source folder is
        regenerated meanwhile).
    products : sequence of str
        Files the finished folder holds.
    commands : callable
        ``commands(work, out)`` -> iterable of (argv, what): run in order, sources in ``work``
        (deleted afterwards, with any intermediate files), products written into ``out``.
    cache : path
        Cache root.
    shown : path, optional
        Where ``files`` came from; shown instead of ``work`` in error messages.
    keep : sequence of str
        Names of ``files`` (or of ``beside``) copied into the folder beside the products (e.g. the
        metadata).
    beside : dict, optional
        File name -> bytes kept beside the products but not hashed (what of them the products
        depend on goes into ``key``); the first build of a content keeps its own.

    Returns
    -------
    Path
        The folder (built now, or found complete in the cache: every product and kept file
        with the size and sha256 of its ``manifest.json``; a corrupt one is rebuilt).
        Raises CompileError; ``codegen.core.atomic.WriteError`` when the cache cannot be written
        (no space, no permission), nothing left of the attempt.
    """
    h = hashlib.sha256(json.dumps(key, sort_keys=True).encode())
    for fname, data in sorted(files.items()):
        h.update(fname.encode() + b"\0" + data + b"\0")
    out_dir = Path(cache) / f"{name}-{h.hexdigest()[:16]}"
    names = [*products, *keep]
    if _complete(out_dir, names):
        return out_dir
    try:
        out_dir.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}-", dir=out_dir.parent))
    except OSError as e:
        raise write_error(e, out_dir, CACHE_ELSEWHERE) from None
    try:
        work = tmp / ".work"
        work.mkdir()
        for fname, data in files.items():
            (work / fname).write_bytes(data)
        for cmd, what in commands(work, tmp):
            run_tool(cmd, what, shown=[(work, shown)] if shown is not None else ())
        shutil.rmtree(work)
        for fname in keep:
            (tmp / fname).write_bytes({**files, **(beside or {})}[fname])
        record = {}
        for n in names:
            data = (tmp / n).read_bytes()
            record[n] = {"size": len(data), "sha256": digest(data)}
        (tmp / MANIFEST).write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
        try:
            os.rename(tmp, out_dir)
        except OSError:
            # out_dir exists: a concurrent build got there first (keep theirs: it may be loaded
            # right now), or it is corrupt (swap ours in, in one step)
            if not _complete(out_dir, names):
                replace_dir(tmp, out_dir)
    except OSError as e:
        raise write_error(e, out_dir, CACHE_ELSEWHERE) from None
    except ToolError as e:        # the compiler or linker ran out of space writing the products
        if os.strerror(errno.ENOSPC) not in e.stderr:
            raise
        raise write_error(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)), out_dir, CACHE_ELSEWHERE) from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out_dir


def compile_library(target_dir, native=False, strict=False, cc=None, extra_flags=(), cache=None):
    """Compile generated/<prefix>/ into lib<prefix>.so.

    Parameters
    ----------
    target_dir : path
        A folder written by ``codegen.pipeline.emit``.
    native, strict : bool
        Add -march=native; add -Werror.
    cc : str, optional
        C compiler (default $CC, else gcc).
    extra_flags : sequence of str
        Appended to the flags.
    cache : path, optional
        Cache root (default ``cache_dir()``).

    Returns
    -------
    Path
        ``<cache>/<prefix>-<hash>/lib<prefix>.so``, absolute; the hash covers the sources, the
        flags and the compiler, so an unchanged target is never rebuilt.
    """
    target_dir = Path(target_dir).resolve()
    files = read_target(target_dir)
    meta_file = next((n for n in sorted(files) if n.endswith(".json")), None)
    if meta_file is None:
        raise CompileError(f"target_dir: {target_dir} is not a generated target (no metadata .json)")
    prefix = json.loads(files[meta_file])["prefix"]
    tool = compiler(cc)
    flags = c_flags(native, strict, shared=True, extra=extra_flags)
    missing = {f"{prefix}.c", f"{prefix}_kernels.c", f"{prefix}.json"} - set(files)
    if missing:
        raise CompileError(f"target_dir: {target_dir} misses {', '.join(sorted(missing))}")
    # The library is the C and its headers; of the metadata, everything but the "target" record
    # (how the target was named: a catalog name or the URDF behind it, the folder's name) goes
    # into the key, so `build ur5` and compile_observer(observers.build(..., load_robot("ur5")))
    # share one library (one cache for the CLI and Python).
    meta_name = f"{prefix}.json"
    meta = {k: v for k, v in json.loads(files[meta_name]).items() if k != "target"}
    beside = {meta_name: files[meta_name]}
    files = {n: b for n, b in files.items() if n.endswith((".c", ".h"))}
    lib = f"lib{prefix}.so"

    def commands(work, out):
        yield ([tool.path, *flags, "-I", work, "-o", out / lib, work / f"{prefix}.c",
                work / f"{prefix}_kernels.c", "-lm"], f"compiling {prefix}")

    key = [tool, flags, digest(json.dumps(meta, sort_keys=True).encode())]
    out = cached_compile(prefix, key, files, [lib], commands, cache or cache_dir(),
                         shown=target_dir, keep=[meta_name], beside=beside)
    return out.resolve() / lib


def read_target(target_dir, suffixes=(".c", ".h", ".json")):
    """The files of a generated folder (name -> bytes), all of one version of it.

    Read through one directory descriptor, then checked to still be the folder at that path:
    ``emit`` swaps a new version in and deletes the old one, so a read that raced with it is
    done again (what is read is what is compiled, and the metadata is the one it was built from).
    ``target_dir``: the folder (path); ``suffixes``: the file name endings read (others skipped).
    """
    for _ in range(20):
        try:
            fd = os.open(target_dir, os.O_RDONLY | os.O_DIRECTORY)
        except (FileNotFoundError, NotADirectoryError):
            raise CompileError(f"target_dir: {target_dir} is not a generated target folder") from None
        try:
            files = {}
            for name in sorted(os.listdir(fd)):
                if name.endswith(tuple(suffixes)):
                    with open(name, "rb", opener=lambda p, flags: os.open(p, flags, dir_fd=fd)) as f:
                        files[name] = f.read()
            if os.stat(target_dir).st_ino == os.fstat(fd).st_ino:
                return files
        except FileNotFoundError:       # the old version was being deleted: read the new one
            pass
        finally:
            os.close(fd)
    raise CompileError(f"target_dir: {target_dir} kept changing while it was read")


def clear_cache():
    """Delete the compiled-library cache (``cache_dir()``) and all it holds; a missing one is fine."""
    shutil.rmtree(cache_dir(), ignore_errors=True)
