"""Faults found under attack, each reproduced: colliding slot names, two processes
building one target, run() on error, rhs on NaN, a corrupt cached library."""
import ctypes as ct
import json
import multiprocessing as mp
import os
import re
import subprocess
import sys
import time

import numpy as np
import pytest

from codegen.families import observers
from codegen.pipeline.compile import compile_library
from codegen.pipeline.emit import emit
from codegen.pipeline.load import CompiledObserver, ObserverError, load
from conftest import ROOT
from models import load_robot
from urdf_chain import revolute_chain, write_chain

_D = ct.POINTER(ct.c_double)


def _defines(header):
    return re.findall(r"^#define (\w+) (\d+)$", header.read_text(), flags=re.M)


def test_slot_names_colliding_after_sanitising_get_unique_macros(tmp_path):
    """Joints x_2, x and x. sanitise to x_2, x, x: every slot macro is defined once, with its
    own index, and the header compiles with -Werror (a redefinition would warn)."""
    urdf = write_chain(tmp_path / "coll.urdf", revolute_chain(["x_2", "x", "x."]))
    spec = observers.build("reduced_order", load_robot(urdf=urdf))
    target = emit(spec, tmp_path / "t")
    P = target.name.upper()
    slots = [(m, int(v)) for m, v in _defines(target / f"{target.name}.h")
             if re.match(rf"{P}_(X|Y|U|P|EST)_", m)]
    names = [m for m, _ in slots]
    assert len(names) == len(set(names)), names
    for kind, n in (("Y", 3), ("U", 3), ("X", 3), ("EST", 3)):
        assert sorted(v for m, v in slots if m.startswith(f"{P}_{kind}_")) == list(range(n))
    assert dict(slots)[f"{P}_Y_Q_X_2"] == 0 and dict(slots)[f"{P}_Y_Q_X"] == 1
    assert compile_library(target, strict=True, cache=tmp_path / "cache").is_file()


# ------------------------------------------------------------------ two processes, one target
def monkey_sleep_after(module, name, seconds):
    """Make ``module.name`` sleep ``seconds`` after each call (in a child process only)."""
    real = getattr(module, name)

    def slow(*args, **kwargs):
        result = real(*args, **kwargs)
        time.sleep(seconds)
        return result
    setattr(module, name, slow)


def _hammer(mode, spec, out, cache, rounds, done, q):
    """``emit``: rounds of emit + build + load; ``build``: build + load (and an emit every 8th
    round) until ``done`` is set. Puts (rounds done, errors) on q."""
    errors, k = [], 0
    folder = out / spec.target().prefix
    for name in ("replace", "rename"):   # widen any window between two renames (a busy machine)
        monkey_sleep_after(os, name, 0.003)
    while (k < rounds) if mode == "emit" else not done.is_set():
        try:
            if mode == "emit" or k % 8 == 7:
                folder = emit(spec, out)
            obs = load(folder, compile_library(folder, cache=cache))
            assert obs.prefix == folder.name
        except Exception as e:  # reported by the parent
            errors.append(f"{type(e).__name__}: {e}")
        k += 1
    if mode == "emit":
        done.set()
    q.put((mode, k, errors))


def test_two_processes_building_the_same_target(spec_of, tmp_path):
    """Two processes emit, build and load one target at once: neither ever finds the folder
    absent or half-swapped (emit exchanges the folders atomically; build reads one snapshot)."""
    spec = spec_of("seed000_2r")
    out, cache = tmp_path / "out", tmp_path / "cache"
    compile_library(emit(spec, out), cache=cache)
    ctx = mp.get_context("fork")
    done, q = ctx.Event(), ctx.Queue()
    procs = [ctx.Process(target=_hammer, args=(m, spec, out, cache, 40, done, q))
             for m in ("emit", "build")]
    for p in procs:
        p.start()
    results = {m: (k, errors) for m, k, errors in (q.get(timeout=300) for _ in procs)}
    for p in procs:
        p.join()
    assert results["emit"][0] == 40 and results["build"][0] >= 40, results
    errors = results["emit"][1] + results["build"][1]
    assert not errors, f"{len(errors)} failures, first: {errors[:3]}"
    assert sorted(p.name for p in out.iterdir()) == [spec.target().prefix]   # no leftovers


def test_load_reads_the_metadata_that_was_built(spec_of, tmp_path):
    """The library is loaded with the metadata JSON it was compiled with, even if the folder
    was regenerated (another dt) in between."""
    spec = spec_of("seed000_2r")
    folder = emit(spec.target(dt=1e-3), tmp_path / "t", spec=spec)
    lib = compile_library(folder, cache=tmp_path / "cache")
    emit(spec.target(dt=2e-3), tmp_path / "t", spec=spec)
    assert json.loads((folder / f"{folder.name}.json").read_text())["discretization"]["dt"] == 2e-3
    assert load(folder, lib).dt == 1e-3


# ------------------------------------------------------------------ run() and rhs on error
def test_run_failing_at_sample_k_rolls_the_state_back(compiled, spec_of):
    """A sample k > 0 fails: the C run restores the state it had at entry (x, last y and u),
    as docs/guide/reliability.md and ObserverError say, and reports k."""
    obs = compiled("seed000_2r")
    obs.reset([0.1, 0.2])
    for _ in range(3):
        obs.step([0.1, 0.2], [1.0, -1.0])
    x0 = obs.state
    expected_next = obs.estimate([0.15, 0.25], [0.5, 0.5])
    Y = np.full((6, 2), 0.3)
    Y[4] = 1e306                                   # x2hat = z + k0 y overflows at sample 4
    with pytest.raises(ObserverError, match=r"sample 4 .*ERR_NONFINITE_RESULT.*state rolled back"):
        obs.run(Y, np.zeros((6, 2)))
    assert np.array_equal(obs.state, x0)
    assert np.array_equal(obs.estimate([0.15, 0.25], [0.5, 0.5]), expected_next)  # y_prev, u_prev too
    done = ct.c_long(-1)
    EST = np.zeros((6, 2))
    st = obs._run(obs._s, 6, Y.ctypes.data_as(_D), np.zeros((6, 2)).ctypes.data_as(_D),
                  EST.ctypes.data_as(_D), ct.byref(done))
    assert st == obs.meta["status"]["ERR_NONFINITE_RESULT"] and done.value == 4
    assert np.array_equal(obs.state, x0)


def test_rhs_refuses_non_finite_input_in_c(compiled):
    obs = compiled("seed000_2r")
    st = obs.meta["status"]
    obs.reset([0.0, 0.0])

    def c_rhs(x, y, u):
        bufs = [np.asarray(a, dtype=float) for a in (x, y, u, np.zeros(2))]
        return obs._rhs(obs._s, *(b.ctypes.data_as(_D) for b in bufs)), bufs[-1]
    status, xdot = c_rhs([0.1, 0.2], [0.0, 0.1], [1.0, 2.0])
    assert status == st["OK"] and np.all(np.isfinite(xdot))
    for bad in ([np.nan, 0.0], [0.0, np.inf]):
        assert c_rhs(bad, [0.0, 0.1], [1.0, 2.0])[0] == st["ERR_NONFINITE_INPUT"]
        assert c_rhs([0.1, 0.2], bad, [1.0, 2.0])[0] == st["ERR_NONFINITE_INPUT"]
        assert c_rhs([0.1, 0.2], [0.0, 0.1], bad)[0] == st["ERR_NONFINITE_INPUT"]
    # the model sees the velocity estimate within its bound (a finite xdot for z = 1e300), but
    # -k0 x2hat overflows for z near the largest double: a non-finite result, reported
    assert c_rhs([1e300, -1e300], [0.1, 0.2], [0.0, 0.0])[0] == st["OK"]
    assert c_rhs([1.7e308, -1.7e308], [0.1, 0.2], [0.0, 0.0])[0] == st["ERR_NONFINITE_RESULT"]
    with pytest.raises(ObserverError, match="ERR_NONFINITE_RESULT"):
        obs.rhs([1.7e308, -1.7e308], [0.1, 0.2], [0.0, 0.0])


# ------------------------------------------------------------------ corrupt cache
def test_corrupt_cached_library_is_rebuilt_or_refused(spec_of, tmp_path):
    """A truncated library in the cache is never mapped (that is a SIGBUS): compile_library() verifies
    size and sha256 recorded at build time and rebuilds it; loading it refuses clearly."""
    folder = emit(spec_of("seed000_2r"), tmp_path / "t")
    lib = compile_library(folder, cache=tmp_path / "cache")
    good = lib.read_bytes()
    meta = json.loads((folder / f"{folder.name}.json").read_text())
    lib.write_bytes(good[: len(good) // 2])
    code = (f"import json, sys; from codegen.pipeline.load import CompiledObserver\n"
            f"try:\n    CompiledObserver({str(lib)!r}, json.loads({json.dumps(json.dumps(meta))}))\n"
            f"except Exception as e:\n    print(type(e).__name__, e); sys.exit(7)\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 7, (r.returncode, r.stdout, r.stderr)      # an error, not a signal
    assert "corrupt" in r.stdout and lib.name in r.stdout
    assert compile_library(folder, cache=tmp_path / "cache") == lib and lib.read_bytes() == good
    obs = CompiledObserver(lib, meta)
    obs.reset([0.0, 0.0])
    assert np.all(np.isfinite(obs.step([0.1, 0.2], [0.0, 0.0])))
