"""A real arm's logs: ur5, panda and kinova on the "real" MuJoCo plant (codegen.evaluate.sim.real_plant).

The plant is the robot's URDF in MuJoCo with every moving link's mass, centre of mass and principal
moments off by up to +-20 %, a 1 kg payload on the last link, Coulomb (MuJoCo ``frictionloss``) and
viscous friction on every joint; its own controller (computed torque with MuJoCo's inverse
dynamics on the true state: it knows that plant) runs at jittered instants (steps U(0.7, 1.6) ms,
1 us clock). The log is what a user of that arm has: 2^16-count encoder positions and torques
with 1 % (of the effort limit) white noise and a +-0.2 N m offset, 1 % of the rows missing.

Two runs on the same plant: ``excitation``, one 10 s period of a 5-harmonic multi-sine at 0.1 Hz
(``fourier_excitation``; another excitation plugs in through ``excitation``), and ``task``,
four minimum-jerk point-to-point moves with rests (``point_to_point``, 20 s). Files in ``out``:

    excitation.csv, task.csv               the logs: t, q_<joint>, tau_<joint> (measured; no qd)
    excitation_truth.csv, task_truth.csv   t, logged, q_<joint>, qd_<joint>, tau_<joint> (applied)
    perturbation.json                      what was drawn (RealPlant.truth)

and the summary (sample times, torque-sensor error, friction drawn, tracking). ``observe`` (the
scenario) then does what the arm's user does: identifies the robot on the excitation log and
compares the observers with the identified model and with the URDF on the task log
(``identified/``, ``compare_identified/``, ``compare_urdf/``).

    python -m codegen simulate mujoco-kinova-real [--T 20]
"""
from __future__ import annotations

import json
import time
from functools import cache, lru_cache
from pathlib import Path

ROBOTS = ("ur5", "panda", "kinova")
URDFS = {"kinova": "kinova_description/robots/kinova.urdf"}   # example-robot-data, beside the catalog's
T_EXCITATION = 10.0
T_TASK = 20.0


@cache
def robot_model(robot_name):
    """The RobotModel of ``robot_name``: the catalog's (ur5, panda), or example-robot-data's URDF
    (kinova) with every movable gripper joint (a name with "finger" or "gripper") locked at 0."""
    import xml.etree.ElementTree as ET

    from models import load_robot
    from models.urdf import example_robot_data_dir
    if robot_name not in ROBOTS:
        raise ValueError(f"robot: the real MuJoCo scenarios have {', '.join(ROBOTS)}, got {robot_name!r}")
    if robot_name not in URDFS:
        return load_robot(robot_name)
    path = example_robot_data_dir() / URDFS[robot_name]
    locked = {j.get("name"): 0.0 for j in ET.parse(path).getroot().iter("joint")
              if j.get("type") not in (None, "fixed")
              and any(w in j.get("name").lower() for w in ("finger", "gripper"))}
    return load_robot(urdf=path, locked_joints=locked or None)


def runs(robot_name, seed=0, T=T_TASK, T_excitation=T_EXCITATION, excitation=None, torque_noise_of="effort"):
    """The plant and its two runs (module docstring).

    Parameters
    ----------
    robot_name : {"ur5", "panda", "kinova"}
    seed : int
        Seed of the perturbation, of the trajectories and of each run's timing and noise.
    T, T_excitation : float
        Length of the task run and of the excitation run (s).
    excitation : callable, optional
        t -> (q_d, qd_d, qdd_d), the excitation reference; default
        ``fourier_excitation(robot, seed=seed)``.
    torque_noise_of : {"effort", "rms"}
        The torque sensor's 1 % white noise: of each joint's effort limit (a full-scale figure,
        the same in both runs) or of the run's torque RMS (``RealPlant``).

    Returns
    -------
    (RealPlant, RealRun, RealRun)
        The plant, the excitation run and the task run.
    """
    if excitation is None:
        return _runs(robot_name, int(seed), float(T), float(T_excitation), torque_noise_of)
    return _simulate(robot_name, int(seed), float(T), float(T_excitation), excitation, torque_noise_of)


@lru_cache(maxsize=4)
def _runs(robot_name, seed, T, T_excitation, torque_noise_of):
    return _simulate(robot_name, seed, T, T_excitation, None, torque_noise_of)


def _simulate(robot_name, seed, T, T_excitation, excitation, torque_noise_of):
    from ..sim.real_plant import RealPlant, fourier_excitation, point_to_point
    robot = robot_model(robot_name)
    plant = RealPlant(robot, seed=seed, torque_noise_of=torque_noise_of)
    ref = excitation if excitation is not None else fourier_excitation(robot, seed=seed)
    exc = plant.run(ref, T_excitation, seed=(seed, 1))
    task = plant.run(point_to_point(robot, seed=seed), T, seed=(seed, 2))
    return plant, exc, task


def experiment(robot_name, out=None, seed=0, T=T_TASK, T_excitation=T_EXCITATION, excitation=None,
               torque_noise_of="effort"):
    """Simulate the two runs of ``robot_name`` and write them (module docstring).

    Parameters
    ----------
    robot_name : {"ur5", "panda", "kinova"}
    out : path-like, optional
        Folder for the CSVs and perturbation.json.
    seed, T, T_excitation, excitation, torque_noise_of
        As in ``runs``.

    Returns
    -------
    dict
        The summary: robot, seed, the drawn friction, payload, torque offset and body masses,
        each run's statistics (``RealRun.stats``), the files and the wall time.
    """
    t0 = time.perf_counter()
    plant, exc, task = runs(robot_name, seed, T, T_excitation, excitation, torque_noise_of)
    truth = plant.truth()
    files = {}
    if out is not None:
        out = Path(out)
        for name, run in (("excitation", exc), ("task", task)):
            log, tr = run.write(out, name)
            files[name], files[f"{name}_truth"] = log.name, tr.name
        out.mkdir(parents=True, exist_ok=True)
        (out / "perturbation.json").write_text(json.dumps(truth, indent=1) + "\n")
        files["perturbation"] = "perturbation.json"
    bodies = truth["bodies"]
    return {"robot": robot_name, "seed": seed, "joints": truth["joint_names"],
            "coulomb_drawn": truth["coulomb"], "viscous_drawn": truth["viscous"],
            "frictionloss": truth["friction"]["frictionloss"], "damping": truth["friction"]["damping"],
            "payload": truth["payload"], "torque_offset": truth["torque_offset"],
            "torque_noise_std": truth["sensors"]["torque_noise_std"],
            "encoder_step": truth["sensors"]["encoder_step"],
            "body_mass_nominal": [bodies[j]["nominal"]["mass"] for j in truth["joint_names"]],
            "body_mass_real": [bodies[j]["real"]["mass"] for j in truth["joint_names"]],
            "excitation": exc.stats(), "task": task.stats(), "files": files,
            "wall_s": time.perf_counter() - t0}


def truth_recording(folder, name, joint_names):
    """The log ``<folder>/<name>.csv`` (what the user has) with the true velocity of its rows
    from ``<name>_truth.csv`` attached (for judging estimates only; no method sees it).

    Parameters
    ----------
    folder : path-like
    name : {"excitation", "task"}
    joint_names : list of str
        The robot's joints, in model order.

    Returns
    -------
    codegen.logs.recording.Recording
    """
    import numpy as np

    from ...core.columns import read_columns
    from ...logs.recording import read_csv
    rec = read_csv(Path(folder) / f"{name}.csv", joint_names)
    header, data = read_columns(Path(folder) / f"{name}_truth.csv")
    col = {h: data[:, i] for i, h in enumerate(header)}
    logged = col["logged"] > 0.5
    if not np.array_equal(col["t"][logged], rec.t):
        raise ValueError(f"{folder}: {name}_truth.csv does not hold the rows of {name}.csv")
    rec.qd = np.column_stack([col[f"qd_{j}"][logged] for j in joint_names])
    return rec


def observe(robot_name, out, seed=0, T=T_TASK, T_excitation=T_EXCITATION, families=None,
            torque_noise_of="effort", reference=False, progress=True):
    """What a user of the real arm does, judged against the plant's truth: identify the robot on
    the excitation log, then run the observers on the task log twice, with the identified model
    and with the URDF as shipped, against the baselines tuned on the truth.

    The excitation is ``codegen.logs.identify.excitation`` (what `excite` writes; the plain
    multi-sine leaves the wrist's parameters undetermined on this plant); the observers' design
    states the encoder step and, with the identified model, the torque residual that
    identification measured on its held-out tail (N m per joint).

    Parameters
    ----------
    robot_name : {"ur5", "panda", "kinova"}
    out : path-like
        Folder of the logs (``experiment``'s files), ``identified/`` (the identified URDF, side
        file and report) and ``compare_identified/``, ``compare_urdf/`` (tables and figures).
    seed, T, T_excitation
        As in ``runs``.
    families : sequence of str, optional
        Observer families (default ``codegen.evaluate.compare.DEFAULT_FAMILIES``).
    torque_noise_of : {"effort", "rms"}
        As in ``runs``.
    reference : bool
        Run the observers with the numpy reference instead of the compiled C.
    progress : bool
        Progress bars on stderr.

    Returns
    -------
    dict
        The summary: identification (friction found against the plant's, torque residual
        against the sensor's noise; or the refusal, when the log does not determine the model,
        and then the URDF alone), and per model the observers' and the best baseline's RMS
        after t_ss, their ratio, the convergence time and whether every sample is finite.
    """
    from dataclasses import replace

    import numpy as np

    from ..compare import DEFAULT_FAMILIES, compare, design_inputs
    from ...logs.identify import IdentificationError, identify
    from ...logs.identify import excitation as identify_excitation
    out = Path(out)
    robot = robot_model(robot_name)
    ex = identify_excitation(robot, T=T_excitation, seed=seed, progress=progress)
    summary = experiment(robot_name, out=out, seed=seed, T=T, T_excitation=T_excitation,
                         excitation=lambda t: tuple(a[0] for a in ex.at(t)), torque_noise_of=torque_noise_of)
    truth = json.loads((out / "perturbation.json").read_text())
    joints = robot.joint_names
    task = truth_recording(out, "task", joints)
    step = float(truth["sensors"]["encoder_step"])
    models = {"urdf": (robot, design_inputs(quantization=step))}
    try:
        ident = identify(replace(truth_recording(out, "excitation", joints), qd=None), robot,
                         progress=progress)
    except IdentificationError as e:        # what the user is told; the URDF is all they have
        summary["identification"] = {"refused": str(e)}
        ident = None
    if ident is not None:
        models = {"identified": _identified(ident, out, robot, truth, summary, step), **models}
    t_ss = float(task.t[0] + (task.t[-1] - task.t[0]) / 2)
    for label, (model, design) in models.items():
        cmp = compare(task, model, families=families or DEFAULT_FAMILIES, design=design, t_ss=t_ss,
                      reference=reference, title=f"real {robot_name} ({label} model)", progress=progress)
        folder = out / f"compare_{label}"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "table.txt").write_text(cmp.table() + "\n" + cmp.verdict() + "\n")
        cmp.figures(folder)
        best = cmp.best_baseline()
        summary[f"observers_{label}"] = {
            e.name: {"rms": float(e.metrics["rms"]), "ratio": float(e.metrics["rms"] / best.metrics["rms"]),
                     "t_conv": float(e.metrics.get("t_conv", np.inf)),
                     "finite": bool(np.all(np.isfinite(e.est))), "note": e.note}
            for e in cmp.entries if e.kind == "observer"}
        summary[f"best_baseline_{label}"] = {"name": best.name, "rms": float(best.metrics["rms"])}
        summary[f"verdict_{label}"] = cmp.verdict()
    return summary


def _identified(ident, out, robot, truth, summary, step):
    """(identified robot, design inputs) of ``observe``, its files written to ``out/identified``
    and ``summary["identification"]`` filled: friction found against the plant's, the held-out
    residual against the sensor's noise."""
    import numpy as np

    from models import load_robot

    from ..compare import design_inputs
    files = ident.write(Path(out) / "identified")
    report, joints = ident.report, robot.joint_names
    found = {k: np.array([report["friction"][j][k] for j in joints]) for k in ("viscous", "coulomb")}
    plant = {"viscous": np.array(truth["viscous"]), "coulomb": np.array(truth["coulomb"])}
    noise = np.array(truth["sensors"]["torque_noise_std"] if truth["sensors"]["torque_noise_std"][0] is not None
                     else summary["excitation"]["torque_error_std"])
    residual = np.array([report["residual_rms"]["after"][j] for j in joints])
    summary["identification"] = {
        "friction_error": {k: (np.abs(found[k] - plant[k]) / plant[k]).round(4).tolist() for k in found},
        "residual_over_noise": (residual / noise).round(3).tolist(), "coulomb_width": report["coulomb_width"],
        "condition_number": report["condition_number"], "files": {k: str(f) for k, f in files.items()}}
    model = load_robot(urdf=files["urdf"], locked_joints=robot.source.get("locked_joints") or None)
    return model, design_inputs(quantization=step, torque_uncertainty=residual.tolist())


def _scenario(robot_name):
    def run(reference=False, out=None, T=T_TASK):
        if out is None:
            import tempfile
            with tempfile.TemporaryDirectory() as tmp:
                return observe(robot_name, tmp, T=T, reference=reference)
        return observe(robot_name, out, T=T, reference=reference)
    run.__doc__ = (f"Real {robot_name} on MuJoCo, what its user does (``observe``): the excitation and "
                   f"task logs with their truth, identification on the excitation, the default observers "
                   f"(compiled C, or the numpy reference with ``reference``) against the tuned baselines "
                   f"on the task with the identified model and with the URDF; ``out`` the folder, ``T`` "
                   f"the task run's length (s).")
    return run


SCENARIOS = {f"mujoco-{name}-real": _scenario(name) for name in ROBOTS}
