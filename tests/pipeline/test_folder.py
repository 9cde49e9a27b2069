"""The generated folder and what writes it (codegen.pipeline.emit, codegen.core.atomic): names a
folder can carry, --force that replaces only what this tool generated, one writer per folder at
a time, one-line errors for a full disk or a missing permission with nothing half-written, the
licence, version and fingerprint it carries, and the CMake route building the bits the
verified compile builds."""
import errno
import json
import multiprocessing
import os
import pathlib
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from codegen.pipeline.compile import compile_library
from codegen.pipeline.emit import FolderTaken, emit
from codegen.pipeline.targets_file import build_spec, make_target
from test_cli import run, workdir  # noqa: F401  (the CLI runner; each test in its own working folder)

CHEAP = ["seed002_2r", "--family", "su_nonsmooth"]        # no design, a small kernel


def one_line(err, *words):
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def cheap(**over):
    """The su_nonsmooth target of seed002_2r (no design, a small kernel) and its spec."""
    target, _ = make_target({"robot": "seed002_2r", "family": "su_nonsmooth", "substeps": 1, **over})
    return target, build_spec(target)


# ------------------------------------------------------------------------------------ names
@pytest.mark.parametrize("name", ["all", "install", "help", "clean", "m"])
def test_names_cmake_cannot_build_are_refused_at_once(capsys, workdir, name):
    """F10: CMake refuses a target named all, install, help (reserved) and m ("links to
    itself": the library the build links); refused before anything is written."""
    code, _, err = run(capsys, "build", *CHEAP, "--name", name, "--out", "g")
    assert code == 2
    one_line(err, repr(name), "--name")
    assert not (workdir / "g").exists()


def test_a_name_too_long_is_refused_with_the_limit(capsys, workdir):
    """F11: a 250-character --name: one line stating the limit (no ENAMETOOLONG traceback)."""
    code, _, err = run(capsys, "build", *CHEAP, "--name", "a" * 250, "--out", "g")
    assert code == 2
    line = one_line(err, "250 characters", "--name")
    assert re.search(r"at most \d+", line)
    assert not (workdir / "g").exists()


def test_the_longest_name_allowed_builds(capsys, workdir):
    """The limit is one a folder can carry: a name of exactly that length builds and compiles."""
    from codegen.core.target import MAX_PREFIX
    code, _, err = run(capsys, "build", *CHEAP, "--name", "a" * MAX_PREFIX, "--out", "g")
    assert code == 0, err
    assert (workdir / "g" / ("a" * MAX_PREFIX) / f"{'a' * MAX_PREFIX}.json").exists()


# ------------------------------------------------------------------------------------ --force
def test_force_never_deletes_a_users_folder(capsys, workdir):
    """F12: --force onto a folder without this tool's metadata is refused and nothing is
    deleted; a folder this tool generated is still replaced."""
    photos = workdir / "D" / "photos"
    photos.mkdir(parents=True)
    (photos / "wedding.jpg").write_text("x")
    code, _, err = run(capsys, "build", *CHEAP, "--name", "photos", "--out", "D", "--force")
    assert code == 2
    one_line(err, str(photos), "not a generated target", "--force")
    assert sorted(p.name for p in photos.iterdir()) == ["wedding.jpg"]
    assert (photos / "wedding.jpg").read_text() == "x"
    assert sorted(p.name for p in (workdir / "D").iterdir()) == ["photos"]     # no temporaries
    # a generated folder is replaced by --force (another target)
    code, _, err = run(capsys, "build", *CHEAP, "--name", "mine", "--out", "D")
    assert code == 0, err
    code, _, err = run(capsys, "build", *CHEAP, "--name", "mine", "--out", "D", "--dt", "5e-4", "--force")
    assert code == 0, err
    meta = json.loads((workdir / "D" / "mine" / "mine.json").read_text())
    assert meta["target"]["discretization"]["dt"] == 5e-4 and meta["generator"]["tool"] == "observer-codegen"


def test_force_never_replaces_json_that_is_not_ours(workdir):
    """A folder whose <name>.json is not this tool's metadata (another program's, or none
    naming the generator) is not a generated folder: refused, kept."""
    target, spec = cheap(name="data")
    folder = workdir / "data"
    folder.mkdir()
    (folder / "data.json").write_text(json.dumps({"prefix": "data", "target": {}, "rows": [1, 2]}))
    with pytest.raises(FolderTaken, match="not a generated target"):
        emit(target, workdir, spec=spec, force=True)
    assert sorted(p.name for p in folder.iterdir()) == ["data.json"]


@pytest.mark.parametrize("kind", ["file", "symlink"])
def test_force_onto_a_file_or_a_symlink_is_one_line(capsys, workdir, kind):
    """F13: --force onto a file or a symbolic link: one line, both left as they were."""
    out = workdir / "D"
    out.mkdir()
    (workdir / "elsewhere").mkdir()
    path = out / "thing"
    if kind == "file":
        path.write_text("keep me")
    else:
        path.symlink_to(workdir / "elsewhere")
    code, _, err = run(capsys, "build", *CHEAP, "--name", "thing", "--out", "D", "--force")
    assert code == 2
    one_line(err, str(path), "a file" if kind == "file" else "a symbolic link")
    if kind == "file":
        assert path.read_text() == "keep me"
    else:
        assert path.is_symlink() and os.readlink(path) == str(workdir / "elsewhere")
    assert sorted(p.name for p in out.iterdir()) == ["thing"]
    assert list((workdir / "elsewhere").iterdir()) == []


# ------------------------------------------------------------------------------------ writers
def _emit_after(barrier, target, spec, out, results):
    barrier.wait()
    try:
        emit(target, out, spec=spec, force=False)
        results.put((target.family, "ok"))
    except FolderTaken as e:
        results.put((target.family, str(e)))


def test_two_writers_of_one_folder_do_not_both_succeed(tmp_path):
    """F14: two processes emit different targets into one --out/--name at the same moment,
    without force (both pass the early check: the folder is absent): exactly one writes, the
    other gets FolderTaken, and the folder holds the winner's target whole."""
    a, spec_a = cheap(name="clash")
    b, spec_b = cheap(name="clash", dt=5e-4)
    ctx = multiprocessing.get_context("fork")
    for attempt in range(3):
        out = tmp_path / f"run{attempt}"
        barrier, results = ctx.Barrier(2), ctx.Queue()
        procs = [ctx.Process(target=_emit_after, args=(barrier, t, s, out, results))
                 for t, s in ((a, spec_a), (b, spec_b))]
        for p in procs:
            p.start()
        for p in procs:
            p.join(60)
        got = [results.get(timeout=5) for _ in procs]
        wins = [r for r in got if r[1] == "ok"]
        assert len(wins) == 1, got
        assert "holds another target" in next(r[1] for r in got if r[1] != "ok")
        meta = json.loads((out / "clash" / "clash.json").read_text())
        winner = a if meta["target"]["discretization"]["dt"] == a.discretization.dt else b
        assert meta["target"] == json.loads(json.dumps(winner.to_dict()))
        assert sorted(p.name for p in out.iterdir()) == ["clash"]      # no temporaries left


def test_a_concurrent_writer_between_check_and_swap_is_caught(tmp_path, monkeypatch):
    """The check is repeated under the lock at the swap (compare-and-swap): a folder of another
    target written after the early check is not replaced without force."""
    import codegen.pipeline.emit as emit_module
    a, spec_a = cheap(name="cas")
    b, spec_b = cheap(name="cas", dt=5e-4)
    real = emit_module.locked

    def competitor_first(folder):
        monkeypatch.setattr(emit_module, "locked", real)
        emit(a, tmp_path, spec=spec_a, force=False)          # finishes while b is writing
        return real(folder)

    monkeypatch.setattr(emit_module, "locked", competitor_first)
    with pytest.raises(FolderTaken, match="holds another target"):
        emit(b, tmp_path, spec=spec_b, force=False)
    meta = json.loads((tmp_path / "cas" / "cas.json").read_text())
    assert meta["target"]["discretization"]["dt"] == a.discretization.dt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cas"]


def test_a_forced_build_swapped_out_before_its_compile_says_so(tmp_path, monkeypatch):
    """Two --force builds of different targets into one folder: the last writer wins, and the
    build whose folder was replaced before it compiled says so rather than return the other
    target's library as its own."""
    import codegen.pipeline.stages as stages
    a, spec_a = cheap(name="swap")
    b, spec_b = cheap(name="swap", dt=5e-4)
    real = stages.compile_library

    def other_writer_first(folder, **kw):
        emit(b, tmp_path, spec=spec_b, force=True)
        return real(folder, **kw)

    monkeypatch.setattr(stages, "compile_library", other_writer_first)
    with pytest.raises(FolderTaken, match="replaced by another build"):
        stages.make(a, tmp_path, spec=spec_a, force=True)


# ------------------------------------------------------------------------------------ disk
def _failing(method, name_part, code):
    """``pathlib.Path.<method>`` raising OSError(code) for a path containing ``name_part``."""
    real = getattr(pathlib.Path, method)

    def fail(self, *args, **kwargs):
        if name_part in str(self):
            raise OSError(code, os.strerror(code))
        return real(self, *args, **kwargs)
    return fail


@pytest.mark.parametrize("code, fix", [(errno.ENOSPC, "free space"), (errno.EACCES, "make it writable")])
def test_a_full_disk_or_no_permission_is_one_line_and_nothing_half_written(
        capsys, workdir, monkeypatch, code, fix):
    """F18: the folder's last file cannot be written (ENOSPC, EACCES): one line naming the
    folder and the fix; no folder, no temporary, not even the --out folder the build made."""
    monkeypatch.setattr(pathlib.Path, "write_text", _failing("write_text", ".json", code))
    out = workdir / "new" / "out"
    ret, _, err = run(capsys, "build", *CHEAP, "--out", out)
    assert ret == 2
    one_line(err, str(out / "seed002_2r_su_nonsmooth"), os.strerror(code), fix, "--out")
    assert sorted(p.name for p in workdir.iterdir()) == []


def test_a_full_disk_under_casadi_is_one_line(capsys, workdir, monkeypatch):
    """F18: CasADi reports no failed write: on a full disk it leaves its kernels truncated. That
    is one line naming the folder and the fix, not "no casadi_real definition block"."""
    import casadi as ca
    real = ca.CodeGenerator.generate

    def truncated(self, prefix):
        name = real(self, prefix)
        for f in Path(prefix).glob("*_kernels.[ch]"):
            f.write_bytes(f.read_bytes()[:4096])
        return name

    class Full:
        f_bavail, f_frsize = 0, 4096
    monkeypatch.setattr(ca.CodeGenerator, "generate", truncated)
    monkeypatch.setattr(os, "statvfs", lambda path: Full)
    ret, _, err = run(capsys, "build", *CHEAP, "--out", "out")
    assert ret == 2
    one_line(err, str(workdir / "out" / "seed002_2r_su_nonsmooth"), "No space left on device", "free space")
    assert sorted(p.name for p in workdir.iterdir()) == []


def test_a_full_cache_is_one_line_naming_the_cache(capsys, workdir, monkeypatch):
    """F18: the compile cache cannot be written: one line naming the cache folder and
    CODEGEN_CACHE; nothing of the attempt is left in the cache."""
    cache = workdir / "cache"
    monkeypatch.setenv("CODEGEN_CACHE", str(cache))
    monkeypatch.setattr(pathlib.Path, "write_bytes", _failing("write_bytes", str(cache), errno.ENOSPC))
    ret, _, err = run(capsys, "build", *CHEAP, "--out", "g")
    assert ret == 2
    one_line(err, str(cache / "seed002_2r_su_nonsmooth-"), "No space left on device", "CODEGEN_CACHE")
    assert not [p for p in cache.iterdir() if p.name.startswith(("seed002", ".seed002"))]


# ------------------------------------------------------------------------------------ contents
def test_the_folder_carries_licence_version_and_fingerprint(tmp_path):
    """Issue 24: a LICENSE (the generated C is the user's without restriction; CasADi's notice
    quoted from the kernels it wrote), <P>_VERSION and <P>_FINGERPRINT in the header, the same
    fingerprint in the metadata, changing with the target and stable for the same one."""
    from codegen.core.version import __version__
    from codegen.pipeline.emit import fingerprint
    target, spec = cheap(name="lic")
    folder = emit(target, tmp_path / "a", spec=spec)
    meta = json.loads((folder / "lic.json").read_text())
    assert meta["fingerprint"] == fingerprint(meta) and re.fullmatch(r"[0-9a-f]{16}", meta["fingerprint"])
    header = (folder / "lic.h").read_text()
    assert f'#define LIC_VERSION "{__version__}"' in header
    assert f'#define LIC_FINGERPRINT "{meta["fingerprint"]}"' in header
    licence = (folder / "LICENSE").read_text()
    assert "without restriction" in licence and meta["fingerprint"] in licence
    kernels = (folder / "lic_kernels.c").read_text()
    notice = kernels[:kernels.index("*/") + 2]
    assert notice.startswith("/* This file was automatically generated by CasADi") and notice in licence
    again = emit(target, tmp_path / "b", spec=spec)
    assert json.loads((again / "lic.json").read_text())["fingerprint"] == meta["fingerprint"]
    other, other_spec = cheap(name="lic", dt=5e-4)
    moved = emit(other, tmp_path / "c", spec=other_spec)
    assert json.loads((moved / "lic.json").read_text())["fingerprint"] != meta["fingerprint"]
    # the macros compile and read back in C
    main = tmp_path / "main.c"
    main.write_text('#include <stdio.h>\n#include "lic.h"\nint main(void) {\n'
                    '  printf("%s %s %d\\n", LIC_VERSION, LIC_FINGERPRINT, LIC_VERSION_MAJOR);\n  return 0;\n}\n')
    subprocess.run(["gcc", "-std=c99", "-I", str(folder), "-o", str(tmp_path / "main"), str(main)], check=True)
    got = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True, check=True).stdout.split()
    assert got == [__version__, meta["fingerprint"], __version__.split(".")[0]]


@pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake not installed")
def test_cmake_installs_the_metadata_and_the_licence(tmp_path):
    """Issue 24: `cmake --install` puts <prefix>.json and LICENSE in share/<prefix>/."""
    target, spec = cheap(name="inst")
    folder = emit(target, tmp_path / "gen", spec=spec)
    for cmd in (["-S", folder, "-B", tmp_path / "b"], ["--build", tmp_path / "b"],
                ["--install", tmp_path / "b", "--prefix", tmp_path / "p"]):
        r = subprocess.run(["cmake", *map(str, cmd)], capture_output=True, text=True)
        assert r.returncode == 0, r.stdout + r.stderr
    share = tmp_path / "p" / "share" / "inst"
    assert (share / "inst.json").read_bytes() == (folder / "inst.json").read_bytes()
    assert (share / "LICENSE").read_bytes() == (folder / "LICENSE").read_bytes()


def _fma():
    """The host CPU has fused multiply-add (the flag that lets gcc contract a*b+c)."""
    try:
        return " fma " in Path("/proc/cpuinfo").read_text().replace("\n", " ")
    except OSError:
        return False


@pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("make") is None,
                    reason="cmake or make not installed")
def test_cmake_and_makefile_build_the_verified_bits(spec_of, tmp_path):
    """The deliverable is what was verified: the folder built by its CMakeLists.txt (default
    configuration: Release; and Release asked for) and by its Makefile (CFLAGS overridden as a
    cross-compile does, in GNU C) gives the estimates of the verified compile (compile_library)
    bit for bit over 300 steps, on a CPU with FMA (-mfma on all: in GNU C gcc fuses a*b+c, as
    it would for a Cortex-M4F)."""
    from codegen.pipeline.load import load
    from codegen.verify.inputs import trajectory_inputs
    spec = spec_of("seed000_2r")
    folder = emit(spec, tmp_path / "gen")
    cpu = " ".join(["-mfma"] if _fma() else [])
    libs = {"verified": compile_library(folder, extra_flags=cpu.split(), cache=tmp_path / "cache")}
    for config in ("default", "Release"):
        b = tmp_path / f"cmake-{config}"
        chosen = [] if config == "default" else [f"-DCMAKE_BUILD_TYPE={config}"]
        for cmd in (["cmake", "-S", folder, "-B", b, "-DBUILD_SHARED_LIBS=ON", f"-DCMAKE_C_FLAGS={cpu}", *chosen],
                    ["cmake", "--build", b]):
            r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
            assert r.returncode == 0, r.stdout + r.stderr
        libs[f"cmake {config}"] = b / f"lib{folder.name}.so"
    assert "CMAKE_BUILD_TYPE:STRING=Release" in (tmp_path / "cmake-default" / "CMakeCache.txt").read_text()
    r = subprocess.run(["make", "-C", str(folder), "shared", f"CFLAGS=-O3 -std=gnu99 {cpu}"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    libs["make"] = folder / f"lib{folder.name}.so"
    run = trajectory_inputs(spec, 300, 1e-3)
    est = {}
    for route, lib in libs.items():
        obs = load(folder, lib)
        obs.reset(run.Y[0])
        est[route] = obs.run(run.Y, run.U).view(np.int64)
    assert np.all(np.isfinite(est["verified"].view(np.float64)))
    ulps = {route: int(np.abs(e - est["verified"]).max()) for route, e in est.items()}
    assert set(ulps.values()) == {0}, f"largest difference to the verified build, in ulp: {ulps}"


def test_compile_observer_keeps_a_folder_per_target(tmp_path, monkeypatch):
    """Two targets under one prefix (two methods here; a float and a double build alike) compiled
    by compile_observer get a folder each under build/targets: neither replaces the other's, so
    two processes or test workers building them at once cannot swap a folder mid-build (it raised
    FolderTaken, 'replaced by another build while this one compiled it'); the same target again
    reuses its folder."""
    from codegen import compile_observer
    from codegen.families import observers
    from models import load_robot
    monkeypatch.setenv("CODEGEN_BUILD", str(tmp_path))
    spec = observers.build("reduced_order", load_robot("seed000_2r"))
    est = [compile_observer(spec, method=m, prefix="same").run(np.full((5, 2), 0.1), np.zeros((5, 2)))
           for m in ("rk4", "expmid")]
    folders = sorted((tmp_path / "targets").glob("*/same"))
    assert len(folders) == 2 and all(np.all(np.isfinite(e)) for e in est)
    assert {json.loads((f / "same.json").read_text())["target"]["discretization"]["method"]
            for f in folders} == {"rk4", "expmid"}
    compile_observer(spec, method="rk4", prefix="same")
    assert sorted((tmp_path / "targets").glob("*/same")) == folders
