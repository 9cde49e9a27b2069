"""What runs on a worker: true runs of the plant, and batches of cells on shipped C.

A target travels as a payload {prefix, sha, files (name -> bytes of the emitted folder),
cflags}: the worker writes the files under ``<cache>/sweep-src/`` and builds them through the
content-hash cache (``codegen.pipeline.compile.build``), so a cell does no CasADi work and a worker on the
client's machine finds the library already built.
"""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from .. import metrics

_LOADED = {}        # sha -> CompiledObserver, one per worker process


def payload(folder, cflags=()):
    """The shipped form of an emitted target folder: {prefix, sha, files, cflags}.

    Parameters
    ----------
    folder : path
        A folder written by ``codegen.pipeline.emit`` (its .c, .h and .json files are read).
    cflags : sequence of str
        Extra compiler flags of its kernel (``sim.blocks.compiler_flags``).

    Returns
    -------
    dict
        prefix (folder name), files (name -> bytes), cflags (list), sha (sha256 of the files)."""
    from ...pipeline.compile import read_target
    from .plan import digest
    files = read_target(Path(folder))
    prefix = Path(folder).name
    return {"prefix": prefix, "files": files, "cflags": list(cflags),
            "sha": digest({n: b.hex() for n, b in files.items()}, 64)}


def observer(target):
    """The CompiledObserver of a payload ``target`` (``payload``), built from its C once per
    process (cache hit when the library exists)."""
    if target["sha"] not in _LOADED:
        from ...pipeline.compile import compile_library, cache_dir
        from ...pipeline.load import load
        folder = cache_dir() / "sweep-src" / f"{target['prefix']}-{target['sha'][:16]}"
        if not folder.is_dir():
            folder.parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=".src-", dir=folder.parent))
            for name, data in target["files"].items():
                (tmp / name).write_bytes(data)
            try:
                os.rename(tmp, folder)
            except OSError:                       # another worker got there first: same content
                for f in tmp.iterdir():
                    f.unlink()
                tmp.rmdir()
        _LOADED[target["sha"]] = load(folder, compile_library(folder, extra_flags=target["cflags"]))
    return _LOADED[target["sha"]]


def warm():
    """Import what a cell needs (so that timings exclude a worker's first imports)."""
    import importlib
    for m in ("scipy.signal", "scipy.optimize", "codegen.evaluate.compare", "codegen.evaluate.sim.sensors",
              "codegen.evaluate.sim.mujoco_plant", "mujoco"):
        try:
            importlib.import_module(m)
        except ImportError:     # the MuJoCo plant is optional
            pass
    return os.getpid()


def true_run(robot_name, plant, T, mismatch, seed, dt):
    """The plant's true run (a Recording with true q, qd and the applied tau).

    ``"mujoco"``: MuJoCo's computed-torque tracking of seeded sinusoids
    (codegen.evaluate.sim.mujoco_plant); ``"model"``: our model's exact inverse-dynamics trajectory
    (codegen.verify.trajectory.demo_trajectory) of a plant whose masses and inertias are (1 + mismatch)
    times the model's: tau = (1 + mismatch)(tau_model - tau_f(qd)) + tau_f(qd) (the dynamics are
    linear in the inertial parameters; the friction tau_f, viscous, Coulomb and offset, is not
    scaled).

    Parameters
    ----------
    robot_name : str
        Catalog name or .urdf path (``compare.robot_by_name``).
    plant : {"model", "mujoco"}
    T : float
        Run length (s).
    mismatch : float
        Relative error m of the plant's masses and inertias.
    seed : int
        Seed of the trajectory.
    dt : float
        Sample time (s).

    Returns
    -------
    codegen.logs.recording.Recording
    """
    from ..compare import robot_by_name
    from ...logs.recording import Recording
    robot = robot_by_name(robot_name)
    if plant == "mujoco":
        from ..sim.mujoco_plant import MujocoPlant, sinusoids
        return MujocoPlant(robot, mismatch=mismatch).track(sinusoids(robot, seed=int(seed)), T, dt=dt)
    from ...verify.trajectory import demo_trajectory
    t, Q, QD, TAU = demo_trajectory(robot, T=T, dt=dt, seed=int(seed))
    friction = np.asarray(robot.tau_f.map(len(QD))(QD.T), dtype=float).T
    TAU = (1.0 + mismatch) * (TAU - friction) + friction
    return Recording(t=t, q=Q, tau=TAU, qd=QD, joint_names=list(robot.joint_names))


def run_cell(cell, rec, target, t_ss, level):
    """One cell on a measured recording: the observer (loop in C) from est0 with the cell's
    parameters, or the baseline tuned over its grid; the metrics of ``codegen.evaluate.metrics``.

    Parameters
    ----------
    cell : dict
        A cell of ``plan.cells`` (kind, family, est0 (rad/s) and p).
    rec : codegen.logs.recording.Recording
        The measured run (``sim.sensors.measured``), with the true qd.
    target : dict or None
        The observer's payload (``payload``); None for a baseline.
    t_ss : float
        Start of the steady-state window (s).
    level : float
        Convergence threshold on ||err|| (rad/s).

    Returns
    -------
    dict
        The metrics (rms, max, t_conv, gain, lag, diverged), params run (dict) and a note.
    """
    from ..compare import tune_on_reference as tune
    from ...core.estimator import full_estimate, velocity_estimate
    from ...pipeline.load import ObserverError
    Y, U, truth = rec.q, rec.tau, rec.qd
    note = ""
    if cell["kind"] == "observer":
        obs = observer(target)
        # the velocity slots by name: an estimate may hold more (extended_state: tau_d_hat)
        names, joints = obs.meta["names"]["est"], rec.joint_names
        est0 = None if cell["est0"] is None else full_estimate(names, truth[0] + cell["est0"], joints)
        params = dict(cell["p"])
        p = [params.get(k, d) for k, d in zip(obs.meta["names"]["p"], obs.p_default)]
        try:
            obs.reset(Y[0], est0=est0, p=p)
            est = velocity_estimate(obs.run(Y, U), names, joints)
        except (ObserverError, FloatingPointError, ValueError) as e:
            est, note = np.full(truth.shape, np.nan), str(e)
    else:
        params, est = tune(cell["family"], Y, rec.t, truth, t_ss, rec.dt)
    return {**metrics.summarize(rec.t, est, truth, t_ss, level), "params": params, "note": note}


def run_batch(cells, true, targets, t_ss, level):
    """Rows (dicts) of a batch of cells sharing one true run; the measured run is made once
    per sensor setting (the cells come sorted by it). ``worker`` (pid) and ``cpu_s`` (CPU
    seconds of this thread on the cell) say where and at what cost a row was computed.

    Parameters
    ----------
    cells : list of dict
        Cells of one batch (``plan.batches``).
    true : codegen.logs.recording.Recording
        Their true run (``true_run``).
    targets : dict
        Payloads keyed by (item, dt) (``prepare``).
    t_ss, level : float
        Steady-state start (s) and convergence threshold (rad/s), as in ``run_cell``.

    Returns
    -------
    list of dict
        Each cell with its metrics, params, note, worker and cpu_s."""
    from ..sim.sensors import measured
    rows, last = [], (None, None)
    for c in cells:
        sensor = (c["quantization"], c["noise"], c["seed"])
        if last[0] != sensor:
            last = (sensor, measured(true, *sensor))
        target = targets.get((c["method"], c["dt"])) if c["kind"] == "observer" else None
        t0 = time.thread_time()
        row = run_cell(c, last[1], target, t_ss, level)
        rows.append({**c, **row, "worker": os.getpid(), "cpu_s": time.thread_time() - t0})
    return rows
