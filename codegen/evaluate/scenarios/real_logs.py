"""Logs recorded on real arms as a test bed: each log written as the project's recording CSV, the
sample clock its robot's own velocity signal implies (the judge's truth), and the product's clock
judged against it (codegen.evaluate.scenarios.real_judge judges identification, velocity and the
user's flow).

The logs live outside the repository, in the real-log folder: ``$CODEGEN_REAL_LOGS``, else
``../shared/data/real`` beside the repository (``folder``); nothing here copies them. Each arm's
``.npz`` holds t, q, dq (the robot's velocity signal), a torque and, for some, segments and a URDF.
``write_log`` writes one named log (``LOGS``) as t, q_<joint>, tau_<joint> and, where the arm's
velocity signal is given to the product (``ARMS[arm]["qdm"]``), qdm_<joint>.

**The true sample intervals.** Between rows j-1 and j, q moves by dq's mean over the interval
times its length, so over the joints i that move

    dt_j = sum_i dq_ij v_ij / sum_i v_ij^2            (least squares)

with v_ij the robot's velocity at row j (``cur``), j-1 (``prev``) or their mean (``mean``): the
convention is chosen per log as the one with the least residual. The interval is known where its
standard error s_j / sqrt(sum_i v_ij^2) (s_j the fit's residual RMS) is at most a third of the
judged tolerance; a row whose every q equals the previous one while the arm moves (some joint's
velocity above V_MIN) carries no new sample (0). A
fixed-tick arm (the Panda) has whole ticks: round(dt_j / T) T.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ENV = "CODEGEN_REAL_LOGS"
V_MIN = 0.02                # rad/s: a joint slower than this does not enter an interval's fit
CONVENTIONS = ("cur", "mean", "prev")

# per arm: its file, the robot (a catalog name or the URDF in the file), the torque array, whether the
# product gets its velocity signal (qdm_<joint>), the fixed tick (s) when it samples on one, what the
# truth's times are (the stamps, or the velocity signal's intervals) and the judged tolerance (s)
ARMS = {
    "panda": {"file": "panda_real_log.npz", "robot": "panda", "torque": "tau", "qdm": False, "tick": 1e-3,
              "truth": "signal", "tol": 1e-4, "share": 0.995},
    "gen3": {"file": "gen3_real_segments.npz", "robot": None, "torque": "tau", "qdm": True, "tick": None,
             "truth": "signal", "tol": 25e-6, "share": 0.95},
    "ur10e": {"file": "ur10e_real_segments.npz", "robot": None, "torque": "tau", "qdm": False, "tick": None,
              "truth": "stamps", "tol": 5e-4, "share": 0.995},
    "ur5": {"file": "ur5_real_segments.npz", "robot": "ur5", "torque": "tau_target", "qdm": False, "tick": None,
            "truth": "stamps", "tol": 5e-4, "share": 0.995},
}
# name -> (arm, segment (a file stem of seg_names) or None: the whole file, part: whole, first, second)
LOGS = {
    "panda": ("panda", None, "whole"),
    "panda-first-half": ("panda", None, "first"),
    "panda-second-half": ("panda", None, "second"),
    "gen3-testing1": ("gen3", "opti_traj_testing1", "whole"),
    "gen3-testing2": ("gen3", "opti_traj_testing2", "whole"),
    "gen3-quadratic": ("gen3", "RecordTrajectory_quadratic", "whole"),
    "ur10e-50s": ("ur10e", "ur-20_02_12-50sec_12harm", "whole"),
    "ur10e-ptp": ("ur10e", "ur-20_01_17-ptp_10_points", "whole"),
    "ur10e-14harm": ("ur10e", "ur-20_02_19_14harm50sec", "whole"),
    "ur10e-14harm-load": ("ur10e", "ur-20_02_19_14harm50secLoad", "whole"),
    "ur10e-15harm-load": ("ur10e", "ur-20_02_19_15harm50secLoad", "whole"),
    "ur5-no6": ("ur5", "Movement_No6_Acc_slow_Verify_Model", "whole"),
    "ur5-no7": ("ur5", "Movement_No7_Acc_slow_Verify_Model_short", "whole"),
}
CLOCK_LOGS = ("panda", "panda-first-half", "panda-second-half", "gen3-testing1", "gen3-testing2",
              "gen3-quadratic", "ur10e-50s", "ur10e-ptp", "ur10e-15harm-load", "ur5-no7")


def folder(root=None):
    """The real-log folder: ``$CODEGEN_REAL_LOGS`` when set, else ``<root>/../shared/data/real``
    (``root`` default: the repository holding this package); None when it does not exist."""
    given = os.environ.get(ENV)
    if given:
        path = Path(given).expanduser()
    else:
        root = Path(__file__).resolve().parents[3] if root is None else Path(root)
        path = root.parent / "shared" / "data" / "real"
    return path if path.is_dir() else None


def skip_reason():
    """The one line a test prints when the real-log folder is absent."""
    return f"no real-log folder (set {ENV}, or put the logs in ../shared/data/real beside the repository)"


@dataclass
class Log:
    """One real log: rows of the arm's file, as recorded.

    Attributes
    ----------
    name, arm : str
    t : (N,) s, the log's time column
    q, dq, tau : (N, n) rad, rad/s (the robot's velocity signal), N m
    joint_names : list of str
    urdf : str or None
        The URDF text shipped with the data (None: the arm's catalog robot).
    """

    name: str
    arm: str
    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    joint_names: list
    urdf: str | None

    @property
    def spec(self):
        """The arm's entry of ``ARMS``."""
        return ARMS[self.arm]


def load(name, where=None):
    """The Log ``name`` of ``LOGS`` from the real-log folder ``where`` (default ``folder()``)."""
    if name not in LOGS:
        raise KeyError(f"unknown real log {name!r}; known: {', '.join(LOGS)}")
    where = folder() if where is None else Path(where)
    if where is None:
        raise FileNotFoundError(skip_reason())
    arm, segment, part = LOGS[name]
    spec = ARMS[arm]
    with np.load(where / spec["file"], allow_pickle=False) as d:
        rows = slice(None)
        if segment is not None:
            stems = [Path(str(s)).stem for s in d["seg_names"]]
            k = stems.index(segment)
            rows = slice(int(d["seg_start"][k]), int(d["seg_start"][k + 1]))
        t, q, dq, tau = (np.asarray(d[k][rows], dtype=float) for k in ("t", "q", "dq", spec["torque"]))
        joints = [str(j) for j in d["joint_names"]] if "joint_names" in d.files else None
        urdf = str(d["urdf"][0]) if "urdf" in d.files else None
    if part != "whole":
        half = len(t) // 2
        cut = slice(0, half) if part == "first" else slice(half, None)
        t, q, dq, tau = t[cut], q[cut], dq[cut], tau[cut]
    if joints is None or spec["robot"] is not None:
        joints = list(robot_of(spec).joint_names)
    return Log(name, arm, t, q, dq, tau, joints, None if spec["robot"] is not None else urdf)


def robot_of(spec, urdf=None):
    """The shipped robot of an arm's ``spec``: its catalog robot, or the URDF file ``urdf``."""
    from models import load_robot
    return load_robot(spec["robot"]) if spec["robot"] is not None else load_robot(urdf=urdf)


def write_log(log, out):
    """Write ``log`` into the folder ``out``: ``<name>.csv`` (t, q_, tau_ and, where the arm gives
    it, qdm_) and, for an arm without a catalog robot, its URDF ``<arm>.urdf``. Returns (csv path,
    robot options): {"robot": catalog name} or {"urdf": path}."""
    from ...core.columns import write_columns
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cols = {"t": log.t}
    groups = [("q", log.q), ("tau", log.tau)] + ([("qdm", log.dq)] if log.spec["qdm"] else [])
    for g, a in groups:
        for i, j in enumerate(log.joint_names):
            cols[f"{g}_{j}"] = a[:, i]
    path = write_columns(out / f"{log.name}.csv", cols)
    return path, robot_options(log, out)


def robot_options(log, out):
    """{"robot": name} or {"urdf": path} of the log's shipped robot (the URDF written in ``out``)."""
    if log.spec["robot"] is not None:
        return {"robot": log.spec["robot"]}
    urdf = Path(out) / f"{log.arm}.urdf"
    if not urdf.is_file():
        urdf.write_text(log.urdf)
    return {"urdf": urdf}


def cli_robot(options):
    """The CLI arguments of robot ``options`` (``robot_options``)."""
    return ["--robot", options["robot"]] if "robot" in options else ["--urdf", str(options["urdf"])]


# ------------------------------------------------------------------------------ the truth

@dataclass
class Truth:
    """A log's true sample clock (module docstring).

    Attributes
    ----------
    dt : (N-1,) s, the interval between rows j-1 and j (0: a repeated row)
    known : (N-1,) bool, where the interval is known (motion enough to tell, or a repeat)
    moving : (N-1,) bool, intervals where the arm moves enough to tell
    t : (N,) s, the true times of every row (unknown intervals: the arm's nominal step)
    kept : (M,) int, the rows that carry a new sample
    convention : str, which velocity of the interval fits q's increments ("cur", "mean", "prev")
    residual : dict, convention -> relative residual of the fit
    """

    dt: np.ndarray
    known: np.ndarray
    moving: np.ndarray
    t: np.ndarray
    kept: np.ndarray
    convention: str
    residual: dict


def _fit(dQ, v):
    """(dt, standard error, relative residual) of the interval fit, per row, for velocities v."""
    w = np.abs(v) > V_MIN
    den = np.sum(np.where(w, v * v, 0.0), axis=1)
    m = w.sum(axis=1)
    dt = np.sum(np.where(w, dQ * v, 0.0), axis=1) / np.maximum(den, 1e-300)
    res = np.where(w, dQ - dt[:, None] * v, 0.0)
    s2 = np.sum(res * res, axis=1) / np.maximum(m - 1, 1)
    se = np.where(m >= 2, np.sqrt(s2 / np.maximum(den, 1e-300)), np.inf)
    ok = m >= 2
    rel = float(np.sqrt(np.sum(res[ok] ** 2) / max(np.sum((dQ * w)[ok] ** 2), 1e-300)))
    return dt, se, rel


def true_intervals(q, dq, tol, tick=None):
    """(dt (N-1,), known (N-1,) bool, repeat (N-1,) bool, convention, {convention: relative
    residual}) of q's
    increments against the velocity signal dq (module docstring); ``tol`` (s) the tolerance judged
    (an interval is known when its standard error is at most tol / 3), ``tick`` (s) rounds the
    intervals to whole ticks."""
    dQ = np.diff(q, axis=0)
    velocity = {"cur": dq[1:], "prev": dq[:-1], "mean": 0.5 * (dq[1:] + dq[:-1])}
    fits = {c: _fit(dQ, velocity[c]) for c in CONVENTIONS}
    best = min(CONVENTIONS, key=lambda c: fits[c][2])
    dt, se, _ = fits[best]
    repeat = np.all(dQ == 0, axis=1) & (np.max(np.abs(velocity[best]), axis=1) > V_MIN)
    known = se <= tol / 3
    if tick is not None:
        n = np.round(dt / tick)
        known &= np.abs(dt / tick - n) <= 0.25
        dt = n * tick
    dt = np.where(repeat, 0.0, dt)
    return dt, known & ~repeat, repeat, best, {c: fits[c][2] for c in CONVENTIONS}


def truth(log):
    """The Truth of ``log``: from its velocity signal, or the stamps where they are the sample
    times (``ARMS[arm]["truth"]``; their moving intervals still from the signal)."""
    spec = log.spec
    dt, moving, repeat, conv, rel = true_intervals(log.q, log.dq, spec["tol"], spec["tick"])
    steps = np.diff(log.t)
    if spec["truth"] == "stamps":            # sample times: every row a sample
        dt, repeat = steps.copy(), np.zeros_like(repeat)
        known = moving.copy()
    else:
        nominal = spec["tick"] or float(np.median(dt[moving]))
        # the times between the judged intervals: each fit that is good to a tenth of a step (the
        # tick's rounding for a fixed-tick arm), else the stamps' step in whole ticks or the nominal
        _, usable, _, _, _ = true_intervals(log.q, log.dq, 0.3 * nominal, spec["tick"])
        fill = np.maximum(np.round(steps / nominal), 1) * nominal if spec["tick"] else np.full_like(steps, nominal)
        dt = np.where(usable | moving | repeat, dt, fill)
        known = moving
    t = log.t[0] + np.concatenate([[0.0], np.cumsum(dt)])
    kept = np.concatenate([[0], 1 + np.flatnonzero(dt > 0)])
    return Truth(dt, known | repeat, moving, t, kept, conv, rel)


# ------------------------------------------------------------------------------ the clock judged

def judge_clock(log, out):
    """The product's clock on ``log`` (its CSV written in ``out``, read by
    ``codegen.logs.recording.read_log`` with clock "auto") against the Truth: for each pair of
    consecutive kept rows over moving intervals, whether the interval between them is the true one
    to ``ARMS[arm]["tol"]``. Returns a JSON-ready dict: kind, period and its relative error to the
    tick, the share of pairs right, the pairs judged, the repeats dropped, the clock's line."""
    from ...logs.recording import read_log
    path, options = write_log(log, out)
    robot = robot_of(log.spec, options.get("urdf"))
    import time
    t0 = time.perf_counter()
    rec, clock = read_log(path, log.joint_names, clock="auto", robot=robot)
    seconds = time.perf_counter() - t0
    tr = truth(log)
    kept = np.asarray(clock.kept)
    a, b = kept[:-1], kept[1:]
    cum = np.concatenate([[0.0], np.cumsum(tr.dt)])
    bad = np.concatenate([[0], np.cumsum(~tr.known)])
    mov = np.concatenate([[0], np.cumsum(tr.moving)])
    judged = (bad[b] - bad[a] == 0) & (mov[b] - mov[a] > 0)
    err = np.abs(np.diff(rec.t) - (cum[b] - cum[a]))[judged]
    tol = log.spec["tol"]
    out = {"log": log.name, "kind": clock.kind, "period": clock.period, "text": clock.describe(),
           "pairs": int(judged.sum()), "right": float(np.mean(err <= tol)) if len(err) else 0.0,
           "tol": tol, "share": log.spec["share"], "p99_error": float(np.quantile(err, 0.99)) if len(err) else None,
           "rows": len(log.t), "kept": len(kept), "true_kept": len(tr.kept),
           "repeats_true": int(len(log.t) - len(tr.kept)), "convention": tr.convention,
           "known_share": float(np.mean(tr.moving)), "seconds": round(seconds, 2)}
    if log.spec["tick"] is not None:
        out["tick"] = log.spec["tick"]
        out["period_error"] = (abs(clock.period / log.spec["tick"] - 1.0) if clock.period is not None else None)
    return out
