"""Monte-Carlo sweeps of observers and baselines on Dask, resumable.

    python -m codegen sweep sweeps/ur5_quantisation.toml --workers 2 --out build/sweeps/ur5
    res = sweep.run("sweeps/ur5_quantisation.toml", workers=2)      # or a dict; workers=0: in-process
    res.frame()                                                      # pandas, one row per cell

The client parses the sweep file (``plan``), builds each observer once through
``observers.build`` (with ``compare.design_inputs`` for its sensor and mismatch, so the
designed gains follow the design of the day), emits it once per dt and ships the C to the
workers (``work.payload``). True runs are Dask tasks, one per (mismatch, trajectory seed, dt);
batches of cells sharing a true run are tasks depending on it. Each finished batch is written
as one Parquet file (``store``) before the next is awaited, so a killed client loses at most the
batches in flight and a restart computes only the cells not on disk; a killed worker's task is
retried by Dask (``retries``, and the scheduler's allowed failures). ``maps`` draws a metric
over two axes and tabulates the best gain per noise level.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from . import plan
from .store import Store

__all__ = ["SweepResult", "run"]


@dataclass
class SweepResult:
    """What a run did: the output folder, the number of cells of the sweep, computed now,
    found on disk, failed (batches whose task failed after its retries), and the seconds the
    cells took (true runs included, cluster start excluded)."""

    out: Path
    cells: int
    computed: int
    skipped: int
    failed: int
    seconds: float
    gains: tuple = ()

    def frame(self):
        """The rows on disk (pandas DataFrame sorted by cell id)."""
        return Store(self.out).read()


def _code_version():
    from ...core.version import __version__
    try:                                  # the checkout holding this code (none once installed: "")
        git = subprocess.run(["git", "-C", str(Path(__file__).resolve().parents[2]), "describe", "--always", "--dirty"],
                             capture_output=True, text=True, timeout=10, check=False).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        git = ""
    return {"codegen": __version__, "git": git}


def prepare(sweep, robot, out):
    """Build and emit the sweep's observers in the client, once per dt.

    Parameters
    ----------
    sweep : plan.Sweep
        The parsed sweep file (observers, baselines, axes; ``designed`` says whether the gains
        are designed per sensor/mismatch setting).
    robot : RobotModel
        The robot of ``sweep.robot``.
    out : path
        Output folder of the sweep; the targets are emitted under ``<out>/targets``.

    Returns
    -------
    (methods, designed, designs, targets, fingerprint)
        methods: list of plan.Method (observers, then baselines); designed: the
        (method, point) -> {parameter: value} function of ``plan.cells``; designs: the list it
        fills (a row per observer and sensor/mismatch setting, for designed.json); targets:
        payloads (``work.payload``) keyed by (item, dt); fingerprint: code version and, per
        target, its sha256 and generator metadata.
    """
    import json

    from ...families import observers
    from ..compare import design_for, design_inputs, parse_observer
    from ...pipeline.emit import emit
    from ..sim.blocks import compiler_flags
    from ...core.target import discretization
    from .work import payload
    dts = sweep.axes.get("dt", [plan.DEFAULTS["dt"]])
    if not isinstance(dts, list):
        raise ValueError("axes.dt: a random sample time would compile a target per cell; give a list")
    specs, designs = {}, []

    def build(item, fam, given, point):
        key = (item,) if point is None else (item, point["quantization"], point["noise"], point["mismatch"])
        if key not in specs:
            inputs = {} if point is None else design_inputs(point["quantization"], point["noise"],
                                                            abs(point["mismatch"]))
            try:
                specs[key] = observers.build(fam, robot, **{**design_for(fam, inputs), **given})
            except TypeError as e:
                raise ValueError(f"observers: {item!r}: {e}") from None
        return specs[key]

    methods, targets, prints = [], {}, {}
    for item in sweep.observers:
        fam, given = parse_observer(item)
        if not sweep.designed:        # gains from the first value of each gain axis: no design
            given = {**{k: v[0] for k, v in sweep.axes.items()
                        if k not in plan.AXES and isinstance(v, list)}, **given}
        spec = build(item, fam, given, None if not sweep.designed else next(sweep.points()))
        methods.append(plan.Method(item, "observer", fam, given, tuple(spec.p_names)))
        for dt in dts:
            name = f"{robot.name}_{fam}_{plan.digest([item, dt], 8)}"
            folder = emit(spec.target(discretization(None, dt=dt), name=name), Path(out) / "targets", spec=spec)
            targets[(item, dt)] = payload(folder, compiler_flags(spec))
            meta = json.loads(targets[(item, dt)]["files"][f"{folder.name}.json"])
            prints[f"{item}@dt={dt:g}"] = {"sha256": targets[(item, dt)]["sha"], "generator": meta["generator"],
                                           "discretization": meta["discretization"], "target": meta["target"]}
    methods += [plan.Method(b, "baseline", b, {}) for b in sweep.baselines]

    def designed(method, point):
        spec = build(method.item, method.family, method.given, point if sweep.designed else None)
        p = dict(zip(spec.p_names, map(float, spec.p_default)))
        row = {"method": method.item, **{k: point[k] for k in ("quantization", "noise", "mismatch")}, **p}
        if sweep.designed and row not in designs:
            designs.append(row)
        return p
    return methods, designed, designs, targets, {"code": _code_version(), "targets": prints}


def _cluster(workers, scheduler):
    """(client, cluster or None): a client of ``scheduler``, else of a new LocalCluster of
    ``workers`` single-threaded worker processes (default: one per CPU)."""
    import logging

    from distributed import Client, LocalCluster
    if scheduler:
        return Client(scheduler), None
    cluster = LocalCluster(n_workers=workers or os.cpu_count(), threads_per_worker=1, processes=True,
                           silence_logs=logging.ERROR, dashboard_address=":0")
    return Client(cluster), cluster


def _bar(total, show):
    from ...core.progress import bar
    return bar(total=total, desc="sweep", unit="cell", file=sys.stderr, disable=not show)


def run(source, workers=None, scheduler=None, out=None, progress=True, client=None):
    """Run a sweep (only the cells not already in ``out``).

    Parameters
    ----------
    source : path, TOML text or dict
        The sweep file (``codegen.evaluate.sweep.plan``).
    workers : int, optional
        LocalCluster size (default: one per CPU); 0: every cell in this process, no Dask.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``).
    out : path, optional
        Output folder (default <repo>/build/sweeps/<name>).
    progress : bool
        Show a progress bar (stderr).
    client : distributed.Client, optional
        Use this client (the caller owns its cluster).

    Returns
    -------
    SweepResult
    """
    from ...pipeline.compile import work_dir
    sweep = plan.load(source)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise ValueError(f"workers must be a whole number >= 0, got {workers!r}")
    if scheduler and workers:
        raise ValueError("workers, scheduler: give one (a new local cluster, or an existing one)")
    out = Path(out or work_dir() / "sweeps" / sweep.name)
    with Store(out).lock() as store:      # one writer per folder, from the targets to the last part
        store.parts()                      # a foreign part refused before the (slow) preparation
        return _run(sweep, out, workers, scheduler, progress, client)


def _run(sweep, out, workers, scheduler, progress, client):
    """``run`` of the parsed ``sweep`` into ``out`` (its lock held)."""
    from ..compare import robot_by_name
    from .work import run_batch, true_run, warm
    robot = robot_by_name(sweep.robot)
    methods, designed, designs, targets, fingerprint = prepare(sweep, robot, out)
    cells = plan.cells(sweep, methods, designed)
    gains = tuple(k for k in sweep.axes if k not in plan.AXES) or \
        tuple(sorted({p for m in methods for p in m.p_names}))
    store = Store(out)
    done = store.done(gains)               # every part checked before anything is written
    fid = store.start(sweep, fingerprint)
    store.put("designed.json", designs)
    todo = [c for c in cells if c["cell"] not in done]
    jobs = plan.batches(todo, sweep.batch)
    common = (sweep.robot, sweep.plant, float(sweep.T))
    failed, t0 = 0, time.perf_counter()
    with _bar(len(todo), progress) as bar:
        if workers == 0 and client is None and not scheduler:
            warm()
            t0, runs = time.perf_counter(), {}
            for key, batch in jobs:
                if key not in runs:
                    runs = {key: true_run(*common, *key)}        # batches come grouped by true run
                store.write(run_batch(batch, runs[key], targets, sweep.steady, sweep.level), gains, fid)
                bar.update(len(batch))
        else:
            failed, t0 = _distributed(client, workers, scheduler, jobs, common, targets, sweep, store,
                                      gains, fid, bar)
    return SweepResult(out=out, cells=len(cells), computed=len(todo) - failed, skipped=len(cells) - len(todo),
                       failed=failed, seconds=time.perf_counter() - t0, gains=gains)


def _distributed(client, workers, scheduler, jobs, common, targets, sweep, store, gains, fid, bar):
    """Run the batches on Dask, writing each as it finishes; (failed cells, start time)."""
    from distributed import as_completed

    from .work import run_batch, true_run, warm
    own = client is None
    cluster = None
    if own:
        client, cluster = _cluster(workers, scheduler)
    try:
        client.run(warm)
        t0 = time.perf_counter()
        shipped = client.scatter([targets], broadcast=True)[0]
        runs, futures, sizes = {}, [], {}
        for key, batch in jobs:
            if key not in runs:
                runs[key] = client.submit(true_run, *common, *key, retries=sweep.retries,
                                          key=f"sweep-true-{plan.digest([common, key])}")
            f = client.submit(run_batch, batch, runs[key], shipped, sweep.steady, sweep.level,
                              retries=sweep.retries, key=f"sweep-batch-{plan.digest([c['cell'] for c in batch])}")
            futures.append(f)
            sizes[f.key] = len(batch)
        failed = 0
        for f in as_completed(futures):
            try:
                store.write(f.result(), gains, fid)
            except Exception as e:          # a batch that failed after its retries: the rest go on
                failed += sizes[f.key]
                print(f"sweep: batch {f.key} failed: {type(e).__name__}: {e}", file=sys.stderr)
            bar.update(sizes[f.key])
            f.release()
        return failed, t0
    finally:
        if own:
            client.close()
            if cluster is not None:
                cluster.close()

