"""Sweeps: the plan, results identical on Dask and in-process, nothing lost when the
client or a worker is killed. Small: the 2R of seed 000 on our model, T = 0.5 s."""
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from codegen.evaluate import sweep
from codegen.evaluate.sweep import maps, plan
from codegen.evaluate.sweep.store import Store

ROOT = Path(__file__).resolve().parents[2]
SMALL = {"name": "small", "robot": "seed000_2r", "plant": "model", "T": 0.5,
         "observers": ["reduced_order"], "baselines": ["backward", "butterworth"], "batch": 4,
         "axes": {"k0": {"log": [2, 200, 4]}, "noise": [0, 1e-4], "seed": [0, 1]}}


def _rows(out):
    return Store(out).read().drop(columns=["worker", "cpu_s"])      # where and how long: not results


def _once(out, res):
    ids = Store(out).read()["cell"]
    assert ids.is_unique
    assert len(ids) == res.cells


def test_plan_cells_and_ids():
    cfg = {**SMALL, "axes": {**SMALL["axes"], "est0": {"uniform": [-0.1, 0.1]}}, "samples": 3}
    s = plan.load(cfg)
    m = [plan.Method("reduced_order", "observer", "reduced_order", {}, ("k0",)),
         plan.Method("backward", "baseline", "backward", {})]
    cells = plan.cells(s, m, lambda method, point: {"k0": 16.0})
    obs = [c for c in cells if c["kind"] == "observer"]
    assert len(obs) == 4 * 2 * 2 * 3                      # grid x samples
    assert len(cells) - len(obs) == 2 * 2                 # a baseline ignores k0 and est0: one cell
    assert len({c["cell"] for c in cells}) == len(cells)
    again = plan.cells(plan.load(cfg), m, lambda method, point: {"k0": 16.0})
    assert [c["cell"] for c in again] == [c["cell"] for c in cells]      # stable ids, same draws
    assert {c["p"]["k0"] for c in obs} == set(s.axes["k0"])
    assert all(-0.1 <= c["est0"] < 0.1 for c in obs)
    # a sweep whose gain axis no observer has is refused, naming the axis
    with pytest.raises(ValueError, match="axes.kp"):
        plan.cells(plan.load({**SMALL, "axes": {"kp": [1.0]}}), m, lambda method, point: {"k0": 1.0})


@pytest.mark.parametrize("bad,match", [({"plant": "gazebo"}, "plant"), ({"axes": {"noise": []}}, "axes.noise"),
                                       ({"axes": {"k0": {"log": [0, 1, 3]}}}, "axes.k0"),
                                       ({"batch": 0}, "batch"), ({"typo": 1}, "typo"),
                                       ({"axes": {"dt": [0.0]}}, "axes.dt"), ({"t_ss": 0.5}, "t_ss")])
def test_plan_errors_name_the_key(bad, match):
    with pytest.raises(ValueError, match=match):
        plan.load({**SMALL, **bad})


@pytest.fixture(scope="module")
def cluster():
    import logging

    from distributed import Client, LocalCluster
    c = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, silence_logs=logging.ERROR,
                     dashboard_address=":0")
    client = Client(c)
    yield client
    client.close()
    c.close()


@pytest.mark.slow
def test_two_workers_identical_to_serial_and_maps(tmp_path, cluster):
    serial = sweep.run(SMALL, workers=0, out=tmp_path / "serial", progress=False)
    dist = sweep.run(SMALL, scheduler=cluster.scheduler.address, out=tmp_path / "dask", progress=False)
    assert serial.computed == dist.computed == serial.cells == 4 * 2 * 2 + 2 * 2 * 2
    a, b = _rows(tmp_path / "serial"), _rows(tmp_path / "dask")
    assert a.equals(b)
    assert Store(tmp_path / "dask").read()["worker"].nunique() == 2          # both workers ran cells
    again = sweep.run(SMALL, client=cluster, out=tmp_path / "dask", progress=False)
    assert (again.computed, again.skipped) == (0, again.cells)              # nothing recomputed
    paths = maps.write(tmp_path / "dask", plan.load(SMALL))
    assert [p.name for p in paths] == ["map.png", "best.txt"]
    best = maps.best_gain(b, "k0", "noise", designed=Store(tmp_path / "dask").get("designed.json"))
    assert list(best["noise"]) == [0, 1e-4] and best["designed k0"].notna().all()
    # the best gain is the swept value of least median RMS at that noise
    obs = b[b["kind"] == "observer"]
    for _, r in best.iterrows():
        med = obs[obs["noise"] == r["noise"]].groupby("k0")["rms"].median()
        assert r["best k0"] == med.idxmin()


@pytest.mark.slow
def test_worker_killed_costs_a_retry(tmp_path, cluster):
    cfg = {**SMALL, "batch": 2, "T": 1.0, "axes": {**SMALL["axes"], "seed": [2, 3]}}
    pids = cluster.run(os.getpid)
    done = {}
    t = threading.Thread(target=lambda: done.update(res=sweep.run(cfg, client=cluster, out=tmp_path,
                                                                  progress=False)))
    t.start()
    killed, deadline = None, time.time() + 60
    while killed is None and time.time() < deadline and t.is_alive():
        busy = {w: ks for w, ks in cluster.processing().items() if any("sweep-batch" in str(k) for k in ks)}
        if busy:
            killed = pids[next(iter(busy))]
            os.kill(killed, signal.SIGKILL)      # a batch is lost with its worker
        time.sleep(0.01)
    t.join(120)
    assert killed is not None, "no batch was ever seen running"
    res = done["res"]
    assert res.failed == 0 and res.computed == res.cells
    _once(tmp_path, res)
    assert killed not in set(Store(tmp_path).read()["worker"])               # its batch was redone
    assert set(_rows(tmp_path).columns) >= {"rms", "t_conv", "max", "diverged"}


@pytest.mark.slow
def test_client_killed_then_restarted_computes_only_the_rest(tmp_path):
    cfg = tmp_path / "sweep.toml"
    cfg.write_text('robot = "seed000_2r"\nT = 0.5\nobservers = ["reduced_order"]\nbatch = 1\n'
                   '[axes]\nk0 = {log = [2, 200, 8]}\nnoise = [0, 1e-5, 1e-4, 1e-3]\n')
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "codegen", "sweep", str(cfg), "--workers", "0",
                             "--out", str(out)], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while len(Store(out).parts()) < 3 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = len(Store(out).done())
    assert 3 <= before < 32, f"the kill did not land mid-sweep ({before} cells on disk)"
    res = sweep.run(cfg, workers=0, out=out, progress=False)
    assert (res.skipped, res.computed) == (before, 32 - before)
    _once(out, res)


def test_store_parts_are_whole_or_absent(tmp_path):
    import pandas as pd
    store = Store(tmp_path)
    row = {"cell": "abc", "method": "backward", "kind": "baseline", "family": "backward", "noise": 0.0,
           "quantization": 0.0, "mismatch": 0.0, "seed": 0, "dt": 1e-3, "est0": None, "p": {},
           "rms": 1.0, "max": 2.0, "t_conv": 0.1, "gain": 1.0, "lag": 0.0, "diverged": False,
           "params": {}, "note": "", "worker": 1, "cpu_s": 0.01}
    store.write([row], ("k0",), "fp")
    (store.results / ".part-dead.tmp").write_bytes(b"PAR1 half a file")     # a killed writer
    assert store.done() == {"abc"}
    assert list(pd.read_parquet(store.results)["cell"]) == ["abc"]          # pandas skips it too
    store.start(plan.load(SMALL), {"code": "x"})
    assert not list(store.results.glob(".*"))
    assert (tmp_path / "sweep.json").is_file() and list(store.fingerprints()) != []


def test_a_cell_measures_the_velocity_slots_by_name(tmp_path):
    """An observer whose estimate holds more than q̇̂ (extended_state: tau_d_hat after it) is
    measured on its qd_hat slots, and the cell's est0 sets only those (the torque-error estimate
    starts at 0): the run converges as the velocity estimate does."""
    import numpy as np

    from codegen.evaluate.sweep import work
    from codegen.families import observers
    from codegen.pipeline.emit import emit
    from models import load_robot
    spec = observers.build("extended_state", load_robot("seed000_2r"), omega=40.0)
    folder = emit(spec.target(), tmp_path, spec=spec)
    rec = work.true_run("seed000_2r", "model", 0.5, 0.0, 0, 1e-3)
    cell = {"kind": "observer", "family": "extended_state", "est0": 0.5, "p": {}}
    row = work.run_cell(cell, rec, work.payload(folder), t_ss=0.25, level=1e-2)
    assert not row["note"] and not row["diverged"]
    assert row["max"] < 1e-2 and row["t_conv"] < 0.25


def test_map_axes_carry_units_the_window_and_the_paper(tmp_path, monkeypatch):
    """map.png: every axis with its unit, the RMS window and the paper of the observer's
    equations on the figure."""
    import itertools

    import matplotlib.pyplot as plt
    import pandas as pd
    rows = [{"cell": f"{k}-{q}-{s}", "method": "reduced_order", "kind": "observer", "family": "reduced_order",
             "k0": k, "quantization": q, "seed": s, "rms": 1e-3 * (k / 50 + 50 / k) * (1 + q * 1e3),
             "diverged": False}
            for k, q, s in itertools.product([5.0, 50.0, 500.0], [0.0, 1e-4], [0, 1])]
    figs = []
    monkeypatch.setattr(plt, "close", figs.append)
    spec = plan.load({"name": "q", "robot": "ur5", "plant": "mujoco", "T": 4.0, "observers": ["reduced_order"],
                      "axes": {"k0": [5.0, 50.0, 500.0], "quantization": [0.0, 1e-4], "seed": [0, 1]}})
    monkeypatch.setattr(Store, "read", lambda self: pd.DataFrame(rows))
    monkeypatch.setattr(Store, "get", lambda self, name: None)
    maps.write(tmp_path, spec)
    [fig] = figs
    ax = fig.axes[0]
    assert ax.get_xlabel() == "k0 [1/s]" and ax.get_ylabel() == "quantization [rad]"
    assert fig.axes[1].get_ylabel() == "log10 median rms [rad/s]"
    text = ax.get_title()
    assert "over t >= 2 s of each 4 s run" in text and "reduced_order: docs/papers/seed000.md §1.1" in text


_HOLD = ("import sys\nfrom codegen.evaluate.sweep.store import Store\n"
         "with Store(sys.argv[1]).lock():\n    print('locked', flush=True)\n    sys.stdin.read()\n")


def test_one_writer_per_results_folder(tmp_path, capsys):
    """Issue 22, F19: two sweep clients on one --out wrote every cell twice. A second writer is
    refused in one line naming the folder and the holder's pid, before it writes anything (Python
    and the CLI); the lock goes with the process holding it."""
    from codegen.cli import main
    from codegen.evaluate.sweep.store import FolderBusy
    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", _HOLD, str(out)], cwd=ROOT, stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(FolderBusy, match=rf"{out} is being written by another sweep \(pid {holder.pid}, "):
            sweep.run(SMALL, workers=0, out=out, progress=False)
        cfg = tmp_path / "small.toml"
        cfg.write_text('robot = "seed000_2r"\nT = 0.5\nobservers = ["reduced_order"]\n[axes]\nk0 = [2.0]\n')
        capsys.readouterr()
        assert main(["sweep", str(cfg), "--workers", "0", "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert "is being written by another sweep" in err and "another --out" in err and "\n" not in err
        assert sorted(p.name for p in out.iterdir()) == [".lock"]          # nothing written
    finally:
        holder.kill()
        holder.wait()
    with Store(out).lock():                   # released with its process
        pass


def test_foreign_parquet_part_is_refused(tmp_path):
    """Issue 22, F19: a Parquet part of another schema in results/ was read without complaint.
    Every part is checked against the row schema, naming the file: a foreign table, a file that
    is not Parquet, and a part with other gain columns than the sweep's."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from codegen.evaluate.sweep.store import ForeignPart, schema
    store = Store(tmp_path / "out")
    store.results.mkdir(parents=True)
    foreign = store.results / "part-foreign.parquet"
    pq.write_table(pa.table({"cell": ["x"], "speed": [1.0]}), foreign)
    for call in (store.done, store.read, lambda: sweep.run(SMALL, workers=0, out=store.out, progress=False)):
        with pytest.raises(ForeignPart, match=rf"{foreign}: not a part of this sweep: missing columns method, "):
            call()
    assert not (store.out / "targets").exists()                     # refused before the preparation
    foreign.write_bytes(b"not parquet")
    with pytest.raises(ForeignPart, match=rf"{foreign}: not a sweep's results"):
        store.done()
    foreign.unlink()
    pq.write_table(pa.Table.from_pylist([], schema=schema(("kp",))), store.results / "part-kp.parquet")
    assert store.done() == set()                                     # a sweep's part, its own gains
    with pytest.raises(ForeignPart, match=r"part-kp.parquet: .*missing columns k0; unexpected columns kp; move"):
        store.done(("k0",))
