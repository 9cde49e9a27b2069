"""The log-grid judged: what a user's log gives, with the truth kept aside (codegen.evaluate.scenarios.
log_grid's cells, codegen.logs read as a user would).

For each cell, only the task log is given to the tool (``compare`` on the CSV: its clock rebuilt,
its noise measured, every family and baseline tuned on it without truth, kalman_model's variant
chosen on it); the model is the URDF as shipped (``model="urdf"``) or the one ``identify`` finds on
the cell's excitation log (``model="identified"``, its held-out residual stated as the torque
uncertainty). Then the truth judges:

* the clock: the fraction of kept rows on their true tick (``log_grid.score_clock``), whether
  exactly the repeated rows were dropped;
* every method's RMS error against the true velocity over the second half, as a multiple of the
  constant-acceleration Kalman filter tuned on the truth on the true sample times
  (``log_grid.kalman_truth``: the strongest user's baseline);
* each tuned family against its own best bandwidth on the truth: its gains scaled by s over a
  grid of half-octaves (and around the tuned scale), each stable one (the stability check over
  the step range) run against the truth, the best kept;
* the wall time of ``compare``, and that every estimate is finite.

    python -m codegen simulate log-judge --out /work/grid/log-grid [--T ...]
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

DESCRIPTIONS = {"log-judge": "the log-grid's cells judged against their truth: the rebuilt clock, the methods "
                             "tuned on each log vs the Kalman filter tuned on the truth, each family vs its own "
                             "best gain"}
SCALES = 2.0 ** np.arange(-6.0, 6.01, 0.5)      # the truth's grid of bandwidth scales


def judge(folder, model="urdf", families=None, progress=False):
    """Judge one cell (module docstring).

    Parameters
    ----------
    folder : path-like
        A cell of the log-grid (task.csv, task_truth.csv, excitation.csv, cell.json).
    model : {"urdf", "identified"}
        The robot model the observers are built on.
    families : sequence of str, optional
        Default ``codegen.evaluate.compare.DEFAULT_FAMILIES``.
    progress : bool
        Progress bars on stderr.

    Returns
    -------
    dict
        JSON-ready: clock, kalman_truth, per method its RMS and ratio to it, per tuned family its
        truth-best scale and ratio, compare's wall time, all finite.
    """
    from ..compare import DEFAULT_FAMILIES, compare, observer_block, _link_velocity_slots
    from ...logs import tune as tuning
    from ...logs.recording import read_log
    from .log_grid import _parse, kalman_truth, read_rows, score_clock
    from .mujoco_real import robot_model
    folder = Path(folder)
    robot_name = _parse(folder.name)[0]
    robot = robot_model(robot_name)
    rows = read_rows(folder, "task")
    out = {"cell": folder.name, "model": model}
    design = {}
    if model == "identified":
        robot, design, out["identification"] = _identified(folder, robot, progress)
    elif model != "urdf":
        raise ValueError(f"model: expected urdf or identified, got {model!r}")
    t0 = time.perf_counter()
    rec, clock = read_log(folder / "task.csv", robot.joint_names)
    truth = rows["qd"][clock.kept]
    t_ss = float(rec.t[0] + (rec.t[-1] - rec.t[0]) / 2)
    cmp = compare(rec, robot, families=families or DEFAULT_FAMILIES, design=design, t_ss=t_ss, clock=clock,
                  progress=progress)
    out["compare_s"] = round(time.perf_counter() - t0, 1)
    out["clock"] = {"kind": clock.kind, "text": clock.describe()}
    if clock.ticks is not None:
        out["clock"].update(score_clock(rows, clock.kept, clock.ticks))
    else:
        out["clock"]["repeats_dropped_exactly"] = bool(len(clock.kept) == len(rows["t"]) - int(rows["repeat"].sum())
                                                       or not rows["repeat"].any())
    kf = kalman_truth(rows, _measurement_variance(rec))
    out["kalman_truth"] = kf
    w = rec.t >= t_ss

    def rms(est):
        e = est[w] - truth[w]
        return float(np.sqrt(np.mean(np.sum(e * e, axis=1)))) if np.all(np.isfinite(e)) else math.inf
    out["methods"] = {}
    for e in cmp.entries:
        out["methods"][e.name] = {"kind": e.kind, "rms": rms(e.est), "ratio": rms(e.est) / kf["rms"],
                                  "validation_rms": e.metrics.get("validation_rms"), "variant": e.variant,
                                  "tuned": None if e.tuned is None else e.tuned.params,
                                  "finite": bool(np.all(np.isfinite(e.est))), "note": e.note}
    out["families"] = {}
    for e in cmp.entries:
        if e.kind != "observer" or e.tuned is None:
            continue
        spec = _spec(e, robot)
        obs, _ = observer_block(spec, rec.dt)
        slots = _link_velocity_slots(spec, robot)
        tune = tuning.bandwidth(e.name.split(":")[0], spec.p_names)
        p0 = np.array(spec.p_default, dtype=float)
        scales = np.unique(np.concatenate([SCALES, e.tuned.scale * SCALES[np.abs(np.log2(SCALES)) <= 3]]))
        errs = {}
        for s in scales:
            p = tuning.scaled(spec.p_names, p0, tune, float(s))
            try:
                tuning.check_candidate(obs, spec, tune, p)       # the admissible gains: stable over the step range
            except ValueError:
                continue
            errs[float(s)] = rms(tuning.run_with(obs, p, rec.q, rec.tau, rec.t, obs.dt_limit)[:, slots])
        best = min(errs, key=errs.get)
        out["families"][e.name] = {"best_scale": best, "best_rms": errs[best], "tuned_scale": e.tuned.scale,
                                   "tuned_rms": out["methods"][e.name]["rms"],
                                   "ratio": out["methods"][e.name]["rms"] / errs[best]}
    observers = [m for m in out["methods"].values() if m["kind"] == "observer"]
    out["best_observer_ratio"] = min(m["ratio"] for m in observers)
    out["kalman_model_ratio"] = out["methods"].get("kalman_model", {}).get("ratio")
    out["all_finite"] = all(m["finite"] for m in out["methods"].values())
    return out


def _measurement_variance(rec):
    from ...logs.noise import measure
    return float(np.mean(measure(rec.t, rec.q).sigma ** 2))


def _spec(entry, robot):
    """The spec an entry ran with (its family, build arguments and variant)."""
    from ...families import observers
    return observers.build(entry.name.split(":")[0], robot, **(entry.build or {}))


def _identified(folder, robot, progress):
    """(identified robot, design inputs with its held-out residual, summary) of the cell's
    excitation log, read on its clock."""
    from models import load_robot

    from ..compare import design_inputs
    from ...logs.identify import identify
    from ...logs.recording import read_log
    rec, _ = read_log(Path(folder) / "excitation.csv", robot.joint_names)
    ident = identify(rec, robot, progress=progress)
    files = ident.write(Path(folder) / "identified")
    residual = [ident.report["residual_rms"]["after"][j] for j in robot.joint_names]
    model = load_robot(urdf=files["urdf"], locked_joints=robot.source.get("locked_joints") or None)
    return model, design_inputs(None, None, torque_uncertainty=residual), {"residual": residual}


def judge_all(out, model="urdf", names=None, progress=True):
    """``judge`` every cell folder under ``out`` (or ``names`` of them), a progress bar on stderr
    (``progress``); writes ``out/judged-<model>.json`` and returns the summary: the worst of each
    criterion over the cells."""
    import sys

    from ...core.progress import bar
    out = Path(out)
    if names is None:
        folders = sorted(p for p in out.iterdir() if not p.name.startswith(".") and (p / "task_truth.csv").is_file())
    else:
        folders = [out / n for n in names]
    cells = {}
    for folder in bar(folders, desc="log-judge", unit="cell", file=sys.stderr, disable=not progress):
        cells[folder.name] = judge(folder, model)
        (out / f"judged-{model}.json").write_text(json.dumps(cells, indent=1, default=float) + "\n")
    return summary(cells)


def summary(cells):
    """The worst of each criterion over the judged ``cells`` (dict of ``judge`` results)."""
    fam = [f["ratio"] for c in cells.values() for f in c["families"].values()]
    ticks = [c["clock"]["tick_fraction"] for c in cells.values() if "tick_fraction" in c["clock"]]
    return {"cells": len(cells),
            "clock_tick_fraction_min": min(ticks) if ticks else None,
            "repeats_dropped_exactly": all(c["clock"].get("repeats_dropped_exactly", True) for c in cells.values()),
            "best_observer_ratio_max": max(c["best_observer_ratio"] for c in cells.values()),
            "kalman_model_ratio_max": max((c["kalman_model_ratio"] for c in cells.values()
                                           if c["kalman_model_ratio"] is not None), default=None),
            "family_over_its_best_max": max(fam) if fam else None,
            "compare_s_max": max(c["compare_s"] for c in cells.values()),
            "all_finite": all(c["all_finite"] for c in cells.values())}


def _scenario(reference=False, out=None, T=None, jobs=1):
    if out is None:
        raise ValueError("log-judge: give --out, the folder of the log-grid's cells")
    return {"urdf": judge_all(out, "urdf")}


_scenario.__doc__ = ("The log-grid's cells in ``out`` judged against their truth (module docstring) with the "
                     "URDF as shipped; writes judged-urdf.json there (``reference``, ``T``, ``jobs`` unused).")
SCENARIOS = {"log-judge": _scenario}
