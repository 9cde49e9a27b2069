"""Collision detection on a log: the momentum observer (codegen.families.observers.momentum) run
over a recording, its thresholds set on a collision-free log (codegen.logs.detect), the alarms
grouped into events, and what ``detect`` writes.

    external_torque.csv   t, tau_ext_<joint> (N m), alarm (0/1: any joint), link (1-based, 0: none)
    events.csv            start, end (s), link, then the peak tau_ext_<joint> (signed, N m)
    detect.json           thresholds, their calibration, the observer's parameters, the events
    detect.png            residuals with their thresholds, events shaded
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..logs.detect import FALSE_ALARMS, MERGE, calibrate, episodes

SLOW_LOG_SAMPLES = 10

__all__ = ["Detection", "run_momentum", "detect", "events_of", "write_detection"]


@dataclass
class Detection:
    """The momentum observer over a log: stamps t (N,), qd_hat, tau_ext, alarm (N, n), link (N,),
    the thresholds th0, th1 (n,), the events [{start, end, link, peak}] and the calibration
    (a codegen.logs.detect.Thresholds as a dict, or None for the design's defaults)."""

    joint_names: list
    t: np.ndarray
    qd_hat: np.ndarray
    tau_ext: np.ndarray
    alarm: np.ndarray
    link: np.ndarray
    th0: np.ndarray
    th1: np.ndarray
    events: list = field(default_factory=list)
    calibration: dict | None = None
    params: dict = field(default_factory=dict)
    note: str = ""


def _dt(t):
    return float(np.median(np.diff(t)))


def run_momentum(robot, recording, p=None, spec=None, **build):
    """(spec, estimate (N, 3n + 1), note): the compiled momentum observer for ``robot`` over the
    ``recording`` (its stamps), designed at the log's median step; ``p`` the runtime parameters
    (None: the designed ones); ``build`` keyword arguments of the family."""
    from ..families import observers
    from .compare import run_observer
    t = np.asarray(recording.t, float)
    dt = _dt(t)
    if spec is None:
        spec = observers.build("momentum", robot, dt=dt, **detection_time(dt, build))
    est, note = run_observer(spec, recording.q, recording.tau, dt, t=t, p=p)
    return spec, est, note


def _with_thresholds(spec, th0, th1):
    p = spec.p_default.copy()
    n = spec.robot.n
    p[1 + n:1 + 2 * n], p[1 + 2 * n:1 + 3 * n] = th0, th1
    return p


def events_of(t, alarm, link, tau_ext, merge=MERGE):
    """[{start, end, link, peak}]: the runs of any joint's ``alarm`` (N, n) at the stamps ``t``
    (N,) (closer than ``merge`` s joined), the ``link`` (N,) most often named in each, and the
    signed ``tau_ext`` (N, n) of largest |.| per joint."""
    out = []
    for s, e in episodes(t, np.asarray(alarm).any(axis=1), merge):
        links = link[s:e + 1][link[s:e + 1] > 0].astype(int)
        seg = tau_ext[s:e + 1]
        peak = seg[np.argmax(np.abs(seg), axis=0), np.arange(seg.shape[1])]
        out.append({"start": float(t[s]), "end": float(t[e]),
                    "link": int(np.bincount(links).argmax()) if len(links) else 0, "peak": peak.tolist()})
    return out


def detect(robot, recording, clean=None, false_alarms=FALSE_ALARMS, th0=None, th1=None, **build):
    """Detection on ``recording`` (codegen.logs.recording.Recording) for ``robot``.

    Parameters
    ----------
    clean : Recording, optional
        A collision-free log of the same arm: the thresholds are set on it for ``false_alarms``
        (per hour; codegen.logs.detect.calibrate). None: ``th0``, ``th1`` if given, else the
        design's defaults.
    th0, th1 : (n,) arrays, optional
        Thresholds given (N m, N m s/rad).
    build
        Keyword arguments of the momentum family (gains, torque_noise, ...).

    Returns
    -------
    Detection
    """
    n = robot.n
    spec, notes, calib = None, [], None
    if clean is not None:
        spec, est, note = run_momentum(robot, clean, **build)
        notes.append(note)
        thr = calibrate(clean.t, est[:, n:2 * n], est[:, :n], false_alarms)
        calib = thr.as_dict()
        th0, th1 = np.array(thr.th0), np.array(thr.th1)
    spec = spec if spec is not None else _build(robot, recording, build)
    th0 = spec.p_default[1 + n:1 + 2 * n] if th0 is None else np.broadcast_to(np.asarray(th0, float), (n,))
    th1 = spec.p_default[1 + 2 * n:1 + 3 * n] if th1 is None else np.broadcast_to(np.asarray(th1, float), (n,))
    p = _with_thresholds(spec, th0, th1)
    spec, est, note = run_momentum(robot, recording, p=p, spec=spec)
    notes.append(note)
    t = np.asarray(recording.t, float)
    qd, tau_ext, alarm, link = est[:, :n], est[:, n:2 * n], est[:, 2 * n:3 * n] > 0.5, est[:, 3 * n]
    return Detection(joint_names=list(robot.joint_names), t=t, qd_hat=qd, tau_ext=tau_ext, alarm=alarm,
                     link=link, th0=np.array(th0, float), th1=np.array(th1, float),
                     events=events_of(t, alarm, link, tau_ext), calibration=calib,
                     params=dict(zip(spec.p_names, p.tolist())), note="; ".join(x for x in notes if x))


def _build(robot, recording, build):
    from ..families import observers
    dt = _dt(np.asarray(recording.t, float))
    return observers.build("momentum", robot, dt=dt, **detection_time(dt, build))


def detection_time(dt, build):
    """``build`` with the detection time a log's sample time dt (s) allows when none is given:
    the design's T_DETECT, or SLOW_LOG_SAMPLES samples on a slower log (a 100 Hz logger)."""
    from ..families.design.momentum import T_DETECT
    if "t_detect" in build:
        return build
    return {**build, "t_detect": max(T_DETECT, SLOW_LOG_SAMPLES * dt)}


def write_detection(det, out):
    """Write ``det`` (Detection) into the folder ``out``: the files of the module docstring.
    Returns {name: path}."""
    from ..core.columns import write_columns
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    J = det.joint_names
    cols = {"t": det.t, **{f"tau_ext_{j}": det.tau_ext[:, i] for i, j in enumerate(J)},
            "alarm": det.alarm.any(axis=1).astype(float), "link": det.link}
    paths = {"external_torque": out / "external_torque.csv", "events": out / "events.csv",
             "json": out / "detect.json", "figure": out / "detect.png"}
    write_columns(paths["external_torque"], cols)
    ev = {"start": [e["start"] for e in det.events], "end": [e["end"] for e in det.events],
          "link": [float(e["link"]) for e in det.events],
          **{f"tau_ext_{j}": [e["peak"][i] for e in det.events] for i, j in enumerate(J)}}
    write_columns(paths["events"], ev)
    summary = {"joints": J, "thresholds": {"th0": det.th0.tolist(), "th1": det.th1.tolist(),
                                           "rule": "alarm_j: |tau_ext_j| > th0_j + th1_j |qd_hat_j|"},
               "calibration": det.calibration, "params": det.params, "events": det.events,
               "duration": float(det.t[-1] - det.t[0]), "note": det.note}
    paths["json"].write_text(json.dumps(summary, indent=1))
    figure(det, paths["figure"])
    return paths


def figure(det, path):
    """The figure of ``det`` (Detection) at ``path`` (PNG): residuals with their thresholds (+-),
    one axes per joint, events shaded; returns the path."""
    from .sim.plots import _plt, _save
    plt = _plt()
    n = len(det.joint_names)
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.6 * n + 0.6), sharex=True, squeeze=False)
    th = det.th0 + det.th1 * np.abs(det.qd_hat)
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(det.t, det.tau_ext[:, i], lw=0.7, color="C0")
        ax.plot(det.t, th[:, i], lw=0.6, color="C3", ls="--")
        ax.plot(det.t, -th[:, i], lw=0.6, color="C3", ls="--")
        for e in det.events:
            ax.axvspan(e["start"], max(e["end"], e["start"] + 1e-3), color="C1", alpha=0.25, lw=0)
        ax.set_ylabel(f"{det.joint_names[i]}\n[N m]", fontsize=8)
    axes[0, 0].set_title(f"external torque estimate, thresholds (dashed), {len(det.events)} events (shaded)",
                         fontsize=9)
    axes[-1, 0].set_xlabel("t [s]")
    return _save(fig, path)
