"""Synthetic logs of the kind users bring, with the truth kept aside: a grid of real-arm runs
(codegen.evaluate.sim.real_plant) over robots, tasks, torque sensors and clocks.

Each cell is one plant (``RealPlant``, drawn with ``seed`` per robot: the 12 cells of a robot share
its perturbation) with a 2^20-count encoder logged to 1e-6 rad (``POSITION``), one torque sensor
and one clock:

    robots         ur5, panda, kinova (codegen.evaluate.scenarios.mujoco_real.robot_model)
    tasks          p2p        four minimum-jerk moves with rests (``point_to_point``)
                   multisine  a 5-harmonic multi-sine at 0.1 Hz (``fourier_excitation``)
                   bursts     slow drifts with short, fast moves of a few joints (``drifts_and_bursts``)
    torque sensors rms        white noise of 1 % of the run's RMS torque per joint
                   abs        white noise of 0.05 N m on every joint (both with the plant's +-0.2 N m offset)
    clocks         receive    1 ms ticks, stamps when a logger received each row (delay std 0.4 ms,
                              0.1 ms resolution, 5 % repeated rows, bunching)
                   jitter     the controller at jittered instants U(0.7, 1.6) ms, 1 % rows dropped

and two runs on it: the task (``T``, 20 s) and an excitation for identification (``T_excitation``,
10 s; ``codegen.logs.identify.excitation``, what `excite` writes). Files of a cell
``<robot>-<task>-<torque>-<clock>``:

    task.csv, excitation.csv               the logs: t, q_<joint>, tau_<joint> (no qd)
    task_truth.csv, excitation_truth.csv   per log row: t, t_sample, tick, repeat, true q, qd, tau
    cell.json                              what was drawn (the plant's perturbation, sensors, clock),
                                           what was measured (each run's statistics: delay std,
                                           repeat fraction, ...) and the yardstick below

Seeds are fixed per cell (the runs' seeds are (seed, crc32(cell), 1 | 2)); a cell is computed on
its own (``cell``), so cells run in parallel processes, and a rerun writes byte-identical files.

Truth-side yardsticks (numpy only): ``kalman_truth``, the constant-acceleration Kalman filter
(codegen.evaluate.baselines.Kalman) on the true sample times of the logged rows, repeats dropped,
its q tuned on the true velocity; ``score_clock``, how many rows a rebuilt clock gives their true
tick, and whether it dropped exactly the repeated rows.

    python -m codegen simulate log-grid --out /work/grid [--T 20] [--jobs 2]
"""
from __future__ import annotations

import json
import time
import zlib
from pathlib import Path

import numpy as np

from .mujoco_real import ROBOTS, T_EXCITATION, T_TASK, robot_model

TASKS = ("p2p", "multisine", "bursts")
TORQUE_SENSORS = {"rms": {"torque_noise": 0.01, "torque_noise_of": "rms"},
                  "abs": {"torque_noise": 0.05, "torque_noise_of": "absolute"}}
CLOCKS = {"receive": {"log_clock": "receive", "tick": 1e-3, "delay_std": 0.4e-3, "stamp_resolution": 1e-4,
                      "repeat": 0.05},
          "jitter": {"log_clock": "jitter"}}
POSITION = {"counts_per_rev": 2 ** 20, "position_decimals": 6}
RUNS = {"excitation": 1, "task": 2}
DESCRIPTIONS = {"log-grid": "synthetic real-arm logs with their truth: robots x tasks x torque sensors x "
                            "clocks (36 cells of task + excitation logs)"}


def cells(robots=ROBOTS, tasks=TASKS, torques=tuple(TORQUE_SENSORS), clocks=tuple(CLOCKS)):
    """The cell names ``<robot>-<task>-<torque>-<clock>`` of the grid, in a fixed order: every
    combination of ``robots`` (of ``ROBOTS``), ``tasks`` (of ``TASKS``), ``torques`` (keys of
    ``TORQUE_SENSORS``) and ``clocks`` (keys of ``CLOCKS``); ValueError naming an unknown one."""
    for name, options, known in (("robot", robots, ROBOTS), ("task", tasks, TASKS),
                                 ("torque", torques, tuple(TORQUE_SENSORS)), ("clock", clocks, tuple(CLOCKS))):
        bad = [v for v in options if v not in known]
        if bad:
            raise ValueError(f"{name}: expected one of {', '.join(known)}, got {', '.join(map(str, bad))}")
    return [f"{r}-{t}-{s}-{c}" for r in robots for t in tasks for s in torques for c in clocks]


def _parse(name):
    parts = str(name).split("-")
    if len(parts) != 4:
        raise ValueError(f"cell: expected <robot>-<task>-<torque>-<clock>, got {name!r}")
    cells(*([p] for p in parts))                          # each part known, else the error names it
    return parts


def task_reference(robot, task, T=T_TASK, seed=0):
    """The reference t -> (q_d, qd_d, qdd_d) of ``task`` (one of ``TASKS``) for ``robot``,
    drawn with ``seed``; ``T`` (s) is the bursts task's length."""
    from ..sim.real_plant import drifts_and_bursts, fourier_excitation, point_to_point
    if task == "p2p":
        return point_to_point(robot, seed=seed)
    if task == "multisine":
        return fourier_excitation(robot, seed=seed)
    if task == "bursts":
        return drifts_and_bursts(robot, T=T, seed=seed)
    raise ValueError(f"task: expected one of {', '.join(TASKS)}, got {task!r}")


def cell(name, out, seed=0, T=T_TASK, T_excitation=T_EXCITATION):
    """Simulate and write one cell of the grid (module docstring) into ``out/<name>``, replacing
    a folder there in one step (nothing half-written).

    Parameters
    ----------
    name : str
        ``<robot>-<task>-<torque>-<clock>`` (``cells()``).
    out : path-like
        Parent folder.
    seed : int
        Seed of the plant, the trajectories and (with the cell's name) the runs.
    T, T_excitation : float
        Length of the task run and of the excitation run (s).

    Returns
    -------
    dict
        The contents of cell.json.
    """
    import os
    import shutil
    import tempfile

    from ...core.atomic import replace_dir
    from ...logs.identify import excitation
    from ..sim.real_plant import RealPlant
    robot_name, task, torque, clock = _parse(name)
    robot = robot_model(robot_name)
    plant = RealPlant(robot, seed=seed, **TORQUE_SENSORS[torque], **CLOCKS[clock], **POSITION)
    ex = excitation(robot, T=T_excitation, seed=seed)
    references = {"excitation": lambda t: tuple(a[0] for a in ex.at(t)),
                  "task": task_reference(robot, task, T=T, seed=seed)}
    code = zlib.crc32(name.encode())
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=out))
    umask = os.umask(0)
    os.umask(umask)
    tmp.chmod(0o777 & ~umask)                          # mkdtemp's 0700, as a folder mkdir makes
    try:
        measured, files = {}, []
        for run_name, length in (("excitation", T_excitation), ("task", T)):
            run = plant.run(references[run_name], length, seed=(seed, code, RUNS[run_name]))
            log, truth = run.write(tmp, run_name, truth="rows")
            files += [log.name, truth.name]
            measured[run_name] = run.stats()
        summary = {"cell": name, "robot": robot_name, "task": task, "torque_sensor": torque, "clock": clock,
                   "seed": seed, "run_seeds": {k: [seed, code, v] for k, v in RUNS.items()},
                   "T": T, "T_excitation": T_excitation, "excitation": "codegen.logs.identify.excitation",
                   "sensors": {"position": dict(POSITION), "torque": dict(TORQUE_SENSORS[torque])},
                   "clock_settings": dict(CLOCKS[clock]), "plant": plant.truth(), "measured": measured,
                   "yardstick": {"kalman_truth": kalman_truth(read_rows(tmp, "task"), r=_r(plant))},
                   "files": files + ["cell.json"]}
        (tmp / "cell.json").write_text(json.dumps(summary, indent=1) + "\n")
        old = replace_dir(tmp, out / name)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return summary


def _r(plant):
    """The Kalman filter's measurement variance for the plant's position sensor (rad^2): the
    encoder's and the logger's rounding, D^2 / 12 + 10^(-2 decimals) / 12, and its white noise."""
    r = plant.encoder_step ** 2 / 12 + plant.position_noise ** 2
    if plant.position_decimals is not None:
        r += 10.0 ** (-2 * plant.position_decimals) / 12
    return r


# ------------------------------------------------------------------------------ truth-side yardsticks
def read_rows(folder, name="task"):
    """A log and its per-row truth (``<name>.csv``, ``<name>_truth.csv`` of a cell) as arrays.

    Parameters
    ----------
    folder : path-like
        The cell's folder.
    name : {"task", "excitation"}
        The run.

    Returns
    -------
    dict
        ``joint_names``; ``t`` (R,) the log's stamps; ``q_meas`` (R, n) its positions; ``t_sample``
        (R,), ``tick`` (R,) int, ``repeat`` (R,) bool, ``q``, ``qd`` (R, n): the truth of each row.
    """
    from ...core.columns import read_columns
    folder = Path(folder)
    header, log = read_columns(folder / f"{name}.csv")
    joints = [h[2:] for h in header if h.startswith("q_")]
    th, truth = read_columns(folder / f"{name}_truth.csv")
    missing = [c for c in ("t", "t_sample", "tick", "repeat") if c not in th]
    if missing:
        raise ValueError(f"{folder / f'{name}_truth.csv'}: no column {', '.join(missing)} (not a per-row truth)")
    col = lambda h, d, c: d[:, h.index(c)]
    if len(truth) != len(log) or not np.array_equal(col(th, truth, "t"), col(header, log, "t")):
        raise ValueError(f"{folder}: {name}_truth.csv does not hold the rows of {name}.csv")
    return {"joint_names": joints, "t": col(header, log, "t"),
            "q_meas": np.column_stack([col(header, log, f"q_{j}") for j in joints]),
            "t_sample": col(th, truth, "t_sample"), "tick": np.rint(col(th, truth, "tick")).astype(np.int64),
            "repeat": col(th, truth, "repeat") > 0.5,
            "q": np.column_stack([col(th, truth, f"q_{j}") for j in joints]),
            "qd": np.column_stack([col(th, truth, f"qd_{j}") for j in joints])}


def _golden(f, a, b, tol):
    """argmin of f over [a, b] by golden-section search to an interval of ``tol``; (x, f(x))."""
    g = (np.sqrt(5) - 1) / 2
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return (c, fc) if fc <= fd else (d, fd)


def kalman_truth(rows, r, grid=None, tol=0.01):
    """The constant-acceleration Kalman filter (``codegen.evaluate.baselines.Kalman``) on the true
    sample times of the log's rows, repeated rows dropped, its jerk density q tuned on the truth:
    the lowest RMS sqrt(mean_k ||qd_hat_k - qd_k||^2) over the second half (t_sample >= the
    middle of the kept rows' span) over ``grid`` (log q), refined by a golden-section search
    over log10 q within half a decade of the best grid value, to ``tol`` decades.

    Parameters
    ----------
    rows : dict
        ``read_rows``' arrays (``t_sample``, ``repeat``, ``q_meas``, ``qd``).
    r : float
        The measurement variance (rad^2), > 0.
    grid : sequence of float, optional
        Values of q (rad^2/s^5); default ``baselines.GRIDS["kalman"]`` (1e-3 .. 1e12).
    tol : float
        Width of the final interval of log10 q, > 0.

    Returns
    -------
    dict
        ``q`` (the tuned value), ``rms`` (rad/s), ``rms_grid`` (the best of the grid), ``t_ss``
        (s), ``rows`` (kept rows), ``dt`` (the median step, s), ``r``.
    """
    from ..baselines import GRIDS, Kalman
    from ..metrics import rms_after
    keep = ~np.asarray(rows["repeat"], bool)
    t, Y, qd = rows["t_sample"][keep], rows["q_meas"][keep], rows["qd"][keep]
    if len(t) < 3 or np.any(np.diff(t) <= 0):
        raise ValueError("rows: the kept rows' sample times must be >= 3 and increase (repeats dropped)")
    if not (np.isfinite(r) and r > 0):
        raise ValueError(f"r must be a positive variance (rad^2), got {r!r}")
    dt = float(np.median(np.diff(t)))
    t_ss = float(t[0] + (t[-1] - t[0]) / 2)

    def rms(log_q):
        k = Kalman(Y.shape[1], dt, q=10.0 ** log_q, r=r)
        k.reset(Y[0])
        e = rms_after(t, k.run(Y, t=t) - qd, t_ss)
        return e if np.isfinite(e) else np.inf
    logs = np.log10(np.asarray(grid if grid is not None else GRIDS["kalman"], dtype=float))
    values = [rms(v) for v in logs]
    best = int(np.argmin(values))
    x, fx = _golden(rms, logs[best] - 0.5, logs[best] + 0.5, tol)
    if values[best] < fx:
        x, fx = logs[best], values[best]
    return {"q": float(10.0 ** x), "rms": float(fx), "rms_grid": float(values[best]), "t_ss": t_ss,
            "rows": int(keep.sum()), "dt": dt, "r": float(r)}


def score_clock(rows, kept, ticks):
    """How well a rebuilt clock matches the truth: ``kept`` the row indices it keeps, ``ticks``
    the integer tick it gives each.

    Parameters
    ----------
    rows : dict
        ``read_rows``' arrays (``tick``, ``repeat``).
    kept : (K,) int array
        Indices of the kept rows, increasing, K >= 1.
    ticks : (K,) int array
        The tick assigned to each kept row.

    Returns
    -------
    dict
        ``tick_fraction``: the fraction of kept rows whose tick relative to the first kept row,
        ticks_k - ticks_0, is the true one, tick[kept_k] - tick[kept_0]; ``repeats_dropped_exactly``:
        whether the dropped rows are exactly the repeated ones; ``repeats_kept`` and
        ``others_dropped``: the counts of each kind of mistake.
    """
    tick, repeat = np.asarray(rows["tick"]), np.asarray(rows["repeat"], bool)
    kept = np.asarray(kept)
    ticks = np.asarray(ticks)
    if kept.ndim != 1 or len(kept) < 1 or not np.issubdtype(kept.dtype, np.integer):
        raise ValueError(f"kept: expected a 1-D array of row indices, got {kept.dtype} shape {kept.shape}")
    if np.any(np.diff(kept) <= 0) or kept[0] < 0 or kept[-1] >= len(tick):
        raise ValueError(f"kept: expected increasing row indices in [0, {len(tick)}), got {kept[:5]}...")
    if ticks.shape != kept.shape or not np.issubdtype(ticks.dtype, np.integer):
        raise ValueError(f"ticks: expected {len(kept)} integers (one per kept row), got {ticks.dtype} shape "
                         f"{ticks.shape}")
    right = (ticks - ticks[0]) == (tick[kept] - tick[kept[0]])
    dropped = np.ones(len(tick), bool)
    dropped[kept] = False
    return {"tick_fraction": float(right.mean()), "repeats_dropped_exactly": bool(np.array_equal(dropped, repeat)),
            "repeats_kept": int(np.sum(repeat & ~dropped)), "others_dropped": int(np.sum(dropped & ~repeat))}


# ------------------------------------------------------------------------------ the grid
def _cell(args):
    name, out, seed, T, T_excitation = args
    t0 = time.perf_counter()
    return cell(name, out, seed=seed, T=T, T_excitation=T_excitation), time.perf_counter() - t0


def grid(out, names=None, seed=0, T=T_TASK, T_excitation=T_EXCITATION, jobs=1, progress=True):
    """Write the cells ``names`` (default all 36 of ``cells()``) into ``out``, ``jobs`` processes
    at a time, with a progress bar on stderr (``progress``).

    Parameters
    ----------
    out : path-like
        Parent folder of the cells.
    names : list of str, optional
        Cells (``cells()``).
    seed, T, T_excitation
        As in ``cell``.
    jobs : int
        Processes, >= 1.
    progress : bool
        A progress bar on stderr.

    Returns
    -------
    dict
        Per cell: the measured delay std and repeat fraction (receive clock), the dropped
        fraction, the task's peak speed over the limit, the Kalman yardstick and the wall time.
    """
    import sys

    from ...core.progress import bar as progress_bar
    names = list(cells() if names is None else names)
    for name in names:
        _parse(name)
    if not (isinstance(jobs, int) and jobs >= 1):
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    work = [(name, str(out), seed, float(T), float(T_excitation)) for name in names]
    bar = progress_bar(total=len(work), desc="log-grid", unit="cell", file=sys.stderr, disable=None if progress else True)
    rows = {}
    try:
        if jobs == 1:
            results = map(_cell, work)
        else:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor, as_completed
            pool = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"))
            results = (f.result() for f in as_completed([pool.submit(_cell, w) for w in work]))
        for summary, wall in results:
            rows[summary["cell"]] = _row(summary, wall)
            bar.set_postfix_str(summary["cell"])
            bar.update()
    finally:
        bar.close()
        if jobs > 1:
            pool.shutdown(cancel_futures=True)
    return {name: rows[name] for name in names}


def _row(summary, wall):
    task = summary["measured"]["task"]
    v = np.array([np.nan if x is None else x for x in task["velocity_limit"]])
    row = {"rows": task.get("rows", task["logged"]),
           "dropped_fraction": task["dropped_fraction"],
           "peak_speed_over_limit": float(np.nanmax(np.array(task["qd_max"]) / v)),
           "tracking_error_max": max(task["tracking_error_max"]),
           "kalman_truth_rms": summary["yardstick"]["kalman_truth"]["rms"], "wall_s": round(wall, 1)}
    if "delay_ms" in task:
        row.update({"delay_std_ms": task["delay_ms"]["std"], "delay_max_ms": task["delay_ms"]["max"],
                    "repeat_fraction": task["repeat_fraction"]})
    return row


def _scenario(reference=False, out=None, T=T_TASK, jobs=1):
    if out is None:
        raise ValueError("log-grid: give --out, the folder of the cells")
    t0 = time.perf_counter()
    per_cell = grid(Path(out), T=T, jobs=jobs)
    return {"cells": per_cell, "out": str(out), "wall_s": round(time.perf_counter() - t0, 1)}


_scenario.__doc__ = ("Synthetic real-arm logs with their truth: ur5, panda, kinova x p2p, multisine, bursts x "
                     "torque noise 1 % of RMS or 0.05 N m x receive or jitter clock, each cell a 20 s task log "
                     "(``T``), a 10 s excitation log and cell.json in ``out``; ``jobs`` processes "
                     "(``reference`` unused).")
SCENARIOS = {"log-grid": _scenario}


# ------------------------------------------------------------------------------ one log of a user's robot
def synthetic_log(robot, path, T=T_TASK, task="multisine", clock="receive", torque="rms", seed=0):
    """A realistic log of ``robot`` (a URDF robot: one's own arm) and its truth, as one cell of
    the grid writes them: the real plant (its URDF perturbed: masses, inertias, a payload,
    friction, torque offsets, drawn with ``seed``) tracking ``task`` for ``T`` s, logged with the
    grid's encoder, the torque sensor ``torque`` and the clock ``clock``.

    Parameters
    ----------
    robot : models.RobotModel
        A URDF robot (its locked joints held).
    path : path-like
        The log (a CSV: t, q_<joint>, tau_<joint>); its truth is written beside it as
        ``<stem>_truth.csv`` (per row: t, t_sample, tick, repeat, true q, qd, tau).
    T : float
        Length (s) of the run (> 0).
    task, clock, torque : str
        One of TASKS, of CLOCKS and of TORQUE_SENSORS.
    seed : int
        Seed of the plant, the task and the run.

    Returns
    -------
    (pathlib.Path, pathlib.Path, dict)
        The log, its truth and the run's statistics (``RealRun.stats``).
    """
    from ..sim.real_plant import RealPlant, draw_perturbation
    for name, value, known in (("task", task, TASKS), ("clock", clock, CLOCKS), ("torque", torque, TORQUE_SENSORS)):
        if value not in known:
            raise ValueError(f"{name}: expected one of {', '.join(known)}, got {value!r}")
    if not (np.isfinite(T) and T > 0):
        raise ValueError(f"T: expected a positive length in seconds, got {T!r}")
    path = Path(path)
    if path.suffix != ".csv":
        raise ValueError(f"out: expected a .csv path, got {str(path)!r}")
    wrist = min(3, robot.n // 2)                      # the wrist's friction ranges: up to 3 joints, half an arm
    plant = RealPlant(robot, draw_perturbation(robot, seed, wrist=wrist), **TORQUE_SENSORS[torque], **CLOCKS[clock],
                      **POSITION)
    run = plant.run(task_reference(robot, task, T=T, seed=seed), T, seed=(seed, zlib.crc32(path.stem.encode()), 2))
    log, truth = run.write(path.parent, path.stem, truth="rows")
    return log, truth, run.stats()
