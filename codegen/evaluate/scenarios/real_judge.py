"""The user's flow on the real arms' logs, judged against their truth (codegen.evaluate.scenarios.
real_logs: the logs, their CSVs, the true sample clock).

A ``Bed`` runs the commands a user runs (``describe`` -> ``identify`` on one part -> ``compare`` on a
held-out part with the identified model -> ``build`` of the winning observer), each as a
subprocess with its wall time, and keeps their outputs; then the truth judges:

* **identification**: the held-out log's torque against each model's inverse dynamics,

      r_i = RMS_k  LP10[tau_ik - (RNEA(q_k, qd_k, qdd_k) + tau_f(qd_k))_i]

  per joint i, LP10 the zero-phase 10 Hz low-pass (codegen.logs.identify.lowpass), q's derivatives
  zero-phase smoothed at ``DERIVATIVE_CUTOFF`` on the true sample clock, the shipped URDF (its own
  friction: none, as a rule) against the identified one (its friction side file read); and whether
  every identified URDF loads and is physical (each body: mass > 0, principal moments > 0 and
  each at most the sum of the other two);
* **velocity**: compare's best method (observers and filters, not the robot's signal) on the
  held-out log against a constant-acceleration Kalman filter (codegen.evaluate.baselines) tuned on
  the same reference on the true sample clock, both scored on the log's true samples after its
  middle. The reference is the zero-phase one of q (codegen.logs.reference) on the true clock at
  the cut-off that agrees best with the robot's velocity signal (``sharp_reference``), not the
  signal itself: both arms' signals carry noise of their own (docs/guide/real-logs.md), and the
  Gen3's is one of compare's inputs.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from . import real_logs

DERIVATIVE_CUTOFF = 20.0        # Hz: q's zero-phase derivatives for the inverse dynamics
RESIDUAL_CUTOFF = 10.0          # Hz: the torque residual's zero-phase low-pass
# arm -> (identified on, compare on); the flow of each arm
FLOWS = {"panda": ("panda-first-half", "panda-second-half"),
         "gen3": ("gen3-testing1", "gen3-quadratic"),
         "ur10e": ("ur10e-50s", "ur10e-ptp"),
         "ur5": ("ur5-no6", "ur5-no7")}
# (identified on, held out): the identification's pairs
PAIRS = (("panda-first-half", "panda-second-half"), ("gen3-testing1", "gen3-testing2"),
         ("gen3-testing1", "gen3-quadratic"), ("ur10e-50s", "ur10e-ptp"),
         ("ur10e-14harm-load", "ur10e-15harm-load"))
NO_LOAD = ("ur10e-14harm", "ur10e-15harm-load")     # the same trajectory without the payload
LOCKS = {"panda": {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}}
VELOCITY_LOGS = ("panda-second-half", "gen3-quadratic")
CUTOFFS = 2.0 ** np.arange(0.0, 6.01, 0.5)      # Hz: the sharp reference's candidates


class Bed:
    """The real logs' CSVs and the commands' outputs in the folder ``work`` (created), each run
    once; ``where`` the real-log folder (default ``real_logs.folder()``)."""

    def __init__(self, work, where=None):
        self.work = Path(work)
        self.work.mkdir(parents=True, exist_ok=True)
        self.where = where
        self._logs, self._csv, self._runs, self.times = {}, {}, {}, {}

    def log(self, name):
        """The real_logs.Log ``name``."""
        if name not in self._logs:
            self._logs[name] = real_logs.load(name, self.where)
        return self._logs[name]

    def csv(self, name):
        """(csv path, robot options) of the log ``name``, written once."""
        if name not in self._csv:
            self._csv[name] = real_logs.write_log(self.log(name), self.work / "logs")
        return self._csv[name]

    def run(self, key, args):
        """``python -m codegen *args`` once per ``key``: {"ok", "seconds", "stdout", "stderr"}."""
        if key not in self._runs:
            env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[3]) + os.pathsep
                       + os.environ.get("PYTHONPATH", ""))
            t0 = time.perf_counter()
            p = subprocess.run([sys.executable, "-m", "codegen", *map(str, args)], capture_output=True, text=True,
                               env=env, cwd=self.work)
            self._runs[key] = {"ok": p.returncode == 0, "seconds": round(time.perf_counter() - t0, 1),
                               "stdout": p.stdout, "stderr": p.stderr, "args": [str(a) for a in args]}
            self.times[key] = self._runs[key]["seconds"]
        return self._runs[key]

    def robot_args(self, name, urdf=None):
        """The CLI arguments of log ``name``'s robot: its shipped one, or the URDF ``urdf``."""
        arm = self.log(name).arm
        if urdf is None:
            return real_logs.cli_robot(self.csv(name)[1])
        return ["--urdf", str(urdf)] + [a for j, v in LOCKS.get(arm, {}).items() for a in ("--lock", f"{j}={v:g}")]

    def shipped_urdf(self, name):
        """(path, locked joints) of the shipped URDF of log ``name``'s arm."""
        opts = self.csv(name)[1]
        arm = self.log(name).arm
        if "urdf" in opts:
            return Path(opts["urdf"]), LOCKS.get(arm)
        from models.catalog import _URDFS
        from models.urdf import example_robot_data_dir
        rel, locked = _URDFS[opts["robot"]]
        return example_robot_data_dir() / rel, dict(locked) or None

    def describe(self, name):
        """``describe`` of log ``name``."""
        return self.run(("describe", name), ["describe", self.csv(name)[0], *self.robot_args(name)])

    def identify(self, name):
        """``identify`` of log ``name``: the run, with "urdf" and "report" (paths or None)."""
        out = self.work / "identify" / name
        r = self.run(("identify", name), ["identify", self.csv(name)[0], *self.robot_args(name), "--out", out])
        found = sorted(out.glob("*_identified.urdf")) if r["ok"] else []
        r["urdf"] = found[0] if found else None
        r["report"] = out / "report.json" if found else None
        return r

    def compare(self, arm):
        """``compare`` of the arm's held-out log with the model identified on its other part (the
        shipped one if ``identify`` refused): the run, with "json" (compare.json) and "estimates"."""
        train, test = FLOWS[arm]
        ident = self.identify(train)
        out = self.work / "compare" / test
        extra = ([*self.robot_args(test, ident["urdf"]), "--torque-uncertainty", ident["report"]]
                 if ident["ok"] else self.robot_args(test))
        r = self.run(("compare", test), ["compare", self.csv(test)[0], *extra, "--out", out])
        r["model"] = "identified" if ident["ok"] else "shipped"
        r["json"] = json.loads((out / "compare.json").read_text()) if r["ok"] else None
        r["estimates"] = out / "estimates.csv"
        return r

    def winner(self, arm):
        """The best observer of the arm's ``compare`` (its compare.json row), or None."""
        cmp = self.compare(arm)
        obs = [r for r in (cmp["json"] or {}).get("rows", []) if r["kind"] == "observer" and not r["failed"]]
        return min(obs, key=lambda r: r["rms"]) if obs else None

    def _model_args(self, arm):
        """(robot arguments, torque-uncertainty arguments) of the arm's compare model."""
        train, test = FLOWS[arm]
        ident = self.identify(train)
        if not ident["ok"]:
            return self.robot_args(test), []
        return self.robot_args(test, ident["urdf"]), ["--torque-uncertainty", ident["report"]]

    def design(self, arm):
        """``design`` of the winning observer on the arm's held-out log (as the user builds it:
        its sensor measured and its gains tuned on the log): the run, with "json"."""
        best = self.winner(arm)
        if best is None:
            return {"ok": False, "seconds": 0.0, "stderr": "no observer ran in compare", "json": None}
        test = FLOWS[arm][1]
        robot, unc = self._model_args(arm)
        out = self.work / "design" / f"{arm}.json"
        out.parent.mkdir(parents=True, exist_ok=True)
        r = self.run(("design", arm), ["design", self.csv(test)[0], *robot, *unc, "--family",
                                       best["name"].split(":")[0], "--json", out])
        r["json"] = json.loads(out.read_text()) if r["ok"] else None
        r["family"] = best["name"]
        return r

    def build(self, arm):
        """``build`` of the designed winner (``design``) of ``arm`` at its held-out log's step: the
        run, with "family"."""
        d = self.design(arm)
        if not d["ok"]:
            return {"ok": False, "seconds": 0.0, "stderr": "design failed", "family": d.get("family")}
        robot, _ = self._model_args(arm)
        if robot[0] == "--robot":
            robot = robot[1:]                   # build takes a catalog robot as its positional
        step = json.loads((self.work / "compare" / FLOWS[arm][1] / "compare.json").read_text())
        clock = step.get("clock") or {}
        dt = clock.get("period") or float(np.median(np.diff(self.log(FLOWS[arm][1]).t)))
        args = ["build", *robot, "--family", d["family"].split(":")[0], "--dt", f"{dt:.6g}",
                "--out", self.work / "build", "--name", f"real_{arm}", "--force", "-j", "1"]
        for k, v in (d["json"]["build"] or {}).items():
            if not (k == "uncertainty" and v == 0.0):
                args += ["--design", f"{k}={json.dumps(v)}"]
        for k, v in ((d["json"]["tuned"] or {}).get("params") or {}).items():
            args += ["--param", f"{k}={v:.6g}"]
        if d["json"].get("variant"):
            args += ["--variant", d["json"]["variant"]]
        r = self.run(("build", arm), args)
        r["family"] = d["family"]
        return r

    def flow(self, arm):
        """The user's flow of ``arm``: {step: {"ok", "seconds", "error"}} for describe, identify,
        compare, design and build of the winner (the error: the step's error line when it failed)."""
        train, test = FLOWS[arm]
        steps = {"describe": self.describe(test), "identify": self.identify(train),
                 "compare": self.compare(arm), "design": self.design(arm), "build": self.build(arm)}
        return {k: {"ok": r["ok"], "seconds": r["seconds"],
                    "error": "" if r["ok"] else _last_line(r.get("stderr", ""))} for k, r in steps.items()}


def _last_line(text):
    """The error line of a command's stderr (progress bars dropped)."""
    lines = [ln.split("\r")[-1].strip() for ln in text.replace("\r\n", "\n").splitlines()]
    errors = [ln[ln.index("error:"):] for ln in text.replace("\r", "\n").splitlines() if "error:" in ln]
    lines = [ln for ln in lines if ln]
    return errors[-1] if errors else (lines[-1] if lines else "")


# ------------------------------------------------------------------------------ identification

def physical(urdf, locked=None):
    """[] when every moving body of the ``urdf`` file (pinocchio's, the ``locked`` joints reduced) has mass > 0 and
    an inertia about its centre of mass with principal moments > 0 and the triangle inequalities
    I_a <= I_b + I_c; else one line per body that breaks them."""
    from ...reference.robots.urdf import UrdfRobot
    model = UrdfRobot(urdf, None, locked, 0.0).model
    bad = []
    for i in range(1, model.njoints):
        Y = model.inertias[i]
        m, ev = float(Y.mass), np.linalg.eigvalsh(np.asarray(Y.inertia))
        if not (m > 0 and ev[0] > 0 and ev[2] <= ev[0] + ev[1]):
            bad.append(f"body of {model.names[i]}: mass {m:.3g} kg, principal moments "
                       f"{', '.join(f'{e:.3g}' for e in ev)} kg m^2")
    return bad


def torque_residual(log, urdf, locked=None):
    """(n,) RMS of the 10 Hz low-passed torque residual of ``log`` against the model of ``urdf``
    (its friction side file read; the ``locked`` joints held), on the log's true sample clock
    (module docstring)."""
    import pinocchio as pin

    from ...logs.identify import lowpass
    from ...logs.smoothing import derivatives
    from ...reference.robots.urdf import UrdfRobot
    tr = real_logs.truth(log)
    t, q, tau = tr.t[tr.kept], log.q[tr.kept], log.tau[tr.kept]
    cut = min(DERIVATIVE_CUTOFF, 0.4 * 0.5 / float(np.median(np.diff(t))))
    d = derivatives(t, q, cut)
    ref = UrdfRobot(urdf, None, locked, 0.0)
    data = ref.model.createData()
    rnea = np.array([pin.rnea(ref.model, data, ref.pin_q(q_), v, a) for q_, v, a in zip(d.q, d.qd, d.qdd)])
    fv, fc, fo, width = _friction(urdf, ref)
    friction = fv * d.qd + fc * np.tanh(d.qd / width) + fo
    e = lowpass(t, tau - rnea - friction, RESIDUAL_CUTOFF)
    edge = max(derivatives_edge(cut), derivatives_edge(RESIDUAL_CUTOFF))
    w = (t >= t[0] + edge) & (t <= t[-1] - edge)
    return np.sqrt(np.mean(e[w] ** 2, axis=0))


def _friction(urdf, ref):
    """(viscous, coulomb, offset, width) of the URDF's joints: its <dynamics> (pinocchio's damping
    and friction of the reduced model ``ref``) and its friction side file (models.urdf), read without
    building the robot (a model that is not physical still has a residual)."""
    import pinocchio as pin

    from models.robot import DEFAULT_COULOMB_WIDTH
    from models.urdf import friction_file_path, read_friction_file
    fv = np.asarray(ref.model.damping, dtype=float)
    fc = np.asarray(ref.model.friction, dtype=float)
    side = friction_file_path(Path(urdf))
    width, offsets = None, {}
    if side.is_file():
        width, offsets = read_friction_file(side, list(pin.buildModelFromUrdf(str(urdf)).names)[1:])
    fo = np.array([offsets.get(j, 0.0) for j in ref.joint_names])
    return fv, fc, fo, float(width or DEFAULT_COULOMB_WIDTH)


def derivatives_edge(cutoff):
    """The seconds a zero-phase filter at ``cutoff`` Hz leaves out at each end."""
    from ...logs.smoothing import EDGE
    return EDGE / cutoff


def judge_identification(bed, train, test):
    """The identification of log ``train`` held out on log ``test``, the commands run by the Bed
    ``bed``: JSON-ready {"ok" (identify ran), "error",
    "loads", "physical" (lines of what breaks), "shipped", "identified" (per-joint residual, N m),
    "ratio" per joint, "mean_ratio", "seconds"}."""
    ident = bed.identify(train)
    log = bed.log(test)
    shipped, locked = bed.shipped_urdf(test)
    out = {"train": train, "test": test, "ok": ident["ok"], "seconds": ident["seconds"],
           "error": "" if ident["ok"] else _last_line(ident["stderr"]), "joints": list(log.joint_names),
           "shipped": torque_residual(log, shipped, locked).tolist()}
    if not ident["ok"]:
        return out
    from models import load_robot
    try:
        load_robot(urdf=ident["urdf"], locked_joints=locked)
        out["loads"] = True
    except Exception as e:              # what a user would see: any refusal counts
        out["loads"], out["load_error"] = False, f"{type(e).__name__}: {e}"
    out["physical"] = physical(ident["urdf"], locked)
    r = torque_residual(log, ident["urdf"], locked)
    out["identified"] = r.tolist()
    out["ratio"] = (r / np.array(out["shipped"])).tolist()
    out["mean_ratio"] = float(np.mean(r) / np.mean(out["shipped"]))
    return out


# ------------------------------------------------------------------------------ velocity

def judge_velocity(bed, name):
    """compare's best method on log ``name`` (the flow's compare, run by the Bed ``bed``) against
    the Kalman filter tuned on the reference on the true clock: JSON-ready {"best", "best_rms", "kalman_rms", "ratio",
    "signal_rms" (the robot's velocity signal), "rows", "reference"}."""
    from ...logs.recording import Recording
    from ...logs.reference import reference_of
    from ..compare import tune_on_reference
    from ...core.columns import read_columns
    arm = bed.log(name).arm
    cmp = bed.compare(arm)
    if FLOWS[arm][1] != name:
        raise ValueError(f"{name}: not the held-out log of a flow ({', '.join(v[1] for v in FLOWS.values())})")
    out = {"log": name, "model": cmp["model"], "ok": cmp["ok"],
           "error": "" if cmp["ok"] else _last_line(cmp["stderr"])}
    if not cmp["ok"]:
        return out
    log = bed.log(name)
    tr = real_logs.truth(log)
    k = tr.kept
    t = tr.t[k]
    rec = Recording(t=t, q=log.q[k], tau=log.tau[k], qd=None, joint_names=list(log.joint_names))
    t_ss = float(t[0] + (t[-1] - t[0]) / 2)
    ref, against = sharp_reference(rec, log.dq[k], t_ss)
    dt = rec.dt
    _, kf = tune_on_reference("kalman", rec.q, t, ref.qd, t_ss, dt, valid=ref.valid)
    w = ref.valid & (t >= t_ss)
    rms = lambda est: float(np.sqrt(np.mean(np.sum((est[w] - ref.qd[w]) ** 2, axis=1))))  # noqa: E731
    rows = [r for r in cmp["json"]["rows"] if r["kind"] != "signal" and not r["failed"]]
    best = min(rows, key=lambda r: r["rms"])
    header, data = read_columns(cmp["estimates"], ValueError)
    cols = [header.index(f"{best['name']}.qd_{j}") for j in log.joint_names]
    est = data[:, cols][k]
    out.update({"best": best["name"], "best_rms": rms(est), "kalman_rms": rms(kf), "rows": int(w.sum()),
                "signal_rms": rms(log.dq[k]), "reference": ref.label, "reference_cutoff": ref.cutoff,
                "reference_vs_signal": against,
                "reference_uncertainty": ref.uncertainty(t, t_ss)})
    out["ratio"] = out["best_rms"] / out["kalman_rms"]
    return out


def sharp_reference(rec, signal, t_ss):
    """(Reference, RMS of it minus ``signal``): the zero-phase reference of q (codegen.logs.reference)
    of ``rec`` (on the true clock) at the cut-off of ``CUTOFFS`` that agrees best with the robot's
    velocity signal after ``t_ss``. The signal's error is its own (its noise, not q's), so
    E||ref - signal||^2 = E||ref - qd||^2 + E||signal - qd||^2 is least where the reference's own
    error is."""
    from ...logs.reference import reference_of
    best = None
    for c in CUTOFFS:
        ref = reference_of(rec, cutoff=c)
        w = ref.valid & (rec.t >= t_ss)
        d = float(np.sqrt(np.mean(np.sum((ref.qd[w] - signal[w]) ** 2, axis=1))))
        if best is None or d < best[1]:
            best = (ref, d)
    return best


# ------------------------------------------------------------------------------ the page

def figures(bed):
    """Every judge on the Bed ``bed``: {"clock": {log: ...}, "identification": [...], "no_load": ...,
    "velocity": {log: ...}, "flow": {arm: ...}} (JSON-ready)."""
    clock = {n: real_logs.judge_clock(bed.log(n), bed.work / "clock") for n in real_logs.CLOCK_LOGS}
    ident = [judge_identification(bed, a, b) for a, b in PAIRS]
    no_load = judge_identification(bed, *NO_LOAD)
    vel = {n: judge_velocity(bed, n) for n in VELOCITY_LOGS}
    flow = {arm: bed.flow(arm) for arm in FLOWS}
    return {"clock": clock, "identification": ident, "no_load": no_load, "velocity": vel, "flow": flow}


def _f(x, spec=".3g"):
    return "-" if x is None else format(x, spec)


def table(fig):
    """The Markdown tables of ``figures``' result ``fig``."""
    lines = ["| log | clock found | period | intervals right (tolerance) | bar |", "|---|---|---|---|---|"]
    for n, c in fig["clock"].items():
        per = "-" if c["period"] is None else f"{1e3 * c['period']:.5g} ms"
        lines.append(f"| {n} | {c['kind']} | {per} | {100 * c['right']:.2f} % of {c['pairs']} "
                     f"({1e6 * c['tol']:.0f} µs) | ≥ {100 * c['share']:.1f} % |")
    lines += ["", "| identified on → held out | identify | physical, loads | residual / shipped per joint | "
              "mean ratio |", "|---|---|---|---|---|"]
    for r in fig["identification"] + [dict(fig["no_load"], train=fig["no_load"]["train"] + " (no load)")]:
        if not r["ok"]:
            lines.append(f"| {r['train']} → {r['test']} | refused: {r['error'][:120]} | - | - | - |")
            continue
        phys = "yes" if not r["physical"] else f"no ({len(r['physical'])} bodies)"
        lines.append(f"| {r['train']} → {r['test']} | {r['seconds']:.0f} s | {phys}, "
                     f"{'yes' if r['loads'] else 'no'} | {', '.join(f'{x:.2f}' for x in r['ratio'])} | "
                     f"{r['mean_ratio']:.2f} |")
    lines += ["", "| held-out log | model | compare's best | its RMS | KF on the true clock | ratio | robot's signal |",
              "|---|---|---|---|---|---|---|"]
    for n, v in fig["velocity"].items():
        if not v["ok"]:
            lines.append(f"| {n} | {v['model']} | compare failed: {v['error'][:120]} | - | - | - | - |")
            continue
        lines.append(f"| {n} | {v['model']} | {v['best']} | {v['best_rms']:.3g} rad/s | {v['kalman_rms']:.3g} | "
                     f"{v['ratio']:.2f} | {v['signal_rms']:.3g} |")
    lines += ["", "| arm | describe | identify | compare | design | build |", "|---|---|---|---|---|---|"]
    for arm, steps in fig["flow"].items():
        cells = [f"{s['seconds']:.0f} s" if s["ok"] else f"failed: {s['error'][:80]}" for s in steps.values()]
        lines.append(f"| {arm} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


BEGIN, END = "<!-- real-logs table: begin -->", "<!-- real-logs table: end -->"


def write_page(fig, path):
    """Replace the tables between ``BEGIN`` and ``END`` of the page at ``path`` with ``table(fig)``;
    returns the path."""
    path = Path(path)
    text = path.read_text()
    if BEGIN not in text or END not in text:
        raise ValueError(f"{path}: no {BEGIN} ... {END} section to write the tables into")
    head, rest = text.split(BEGIN, 1)
    tail = rest.split(END, 1)[1]
    path.write_text(f"{head}{BEGIN}\n{table(fig)}\n{END}{tail}")
    return path
