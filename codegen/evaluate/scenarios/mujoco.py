"""Observers and baselines on a plant we did not write: MuJoCo's ur5 and panda.

Plant: the catalog URDF simulated by MuJoCo (codegen.evaluate.sim.mujoco_plant: RK4 at 1e-4 s, no
contacts), computed-torque tracking of 0.15-0.35 Hz sinusoids (amplitude 0.6 rad, peak speed
1.3 rad/s) with MuJoCo's own inverse dynamics on the true state, torque held over each 1 ms
sample. Its masses and inertias can be off the model by ``mismatch`` (all x (1 + mismatch)).

Sensor: q sampled at 1 kHz, plus seeded Gaussian noise ``noise`` (rad), then quantised to
``quantization`` (rad) (codegen.evaluate.sim.sensors.Sensor). The controller uses the true state, so the
motion does not depend on the sensor and one simulation serves every sensor setting.

Methods (codegen.evaluate.compare): the default observers (compiled C, the loop in C; numpy reference
with ``reference=True``) built on the nominal model, and the baselines of codegen.evaluate.baselines,
each tuned over its own parameter grid on the same run.

    python -m codegen simulate mujoco-ur5 [--quantization 1e-4] [--noise S] [--mismatch 0.1]
    python -m codegen compare mujoco-panda --quantization 1e-4
"""
from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

ROBOTS = ("ur5", "panda")
T_DEFAULT = 20.0
DT = 1e-3


def plant_run(robot, T, mismatch=0.0, seed=0):
    """The true run of the module docstring on any URDF ``robot`` (models.RobotModel; locked
    joints held where the robot holds them): T s, masses and inertias x (1 + mismatch), phases
    drawn with ``seed``."""
    from ..sim.blocks import stage
    from ..sim.mujoco_plant import MujocoPlant, sinusoids
    stage(f"MuJoCo {robot.name}: {T:g} s of computed-torque tracking at {1 / DT:g} Hz")
    return MujocoPlant(robot, mismatch=mismatch).track(sinusoids(robot, seed=seed), T, dt=DT)


@lru_cache(maxsize=8)
def _true_run(robot_name, T, mismatch, seed):
    from models import load_robot
    return plant_run(load_robot(robot_name), T, mismatch, seed)


def recording(robot_name, T=T_DEFAULT, quantization=0.0, noise=0.0, mismatch=0.0, seed=0):
    """The measured run: true qd and applied tau of the MuJoCo plant, q as the sensor gives it.

    Parameters
    ----------
    robot_name : {"ur5", "panda"} or models.RobotModel
        A catalog robot of the scenarios, or any URDF robot (``plant_run``).
    T : float
        Length (s).
    quantization, noise : float
        Encoder step and Gaussian standard deviation (rad); 0: none.
    mismatch : float
        Relative error of the plant's masses and inertias.
    seed : int
        Seed of the reference phases and of the noise.

    Returns
    -------
    codegen.logs.recording.Recording
    """
    from ..sim.sensors import measured
    if not isinstance(robot_name, str):
        return measured(plant_run(robot_name, float(T), float(mismatch), int(seed)), quantization, noise, seed)
    if robot_name not in ROBOTS:
        raise ValueError(f"robot: the MuJoCo scenarios have {', '.join(ROBOTS)}, got {robot_name!r}")
    return measured(_true_run(robot_name, float(T), float(mismatch), int(seed)), quantization, noise, seed)


def title(robot_name, quantization=0.0, noise=0.0, mismatch=0.0):
    """The heading of a run's table and figures: ``robot_name``, ``quantization`` and ``noise``
    (rad), ``mismatch`` (relative)."""
    return (f"MuJoCo {robot_name}: quantisation {quantization:g} rad, noise {noise:g} rad, "
            f"mismatch {mismatch:g}")


def experiment(robot_name, T=T_DEFAULT, quantization=0.0, noise=0.0, mismatch=0.0, seed=0,
               reference=False, out=None):
    """Run the comparison of observers and tuned baselines on one MuJoCo run.

    Parameters
    ----------
    robot_name, T, quantization, noise, mismatch, seed
        The run, as in ``recording``.
    reference : bool
        Observers by the numpy reference instead of the compiled C.
    out : path-like, optional
        Folder for the run (``run.csv``, the compare CSV format), the figures and ``table.txt``.

    Returns
    -------
    dict
        The summary: the run's settings, the best baseline, the table and one row per method.
    """
    from models import load_robot

    from ..compare import compare, design_inputs
    from ..sim.blocks import staged
    rec = recording(robot_name, T, quantization, noise, mismatch, seed)
    cmp = compare(rec, load_robot(robot_name), design=design_inputs(quantization, noise, mismatch),
                  reference=reference, title=title(robot_name, quantization, noise, mismatch),
                  progress=staged())
    if out is not None:
        out = Path(out)
        rec.write_csv(out / "run.csv")
        cmp.figures(out)
        (out / "table.txt").write_text(cmp.table() + "\n")
    best = cmp.best_baseline()
    return {"robot": robot_name, "T": T, "quantization": quantization, "noise": noise,
            "mismatch": mismatch, "best_baseline": best.name if best else None,
            "table": "\n" + cmp.table(),
            "methods": {r.pop("name"): r for r in json.loads(json.dumps(cmp.rows(), default=float))}}


def _scenario(robot_name):
    def run(reference=False, out=None, quantization=0.0, noise=0.0, mismatch=0.0, T=T_DEFAULT):
        return experiment(robot_name, T=T, quantization=quantization, noise=noise, mismatch=mismatch,
                          reference=reference, out=out)
    run.__doc__ = f"MuJoCo {robot_name}: observers and tuned baselines (see codegen.evaluate.scenarios.mujoco)."
    return run


SCENARIOS = {f"mujoco-{name}": _scenario(name) for name in ROBOTS}
DESCRIPTIONS = {f"mujoco-{name}": f"beyond the papers: observers vs tuned filters on MuJoCo's {name} "
                "(errors.png, joint0.png)" for name in ROBOTS}
