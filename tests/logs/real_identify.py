"""The real arms' logs as `identify` reads them, and the judge of an identified model (tests only).

A log is written as the CSV a user would give (t, t_robot, q_<joint>, tau_<joint>) with its true
sample clock in the robot-time column: for the Panda and the Gen3, recovered from the robot's own
velocity signal dq (per interval, the least squares over the joints of the increments of q
against the mean of dq at its two ends: dt = sum_j v_j dq_j / sum_j v_j^2, v = (dq_k + dq_{k-1})/2,
the Panda's rounded to whole 1 ms ticks); the UR logs' stamps are their sample times.

The judge: the held-out torque residual per joint through a 10 Hz zero-phase low-pass (q's
velocity and acceleration by the same zero-phase smoothing, tau through the same filter), of the
identified URDF with its friction against the shipped URDF without friction.
"""
import os
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
JUDGE_HZ = 10.0
EDGE_S = 0.5                      # the filter's edges left out of the judge (s)


def real_dir():
    """The real-log folder ($CODEGEN_REAL_LOGS or ../shared/data/real), or None."""
    d = Path(os.environ.get("CODEGEN_REAL_LOGS") or ROOT.parent / "shared" / "data" / "real")
    return d if d.is_dir() else None


def robot_times(t, q, dq, tick=None, still=1e-3):
    """Sample times from the robot's velocity signal (module docstring); ``tick`` (s) rounds each
    interval to whole ticks (0: a repeated row); where the arm is still (|v| < ``still`` rad/s
    on every joint) the stamps' interval (whole ticks, at least one, with ``tick``)."""
    dQ = np.diff(q, axis=0)
    v = 0.5 * (dq[1:] + dq[:-1])
    vv = np.sum(v * v, axis=1)
    moving = np.sqrt(vv) > still
    dt = np.where(moving, np.sum(v * dQ, axis=1) / np.where(moving, vv, 1.0), np.diff(t))
    if tick:
        k = np.round(dt / tick)
        k[~moving] = np.maximum(k[~moving], 1)
        dt = np.maximum(k, 0) * tick
    else:
        med = np.median(dt[moving])
        dt = np.where(dt < 0.25 * med, 0.0, dt)          # a repeated row: no time passed
    return t[0] + np.concatenate([[0.0], np.cumsum(dt)])


def segment(data, name):
    """Rows of the segment whose name ends with ``name`` in a *_segments.npz."""
    names = [str(s) for s in data["seg_names"]]
    k = next(i for i, s in enumerate(names) if s.endswith(name) or Path(s).stem == name)
    a, b = int(data["seg_start"][k]), int(data["seg_start"][k + 1])
    return slice(a, b)


def write_log(path, t, t_robot, q, tau, joints):
    """The CSV (t, t_robot, q_<joint>, tau_<joint>) of a log."""
    from codegen.core.columns import write_columns
    cols = {"t": t, "t_robot": t_robot}
    cols.update({f"q_{j}": q[:, k] for k, j in enumerate(joints)})
    cols.update({f"tau_{j}": tau[:, k] for k, j in enumerate(joints)})
    return write_columns(path, cols)


def logs(folder, tmp):
    """{case: (robot, train CSV, [held-out CSVs])} of the real logs (module docstring)."""
    from models import load_robot
    out = {}
    d = np.load(folder / "panda_real_log.npz")
    panda = load_robot("panda")
    t, q, dq, tau = d["t"], d["q"], d["dq"], d["tau"]
    tr = robot_times(t, q, dq, tick=1e-3)
    half = len(t) // 2
    out["panda"] = (panda, write_log(tmp / "panda_1.csv", t[:half], tr[:half], q[:half], tau[:half],
                                     panda.joint_names),
                    [write_log(tmp / "panda_2.csv", t[half:], tr[half:], q[half:], tau[half:], panda.joint_names)])
    d = np.load(folder / "gen3_real_segments.npz")
    (tmp / "gen3.urdf").write_text(str(d["urdf"][0]))
    gen3 = load_robot(urdf=tmp / "gen3.urdf")
    joints = [str(j) for j in d["joint_names"]]

    def gen3_log(name):
        s = segment(d, name)
        t, q, dq, tau = d["t"][s], d["q"][s], d["dq"][s], d["tau"][s]
        return write_log(tmp / f"gen3_{name}.csv", t, robot_times(t, q, dq), q, tau, joints)
    out["gen3"] = (gen3, gen3_log("opti_traj_testing1"),
                   [gen3_log("opti_traj_testing2"), gen3_log("RecordTrajectory_quadratic")])
    d = np.load(folder / "ur10e_real_segments.npz")
    (tmp / "ur10e.urdf").write_text(str(d["urdf"][0]))
    ur10e = load_robot(urdf=tmp / "ur10e.urdf")
    joints = [str(j) for j in d["joint_names"]]

    def ur_log(name):
        s = segment(d, name)
        t = d["t"][s]
        return write_log(tmp / f"ur10e_{name}.csv", t, t, d["q"][s], d["tau"][s], joints)
    out["ur10e"] = (ur10e, ur_log("ur-20_02_12-50sec_12harm"), [ur_log("ur-20_01_17-ptp_10_points")])
    out["ur10e_loaded"] = (ur10e, ur_log("ur-20_02_19_14harm50secLoad"), [ur_log("ur-20_02_19_15harm50secLoad")])
    out["ur10e_loaded_reverse"] = (ur10e, ur_log("ur-20_02_19_15harm50secLoad"), [ur_log("ur-20_02_19_14harm50secLoad")])
    return out


def judge(robot, csv, model=None):
    """RMS per joint (n,) of the measured torque less the model's through the 10 Hz zero-phase
    low-pass, on a log's CSV (its robot-time clock); ``model`` a robot (its URDF's inertials and
    friction), None: ``robot`` as shipped, without friction."""
    from codegen.logs.identify import lowpass
    from codegen.logs.recording import read_log
    from codegen.logs.smoothing import derivatives
    from codegen.reference.robots.urdf import UrdfRobot
    import pinocchio as pin
    rec, _ = read_log(csv, robot.joint_names, robot=robot)
    m = model or robot
    src = m.source
    ref = UrdfRobot(Path(src["path"]), src.get("sha256"), src.get("locked_joints") or {}, src.get("snap_tol", 1e-9))
    t = rec.t
    dv = derivatives(t, rec.q, JUDGE_HZ)
    tau_f = lowpass(t, rec.tau, JUDGE_HZ)
    keep = (t > t[0] + EDGE_S) & (t < t[-1] - EDGE_S)
    pinq = _pin_q(ref.model, dv.q[keep])
    pred = np.array([pin.rnea(ref.model, ref.data, a, b, c) for a, b, c in zip(pinq, dv.qd[keep], dv.qdd[keep])])
    if model is not None:
        v = dv.qd[keep]
        pred = pred + np.asarray(m.viscous) * v + np.asarray(m.coulomb) * np.tanh(v / m.coulomb_width) \
            + np.asarray(m.offset)
    return np.sqrt(np.mean((tau_f[keep] - pred) ** 2, axis=0))


def _pin_q(model, q):
    Q = np.zeros((len(q), model.nq))
    for k, j in enumerate(model.joints[1:]):
        if j.nq == 2:
            Q[:, j.idx_q], Q[:, j.idx_q + 1] = np.cos(q[:, k]), np.sin(q[:, k])
        else:
            Q[:, j.idx_q] = q[:, k]
    return Q


def physical(robot, rho_margin=0.0):
    """Problems (list of str, empty when none) of every moved link of a robot's URDF: mass > 0,
    inertia about the centre of mass positive definite and within the triangle inequalities."""
    bad = []
    for name, m, I in _links(robot):
        lam = np.linalg.eigvalsh(I)
        if not m > 0:
            bad.append(f"{name}: mass {m}")
        if lam[0] <= 0 or lam[0] + lam[1] <= lam[2] * (1 + rho_margin):
            bad.append(f"{name}: inertia eigenvalues {lam}")
    return bad


def _links(robot):
    import xml.etree.ElementTree as ET
    root = ET.parse(robot.source["path"]).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {e.get("name"): e for e in root.findall("link")}
    for jn in robot.joint_names:
        link = links[joints[jn].find("child").get("link")]
        e = link.find("inertial")
        i = e.find("inertia")
        m = float(e.find("mass").get("value"))
        I = np.array([[float(i.get(a)) for a in r] for r in (("ixx", "ixy", "ixz"), ("ixy", "iyy", "iyz"),
                                                                ("ixz", "iyz", "izz"))])
        yield link.get("name"), m, I


def table(folder, tmp):
    """Markdown rows of every case: the held-out log, per joint the shipped URDF's residual and
    the identified one's (N m), the mean ratio, the physical check, identify's wall and CPU time."""
    import time

    from codegen.logs.identify import identify
    from codegen.logs.recording import read_log
    from models import load_robot
    rows, models = [], {}
    for case, (robot, train, held_out) in logs(folder, tmp).items():
        rec, _ = read_log(train, robot.joint_names, robot=robot)
        t0, c0 = time.perf_counter(), time.process_time()
        ident = identify(rec, robot)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        paths = ident.write(tmp / f"out_{case}")
        model = models[case] = load_robot(urdf=paths["urdf"], locked_joints=robot.source.get("locked_joints") or None)
        bad = physical(model)
        kept = sum(b["determined_by"] == "urdf" for b in ident.report["base_parameters"])
        for csv in held_out:
            rec_h, _ = read_log(csv, robot.joint_names, robot=robot)
            if not np.any(rec_h.tau):
                rows.append(f"| {case} | {Path(csv).stem} | no torque in this log | | | |")
                continue
            b, a = judge(robot, csv), judge(robot, csv, model)
            rows.append(f"| {case} | {Path(csv).stem} | {' '.join(f'{v:.3g}' for v in b)} | "
                        f"{' '.join(f'{v:.3g}' for v in a)} | {np.max(a / b):.2f} / **{np.mean(a / b):.2f}** | "
                        f"{'physical' if not bad else '; '.join(bad)}, {len(ident.report['prior']['projected'])} "
                        f"URDF links projected, {kept} of {len(ident.report['base_parameters'])} combinations "
                        f"kept the URDF's | {wall:.1f} s ({cpu:.1f} s CPU) |")
    if "ur10e" in models and "ur10e_loaded" in models:
        robot, _, held_out = logs(folder, tmp)["ur10e_loaded"]
        r = judge(robot, held_out[0], models["ur10e_loaded"]) / judge(robot, held_out[0], models["ur10e"])
        rows.append(f"\nur10e loaded / no-load model on {Path(held_out[0]).stem}: "
                    + " ".join(f"{v:.2f}" for v in r))
    return "\n".join(rows)


if __name__ == "__main__":               # python tests/logs/real_identify.py: the docs' table
    import sys
    import tempfile
    sys.path.insert(0, str(ROOT))
    with tempfile.TemporaryDirectory() as d:
        print(table(real_dir(), Path(d)))
