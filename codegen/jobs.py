"""Targets through the pipeline: design, emit, compile, then run or cross-check; in parallel
processes, with a progress bar over the stages (what `generate`, `build` and `check` do).

    jobs = [Job(target, out="generated", stages=GENERATE)]
    for job, row in run(jobs, processes=2):    # row: dict of results, or the exception raised
        ...
"""
from __future__ import annotations

import json
import multiprocessing as mp
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .pipeline.stages import STAGES as COMPILE  # design, emit, compile

GENERATE = COMPILE + ("run",)
CHECK = COMPILE + ("check",)


@dataclass(frozen=True)
class Job:
    """One target and what to do with it.

    Parameters
    ----------
    target : codegen.core.target.Target
    out : path
        Parent folder of the target's generated folder.
    stages : tuple of str
        ``COMPILE``, ``GENERATE`` (then run the C harness and ctypes over a run of ``T`` seconds)
        or ``CHECK`` (then cross-check against the reference on ``count`` random inputs).
    force : bool
        Replace a folder generated from another target.
    native : bool
        Compile with -march=native.
    options : dict
        ``T`` (s) for GENERATE; ``count`` for CHECK.
    """

    target: object
    out: Path
    stages: tuple = GENERATE
    force: bool = False
    native: bool = False
    options: dict = field(default_factory=dict)


def make(job, report=lambda stage: None):
    """Take ``job`` through its stages, calling ``report(stage)`` as each starts and
    ``report(None)`` at the end.

    Returns
    -------
    dict
        prefix, folder, lib, params, design (the spec's DesignReport), seconds per stage ("<stage>_s") and the stage results:
        "harness_equal" (the C harness and ctypes give identical estimates over the run), "T",
        "error" (|truth - estimate| at the first and last sample, when the run has a truth: qd
        or an elastic robot's state x, named by "error_of"), or "check" (worst relative errors
        of ``codegen.verify.cross_check``).
    """
    from .pipeline.stages import make as make_target
    target = job.target
    row, clock, current = {"prefix": target.prefix, "folder": str(Path(job.out) / target.prefix)}, \
        time.perf_counter(), None

    def stage(name):
        nonlocal clock, current
        now = time.perf_counter()
        if current:
            row[f"{current}_s"] = now - clock
        clock, current = now, name
        report(name)

    made = make_target(target, job.out, force=job.force, native=job.native, report=stage)
    spec, folder = made.spec, made.folder
    row["params"], row["lib"], row["design"] = spec.params, str(made.lib), spec.design
    # the stability of what was built (the folder's: after substeps "auto" was resolved), not the
    # design's own check at the design's discretisation
    row["stability"] = json.loads((Path(folder) / f"{target.prefix}.json").read_text()).get("stability")
    if "run" in job.stages:
        stage("run")
        row.update(_run(spec, target, folder, Path(row["lib"]), job.options.get("T", 2.0)))
    if "check" in job.stages:
        from .verify import cross_check
        stage("check")
        row["check"] = cross_check(spec, count=job.options.get("count", 1000), folder=folder)
    stage(None)
    return row


def _run(spec, target, folder, lib, T):
    """The C harness (run_csv) and ctypes over T seconds of ``check.trajectory_inputs``; the
    estimate's error against the truth at the first and last sample, when there is one."""
    from .verify import c_programs
    from .pipeline.compile import work_dir
    from .verify.inputs import trajectory_inputs
    from .pipeline.load import load
    dt = target.discretization.dt
    run = trajectory_inputs(spec, int(round(T / dt)) + 1, dt)
    t = np.arange(len(run.Y)) * dt
    work = work_dir() / "demo"
    work.mkdir(parents=True, exist_ok=True)
    csv_in, csv_out = work / f"{target.prefix}_in.csv", work / f"{target.prefix}_out.csv"
    c_programs.write_csv(csv_in, t, run.Y, run.U)
    c_programs.run_csv(folder, csv_in, csv_out)
    _, EST = c_programs.read_csv(csv_out)
    obs = load(folder, lib)
    obs.reset(run.Y[0])
    out = {"harness_equal": bool(np.array_equal(obs.run(run.Y, run.U), EST)), "T": float(t[-1])}
    if run.truth is not None and spec.est_names[:len(run.truth_names)] == run.truth_names:
        k = len(run.truth_names)
        out["error"] = [float(np.linalg.norm(EST[i, :k] - run.truth[i])) for i in (0, -1)]
        out["error_of"] = "x" if k > spec.robot.n else "qd"
    return out


# ------------------------------------------------------------------------------------ parallel
_queue = None


def _init(queue):
    global _queue
    _queue = queue


def _make_reporting(i, job):
    return make(job, report=lambda stage: _queue.put((i, stage)))


def run(jobs, processes=None, debug=False):
    """Make every job of ``jobs`` (a list of Job), ``processes`` at a time (default: one per core,
    at most one per job), with a progress bar over all stages when stderr is a terminal.

    Yields
    ------
    (Job, dict or Exception)
        In order of completion; a job that raised yields its exception (``debug``: re-raised).
    """
    from .core.progress import bar as progress_bar
    processes = max(1, min(processes or os.cpu_count() or 1, len(jobs)))
    bar = progress_bar(total=sum(len(j.stages) for j in jobs), desc="targets", unit="stage", file=sys.stderr,
                       leave=False, dynamic_ncols=True, disable=None)

    started = set()

    def tick(i, stage):                      # stage starts (None: the job is done)
        if i in started:
            bar.update(1)
        started.add(i)
        bar.set_postfix_str(f"{jobs[i].target.prefix}: {stage or 'done'}", refresh=True)

    try:
        if processes == 1:
            for i, job in enumerate(jobs):
                try:
                    yield job, make(job, report=lambda stage, i=i: tick(i, stage))
                except Exception as e:
                    if debug:
                        raise
                    yield job, e
            return
        ctx = mp.get_context("fork")
        queue = ctx.Queue()
        with ProcessPoolExecutor(processes, mp_context=ctx, initializer=_init, initargs=(queue,)) as pool:
            pending = {pool.submit(_make_reporting, i, job): job for i, job in enumerate(jobs)}
            while pending:
                finished, _ = wait(pending, timeout=0.1, return_when=FIRST_COMPLETED)
                while not queue.empty():
                    tick(*queue.get())
                for f in finished:
                    job, error = pending.pop(f), f.exception()
                    if error is not None and debug:
                        raise error
                    yield job, error or f.result()
            while not queue.empty():
                tick(*queue.get())
    finally:
        bar.close()
