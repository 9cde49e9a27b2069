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
