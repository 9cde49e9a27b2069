"""Issue 42: the commands on hostile logs and hostile output folders (tests/hostile_logs.py makes
each case): a clear one-line refusal with exit 2, naming what is wrong; no build line for a
design that failed; outputs written as a set, never over an input, checked before the work;
Ctrl-C and a closed pipe end with one line (130, 141)."""
import contextlib
import io
import json
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import hostile_logs as hostile
from codegen.cli import main
from conftest import ROOT

ROBOT = hostile.ROBOT
NOT_WRITABLE = Path("/proc/codegen-out")        # no new file here, even for root


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in argv])
    return status, out.getvalue(), err.getvalue()


def _one_line(err):
    """The last line of stderr (after progress bars), asserting no traceback."""
    assert "Traceback" not in err, err
    return err.strip().splitlines()[-1].split("\r")[-1]


# ------------------------------------------------------------------ design that failed
def test_design_on_a_too_short_log_exits_2_without_a_build_line(tmp_path):
    """0.2 s log: exit 0, "no candidate ran finite and stable", error inf and a build line. Now
    exit 2 and why: scoring starts at 0.6 s, with the length the log needs."""
    log = hostile.too_short(tmp_path)
    status, out, err = _run(["design", log, "--robot", ROBOT, "--family", "kalman_model",
                             "--json", tmp_path / "d.json"])
    line = _one_line(err)
    assert status == 2 and "build it" not in out and not (tmp_path / "d.json").exists()
    assert "too short: 0.2 s" in line and "scoring starts at 0.6 s" in line and "record at least 1.22 s" in line


def test_a_targets_file_tuned_on_a_too_short_log_is_refused(tmp_path):
    log = hostile.too_short(tmp_path)
    status, _, err = _run(["build", "-c", hostile.targets_file(tmp_path, log, "kalman_model"),
                           "--out", tmp_path / "gen"])
    assert status == 2 and "too short" in _one_line(err) and not (tmp_path / "gen").exists()


@pytest.mark.slow
@pytest.mark.parametrize("family, words", [("ii_speed", "stopped at sample"),
                                           ("reduced_order_nonlinear", "saturated")])
def test_a_failed_or_saturated_design_exits_2_without_a_build_line(tmp_path, family, words):
    """Torques x 3 (a wrong unit): ii_speed's run stops (ERR_NONFINITE_RESULT), reduced_order_nonlinear
    sits at its velocity bound on most samples; both printed a build line with exit 0."""
    log = hostile.torque_scaled(tmp_path)
    status, out, err = _run(["design", log, "--robot", ROBOT, "--family", family])
    assert status == 2 and "build it" not in out and words in _one_line(err), err[-500:]


# ------------------------------------------------------------------ crashes
@pytest.mark.parametrize("argv", [["design", "{log}", "--robot", ROBOT, "--family", "tomei"],
                                  ["design", "{log}", "--robot", ROBOT, "--family", "ciccarella_germani"],
                                  ["compare", "{log}", "--robot", ROBOT, "--observers", "tomei",
                                   "--baselines", "backward", "--out", "{tmp}/c"]])
def test_elastic_families_on_a_rigid_robot_refuse_in_one_line(tmp_path, argv):
    """Was an AttributeError traceback ('Planar2R' object has no attribute 'rigid')."""
    log = hostile.too_short(tmp_path)
    status, _, err = _run([a.format(log=log, tmp=tmp_path) for a in argv])
    line = _one_line(err)
    assert status == 2 and "needs an elastic robot" in line and "seed004_2r" in line


def test_a_nul_padded_csv_is_refused_naming_the_row(tmp_path):
    """Was a _csv.Error traceback (field larger than field limit), also through a targets file."""
    log = hostile.nul_padded(tmp_path)
    row = log.read_bytes().count(b"\n") + 1
    status, _, err = _run(["describe", log, "--robot", ROBOT])
    assert status == 2 and f"row {row}: not a CSV row" in _one_line(err)
    status, _, err = _run(["build", "-c", hostile.targets_file(tmp_path, log), "--out", tmp_path / "gen"])
    assert status == 2 and f"row {row}: not a CSV row" in _one_line(err)


def test_a_wild_sample_on_a_robot_without_limits_is_refused_naming_row_and_column(tmp_path):
    """q = 1e200 on seed000_2r: three numpy RuntimeWarnings and "noise: expected a finite real
    number, got inf"; now the reader's refusal, before any work."""
    log = hostile.wild_sample(tmp_path, row=4)
    status, _, err = _run(["compare", log, "--robot", ROBOT, "--out", tmp_path / "c"])
    line = _one_line(err)
    assert status == 2 and "RuntimeWarning" not in err
    assert "row 6, column 'q_q1': 1e+200 outside [-10000, 10000]" in line


@pytest.mark.parametrize("argv", [
    ["compare", "{log}", "--robot", ROBOT, "--out", str(NOT_WRITABLE)],
    ["identify", "{log}", "--robot", "ur5", "--out", str(NOT_WRITABLE)],
    ["design", "{log}", "--robot", ROBOT, "--family", "reduced_order", "--json", str(NOT_WRITABLE / "d.json")],
    ["describe", "{log}", "--json", str(NOT_WRITABLE / "d.json")]])
def test_an_unwritable_output_is_refused_before_the_work(tmp_path, argv):
    """A read-only --out / --json: PermissionError traceback after all the work; now one line
    before it (no clock line: the log was not even read)."""
    log = hostile.too_short(tmp_path)
    status, out, err = _run([a.format(log=log) for a in argv])
    assert status == 2 and out == "" and "cannot write" in _one_line(err) and "choose another" in err


# ------------------------------------------------------------------ Ctrl-C, a closed pipe
def _cli(*argv, **kw):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "codegen", *map(str, argv)], env=env, cwd=ROOT,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,   # a terminal's Ctrl-C:
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **kw)  # even under &


def test_ctrl_c_ends_with_one_line_and_status_130(tmp_path):
    log = hostile.clean(tmp_path)
    p = _cli("compare", log, "--robot", ROBOT, "--out", tmp_path / "c", stdout=subprocess.DEVNULL)
    time.sleep(6.0)                          # inside the work (imports, reading, tuning)
    os.killpg(p.pid, signal.SIGINT)          # the whole group, as a terminal sends it
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "interrupted" in _one_line(err), err[-800:]
    assert not (tmp_path / "c").exists()


def test_describe_into_a_closed_pipe_exits_141_quietly(tmp_path):
    log = hostile.clean(tmp_path, T=1.0)
    p = _cli("describe", log, stdout=subprocess.PIPE)
    p.stdout.close()                         # `| head` gone before the first line
    err = p.stderr.read()
    assert p.wait(timeout=60) == 141 and err == "", err


# ------------------------------------------------------------------ outputs as a set
COMPARE = ["--robot", ROBOT, "--observers", "reduced_order", "--baselines", "backward"]


def test_compare_never_overwrites_its_input_nor_a_users_file(tmp_path):
    """An input log named DIR/estimates.csv was destroyed by the run reading it; a user's
    compare.json in DIR silently overwritten. Both refused before the work, the files kept."""
    out = tmp_path / "out"
    log = hostile.clean(out, T=1.0, name="estimates.csv")
    before = log.read_bytes()
    status, stdout, err = _run(["compare", log, *COMPARE, "--out", out])
    assert status == 2 and "is the input" in _one_line(err) and stdout == "" and log.read_bytes() == before
    log = hostile.clean(tmp_path, T=1.0)
    (out / "estimates.csv").unlink()
    (out / "compare.json").write_text("mine\n")
    status, stdout, err = _run(["compare", log, *COMPARE, "--out", out])
    assert status == 2 and "was not written by this command" in _one_line(err)
    assert (out / "compare.json").read_text() == "mine\n"


@pytest.mark.slow
def test_compare_replaces_its_own_set(tmp_path):
    """A second compare into the same --out replaces the first's set (the manifest lists it); no
    temporary file is left."""
    log = hostile.clean(tmp_path, T=1.0)
    out = tmp_path / "out"
    for _ in range(2):
        status, _, err = _run(["compare", log, *COMPARE, "--out", out])
        assert status == 0, err
    names = {p.name for p in out.iterdir()}
    assert names == {"errors.png", "joint0.png", "estimates.csv", "compare.json", ".codegen-outputs.json"}
    files = json.loads((out / ".codegen-outputs.json").read_text())["files"]
    assert sorted(files) == sorted(names - {".codegen-outputs.json"})


def _write_set(folder, tag, names, rounds, q):
    from codegen.core.atomic import OutputSet
    errors = 0
    for k in range(rounds):
        try:
            with OutputSet(folder, names).writing() as tmp:
                for n in names:
                    (tmp / n).write_text(f"{tag} {k}\n")
                    time.sleep(0.002)
        except (ValueError, OSError):
            errors += 1
    q.put(errors)


def test_two_writers_into_one_folder_never_mix_their_sets(tmp_path):
    """Two compares into one --out left B's compare.json beside A's estimates.csv (2 of 9 tries):
    two processes writing sets into one folder; after each round the folder holds one writer's
    whole set, and neither fails."""
    names = ["errors.png", "estimates.csv", "compare.json"]
    folder = tmp_path / "out"
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    procs = [ctx.Process(target=_write_set, args=(folder, tag, names, 30, q)) for tag in "AB"]
    for p in procs:
        p.start()
    seen = set()
    while any(p.is_alive() for p in procs):
        from codegen.core.atomic import locked
        if folder.exists():
            with locked(folder):
                texts = {(folder / n).read_text() for n in names if (folder / n).exists()}
            assert len(texts) <= 1, texts
            seen |= texts
        time.sleep(0.001)
    for p in procs:
        p.join(timeout=60)
    assert [p.exitcode for p in procs] == [0, 0] and [q.get(timeout=5), q.get(timeout=5)] == [0, 0] and len({t[0] for t in seen}) == 2
    assert not [p for p in folder.iterdir() if p.name.startswith(".out.")]


def test_sigint_in_the_write_phase_leaves_the_old_set_or_the_new_one(tmp_path, monkeypatch):
    """SIGINT during compare's write phase cut errors.png to 124 bytes and left the rest missing.
    An interrupt while the files are written leaves the old set (and no temporary file); one that
    arrives while they move into place is held until the new set is whole."""
    from codegen.core.atomic import OutputSet
    names = ["errors.png", "estimates.csv", "compare.json"]
    folder = tmp_path / "out"
    with OutputSet(folder, names).writing() as tmp:
        for n in names:
            (tmp / n).write_text("old\n")
    with pytest.raises(KeyboardInterrupt):
        with OutputSet(folder, names).writing() as tmp:
            (tmp / names[0]).write_text("new but cut")
            os.kill(os.getpid(), signal.SIGINT)
    assert {(folder / n).read_text() for n in names} == {"old\n"}
    assert sorted(p.name for p in folder.iterdir()) == sorted(names + [".codegen-outputs.json"])
    real = os.replace

    def interrupted(a, b):                   # Ctrl-C as the first file moves into place
        os.kill(os.getpid(), signal.SIGINT)
        real(a, b)
    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        with OutputSet(folder, names).writing() as tmp:
            for n in names:
                (tmp / n).write_text("new\n")
    monkeypatch.setattr(os, "replace", real)
    assert {(folder / n).read_text() for n in names} == {"new\n"}


# ------------------------------------------------------------------ cases that held: kept
@pytest.mark.parametrize("make, words", hostile.HELD, ids=[m.__name__ for m, _ in hostile.HELD])
def test_a_bad_row_is_refused_naming_its_row_and_column(tmp_path, make, words):
    """Held before issue 42, kept: each reader refuses the log in one line naming what is wrong
    and where (describe and compare read it the same way)."""
    log = make(tmp_path)
    for argv in (["describe", log, "--robot", ROBOT], ["compare", log, *COMPARE, "--out", tmp_path / "c"]):
        status, out, err = _run(argv)
        assert status == 2 and words in _one_line(err), err
        assert not (tmp_path / "c").exists()


def test_identify_never_overwrites_a_users_report(tmp_path):
    """identify's --out held a user's report.txt: replaced without a word. Refused before the work
    (the log is not read); its own files of a previous run are listed in the folder's manifest."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.txt").write_text("mine\n")
    status, stdout, err = _run(["identify", hostile.too_short(tmp_path), "--robot", "ur5", "--out", out])
    assert status == 2 and "report.txt exists and was not written by this command" in _one_line(err)
    assert stdout == "" and (out / "report.txt").read_text() == "mine\n"
