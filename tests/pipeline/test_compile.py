"""Build: the toolchain of codegen.pipeline.compile (compiler lookup, flags, content-hash cache, compiler
messages) and the generated folder's own Makefile and CMakeLists.txt."""
import shutil

import pytest

from codegen.pipeline.compile import CompileError, compile_library, c_flags, cached_compile, compiler
from codegen.pipeline.emit import emit


@pytest.mark.parametrize("name", ["seed000_2r", "ur5"])
def test_strict_c99_compile(name, spec_of, tmp_path):
    """The emitted C compiles with -std=c99 -Wall -Wextra -Werror -pedantic."""
    target = emit(spec_of(name), tmp_path / "t")
    lib = compile_library(target, strict=True, cache=tmp_path / "cache")
    assert lib.exists()


def test_compile_error_shows_compiler_message(spec_of, tmp_path):
    target = emit(spec_of("seed000_2r"), tmp_path / "t")
    c = target / f"{target.name}.c"
    c.write_text(c.read_text() + "\nint broken( {\n")
    with pytest.raises(CompileError) as e:
        compile_library(target, cache=tmp_path / "cache")
    assert f"{target.name}.c" in str(e.value) and "error" in str(e.value)


def test_generated_folder_builds_standalone(spec_of, tmp_path):
    """What an embedded user does: no Python, just the folder's Makefile or CMakeLists.txt."""
    import subprocess
    target = emit(spec_of("seed000_2r"), tmp_path)
    for goal in ("all", "shared"):    # static by default; the host's shared library on request
        r = subprocess.run(["make", "-C", str(target), goal], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    assert (target / f"lib{target.name}.a").exists() and (target / f"lib{target.name}.so").exists()
    if shutil.which("cmake"):
        b = tmp_path / "cmake-build"
        for cmd in (["cmake", "-S", str(target), "-B", str(b)], ["cmake", "--build", str(b)]):
            r = subprocess.run(cmd, capture_output=True, text=True)
            assert r.returncode == 0, r.stdout + r.stderr
        assert (b / f"lib{target.name}.a").exists()


def test_missing_compiler_is_a_clear_build_error(monkeypatch):
    with pytest.raises(CompileError, match="compiler 'no-such-cc-h3' not found on PATH"):
        compiler("no-such-cc-h3")
    monkeypatch.setenv("CC", "no-such-cc-from-env")
    with pytest.raises(CompileError, match="no-such-cc-from-env"):
        compiler()
    assert compiler("gcc").path == shutil.which("gcc") and compiler("gcc").version


def test_cached_build_compiles_once_per_content(tmp_path):
    """The same bytes, key and products are compiled once; other bytes get another folder; a failed
    compile leaves nothing in the cache and shows the source folder, not the private copy."""
    tool, calls = compiler(), []

    def commands(work, out):
        calls.append(work)
        yield [tool.path, *c_flags(shared=True, strict=True), "-o", out / "libf.so", work / "f.c"], "compiling f.c"

    files = {"f.c": b"int f(void) { return 1; }\n"}
    first = cached_compile("f", [tool, "k"], files, ["libf.so"], commands, tmp_path)
    assert (first / "libf.so").is_file() and not (first / ".work").exists()
    assert cached_compile("f", [tool, "k"], files, ["libf.so"], commands, tmp_path) == first
    assert len(calls) == 1
    other = cached_compile("f", [tool, "k"], {"f.c": b"int f(void) { return 2; }\n"}, ["libf.so"],
                         commands, tmp_path)
    assert other != first and len(calls) == 2
    with pytest.raises(CompileError, match="compiling f.c failed") as e:
        cached_compile("f", [tool, "k"], {"f.c": b"int f(void) { return }\n"}, ["libf.so"], commands,
                     tmp_path, shown="/somewhere/src")
    assert e.value.returncode != 0 and "error" in e.value.stderr
    assert "/somewhere/src/f.c" in str(e.value) and str(calls[-1]) not in str(e.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([first.name, other.name])


def test_build_is_cached_by_content(spec_of, tmp_path):
    target = emit(spec_of("seed000_2r"), tmp_path / "t")
    lib = compile_library(target, cache=tmp_path / "cache")
    mtime = lib.stat().st_mtime_ns
    assert compile_library(target, cache=tmp_path / "cache") == lib and lib.stat().st_mtime_ns == mtime
    assert compile_library(target, cache=tmp_path / "cache", extra_flags=["-O1"]) != lib


def test_cli_and_python_share_one_library(tmp_path):
    """`build seed000_2r` (a catalog target) and compile_observer of the same observer designed in
    Python differ only in how the target is named (the metadata's "target" record): one library,
    not a second compile."""
    from codegen import compile_observer, observers
    from codegen.pipeline.stages import make
    from codegen.pipeline.targets_file import make_target
    from models import load_robot
    target, _ = make_target({"robot": "seed000_2r", "family": "reduced_order"})
    made = make(target, tmp_path / "generated")
    obs = compile_observer(observers.build("reduced_order", load_robot("seed000_2r")), dt=1e-3,
                           out_dir=tmp_path / "python")
    assert obs.lib_path == made.lib.resolve()


# ------------------------------------------------------------------ the cache's build record
_LOAD = ("import json, sys\nfrom codegen.pipeline.load import CompiledObserver\n"
         "try:\n    CompiledObserver(sys.argv[1], json.loads(sys.argv[2]))\n"
         "except Exception as e:\n    print(type(e).__name__, e); sys.exit(7)\n")


def _load_in_child(lib, meta):
    """Load ``lib`` with ``meta`` in a child process: (exit code, stdout); a signal (SIGBUS on a
    truncated library) is a negative code."""
    import json
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-c", _LOAD, str(lib), json.dumps(meta)], capture_output=True, text=True)
    return r.returncode, r.stdout


def _built(spec_of, tmp_path):
    import json
    folder = emit(spec_of("seed000_2r"), tmp_path / "t")
    lib = compile_library(folder, cache=tmp_path / "cache")
    return folder, lib, json.loads((folder / f"{folder.name}.json").read_text()), lib.read_bytes()


@pytest.mark.parametrize("record", ["entry deleted", "manifest deleted"])
def test_unrecorded_library_is_never_mapped(record, spec_of, tmp_path):
    """Issue 22, F15: a truncated cached library whose manifest entry (or whole manifest) was
    deleted was mapped unchecked (SIGBUS). A file the build record does not list is not trusted:
    loading it is one line naming it, and compile_library() rebuilds it."""
    import json

    from codegen.pipeline.compile import MANIFEST
    folder, lib, meta, good = _built(spec_of, tmp_path)
    lib.write_bytes(good[: len(good) // 2])
    manifest = lib.parent / MANIFEST
    if record == "manifest deleted":
        manifest.unlink()
    else:
        m = json.loads(manifest.read_text())
        del m[lib.name]
        manifest.write_text(json.dumps(m))
    code, out = _load_in_child(lib, meta)
    assert code == 7, (code, out)                        # an error, not a signal
    assert "unverified" in out and lib.name in out and "compile_library() rebuilds it" in out
    assert len(out.strip().splitlines()) == 1
    assert compile_library(folder, cache=tmp_path / "cache") == lib and lib.read_bytes() == good
    assert _load_in_child(lib, meta)[0] == 0


def test_corrupt_manifest_is_reported_and_repaired(spec_of, tmp_path):
    """Issue 22, F17: a manifest ``{"lib<prefix>.so": 5}`` raised TypeError from both the loader
    and compile_library(). Now the loader refuses in one line, and the build rebuilds the folder."""
    import json

    from codegen.pipeline.compile import MANIFEST, verify
    folder, lib, meta, good = _built(spec_of, tmp_path)
    (lib.parent / MANIFEST).write_text(json.dumps({lib.name: 5}))
    with pytest.raises(CompileError, match=f"{lib.name} is corrupt or unverified: its build record .* is corrupt"):
        verify(lib)
    code, out = _load_in_child(lib, meta)
    assert code == 7 and "CompileError" in out and len(out.strip().splitlines()) == 1, (code, out)
    assert compile_library(folder, cache=tmp_path / "cache") == lib
    m = json.loads((lib.parent / MANIFEST).read_text())
    assert m[lib.name]["size"] == len(good) and verify(lib) == lib
    assert _load_in_child(lib, meta)[0] == 0
