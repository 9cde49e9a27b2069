"""The identification's report: a JSON-able dict of everything found (residuals, noise,
friction, links, base combinations, parameters) and its readable text, and the message of a log
that does not determine the model."""
from __future__ import annotations

import math

import numpy as np

from .parametrisation import inertial_to_urdf, pseudo_inertia

STILL = 0.01                    # a joint slower than this x its velocity limit (RMS) does not move


def _refusal(arm, poor, std_beta, bound, d, train):
    """(message, remedy) of a log that leaves base parameters ``poor`` undetermined: the joints
    that do not move (RMS speed below STILL of the velocity limit), else those whose parameters
    lead the undetermined combinations, with their motion; the remedy as data
    (:class:`IdentificationError`)."""
    speed = np.sqrt(np.mean(d.qd[train] ** 2, axis=0))
    still = [j for j in range(arm.n) if speed[j] < STILL * arm.v_limit[j]]
    joints = still or sorted({int(arm.owner[arm.indep[k]]) for k in poor})
    motion = ", ".join(f"{arm.joint_names[j]} moves over {np.ptp(d.q[train, j]):.3g} rad at "
                       f"{speed[j]:.3g} rad/s RMS" for j in joints)
    worst = sorted(poor, key=lambda k: -std_beta[k])[:3]
    which = "; ".join(f"{arm.combination(k, 3)}: {std_beta[k]:.3g}" for k in worst)
    names_ = ", ".join(arm.joint_names[j] for j in joints)
    what = (f"joint{'s' if len(joints) > 1 else ''} {names_} do{'es' if len(joints) == 1 else ''} not move"
            if still else f"the motion of joint{'s' if len(joints) > 1 else ''} {names_} does not excite them enough")
    excite = {"robot": arm.name, "urdf": str(arm.path), "locked_joints": dict(arm.locked)}
    head = (f"recording: the log does not determine the model: {len(poor)} of {len(arm.indep)} identifiable "
            f"parameter combinations have a relative std above {bound:g} ({which}"
            f"{'; ...' if len(poor) > len(worst) else ''}); {what} ({motion}). ")
    if still:
        return (head + "Record a log along an excitation trajectory (excitation()) and identify on it, or "
                "lock a joint that cannot move (locked_joints)"), {"excite": excite, "lock": [arm.joint_names[j]
                                                                                         for j in still]}
    # a std falls as 1/sqrt(samples): how many more samples of the same motion (a longer log, or
    # the same one at a higher rate: a log at 200 Hz needs 5 x the duration of one at 1 kHz)
    longer = float(np.max(std_beta[poor]) / bound) ** 2
    duration = float(np.ptp(d.t[train]))
    rate = float(np.count_nonzero(train)) / duration
    worst_rel = float(np.max(std_beta[poor]))
    remedy = {"samples_factor": longer, "duration_s": longer * duration, "rate": rate,
              "rate_needed": longer * rate, "excite": excite, "max_rel_std": worst_rel * 1.01}
    return (head + f"Record {longer:.2g} x the samples of the same motion ({longer * duration:.3g} s at this "
            f"log's {rate:.3g} samples/s, or {duration:.3g} s at {longer * rate:.3g} samples/s), or a log "
            f"along an excitation trajectory if this one is not (excitation()), or accept the worst at "
            f"{worst_rel:.2g} (max_rel_std={worst_rel * 1.01:.2g})"), remedy


def _report(arm, fit, estimate, options):
    """The report dict of an identification: ``fit`` the log's split (t, train, test, t_split,
    cutoff, wide, decimation, test_fraction, v_stick, stuck), ``estimate`` what was found (x,
    sigma, std_post, std_data, std_beta, effect, residual, cond, rounds), ``options`` (prior,
    max_rel_std)."""
    t, t_split, train, test = fit["t"], fit["t_split"], fit["train"], fit["test"]
    cutoff, wide, decimation, tf = fit["cutoff"], fit["wide"], fit["decimation"], fit["test_fraction"]
    v_stick, stuck = fit["v_stick"], fit["stuck"]
    x, sigma, std_post, std_data, std_beta = (estimate[k] for k in ("x", "sigma", "std_post", "std_data",
                                                                    "std_beta"))
    effect, residual, cond, rounds = (estimate[k] for k in ("effect", "residual", "cond", "rounds"))
    prior, max_rel_std = options["prior"], options["max_rel_std"]
    J = arm.joint_names
    per = lambda v: {j: float(a) for j, a in zip(J, v)}  # noqa: E731
    fv, fc, fo = arm.friction_value(x)
    sv, sc, so = arm.friction_value(std_post)
    bodies = {}
    for i, link in enumerate(arm.links):
        m, c, Ic = inertial_to_urdf(x[10 * i:10 * i + 10] - arm.attached[10 * i:10 * i + 10])
        m0, c0, _ = inertial_to_urdf(arm.primary_urdf[10 * i:10 * i + 10]) if arm.primary_urdf[10 * i] > 0 \
            else (0.0, np.zeros(3), None)
        bodies[link] = {"joint": J[i], "mass": m, "mass_urdf": m0, "com": c.tolist(), "com_urdf": c0.tolist(),
                        "inertia_com": Ic.tolist(),
                        "pseudo_inertia_min_eigenvalue": float(np.linalg.eigvalsh(
                            pseudo_inertia(x[10 * i:10 * i + 10]))[0])}
    beta = (arm.T @ (x / arm.scale)) * arm.scale[arm.indep]
    with np.errstate(invalid="ignore"):
        rel_data = np.where(np.isfinite(std_data), std_data / arm.scale * effect, np.inf)
    return {
        "robot": arm.name, "urdf": str(arm.path), "locked_joints": arm.locked, "joints": J,
        "model": "tau = Y(q, qd, qdd) pi + f_v qd + f_c tanh(qd / w) + f_o",
        "log": {"samples": len(t), "duration_s": float(t[-1] - t[0]),
                "median_step_s": float(np.median(np.diff(t))), "cutoff_hz": float(cutoff),
                "coulomb_column_cutoff_hz": float(wide), "fit_every": int(decimation),
                "train_samples": int(train.sum()), "test_samples": int(test.sum()),
                "test_from_s": float(t_split), "test_fraction": tf, "v_stick": float(v_stick),
                "stuck_fraction": per(stuck)},
        "coulomb_width": arm.width, "coulomb_width_source": arm.width_source,
        **({"coulomb_width_held_out_rms": arm.width_candidates} if arm.width_candidates else {}),
        "noise_std": per(sigma),
        "residual_rms": {k: per(v) for k, v in residual.items()},
        "condition_number": cond,
        "condition_number_definition": "base regressor on the training samples, columns in units of "
                                       "the parameter scales, rows in units of the joint torque scales",
        "prior": prior, "max_rel_std": max_rel_std,
        "solver": rounds,
        "base_parameters": [{"combination": arm.combination(k), "value": float(beta[k]),
                             "std": float(std_beta[k] * arm.scale[arm.indep[k]]),
                             "relative_std": float(std_beta[k] * effect[arm.indep[k]])}
                            for k in range(len(arm.indep))],
        "parameters": [{"name": arm.names[i], "joint": J[arm.owner[i]], "urdf": float(arm.x_urdf[i]),
                        "value": float(x[i]), "std": float(std_post[i]), "std_data": float(std_data[i]),
                        "scale": float(arm.scale[i]),
                        "relative_std": float(rel_data[i]), "identifiable": bool(rel_data[i] <= max_rel_std)}
                       for i in range(arm.p)],
        "friction": {j: {"viscous": float(fv[k]), "viscous_std": float(sv[k]), "coulomb": float(fc[k]),
                         "coulomb_std": float(sc[k]), "offset": float(fo[k]), "offset_std": float(so[k])}
                     for k, j in enumerate(J)},
        "links": bodies,
    }


def report_text(report):
    """A readable text of an identification report dict (:class:`Identification`.report)."""
    J = report["joints"]
    lines = [f"identification of {report['robot']} ({report['urdf']})",
             f"model: {report['model']}, w = {report['coulomb_width']:g} rad/s ({report['coulomb_width_source']})"]
    if report["locked_joints"]:
        lines.append("locked joints (kept as they were): " + ", ".join(f"{k} = {v:g}" for k, v in
                                                                       report["locked_joints"].items()))
    lg = report["log"]
    lines += [f"log: {lg['samples']} samples over {lg['duration_s']:.3f} s (median step {lg['median_step_s'] * 1e3:.3f} ms), "
              f"zero-phase cut-off {lg['cutoff_hz']:g} Hz; trained on {lg['train_samples']}, held out "
              f"{lg['test_samples']} from t = {lg['test_from_s']:.3f} s",
              f"left out of the fit where a joint sticks (|qd| <= {lg['v_stick']:g} rad/s): "
              + ", ".join(f"{j} {100 * lg['stuck_fraction'][j]:.1f} %" for j in J),
              f"condition number of the base regressor: {report['condition_number']:.4g} "
              f"({len(report['base_parameters'])} base parameters)", "",
              "held-out torque residual RMS (N m or N):",
              f"  {'joint':<24}{'noise std':>12}{'before':>12}{'after':>12}"]
    r = report["residual_rms"]
    for j in J:
        lines.append(f"  {j:<24}{report['noise_std'][j]:>12.4g}{r['before'][j]:>12.4g}{r['after'][j]:>12.4g}")
    lines += ["", "friction (value +- std):"]
    for j in J:
        f = report["friction"][j]
        lines.append(f"  {j:<24}viscous {f['viscous']:.4g} +- {f['viscous_std']:.2g}, coulomb "
                     f"{f['coulomb']:.4g} +- {f['coulomb_std']:.2g}, offset {f['offset']:.4g} +- {f['offset_std']:.2g}")
    lines += ["", "links (identified; URDF):"]
    for link, b in report["links"].items():
        lines.append(f"  {link:<24}mass {b['mass']:.4g} kg ({b['mass_urdf']:.4g}), com "
                     f"[{', '.join(f'{v:.4g}' for v in b['com'])}] m ([{', '.join(f'{v:.4g}' for v in b['com_urdf'])}])")
    lines += ["", f"identifiable combinations (relative std: the torque uncertainty it leaves on random "
                  f"states / the joint's RMS torque; refused above {report['max_rel_std']:g}):"]
    for b in report["base_parameters"]:
        lines.append(f"  {b['value']:>12.5g} +- {b['std']:<10.2g} ({b['relative_std']:.1e})  {b['combination']}")
    lines += ["", "parameters (value, std from log and prior, std from the log alone, URDF):"]
    for prm in report["parameters"]:
        sd = prm["std_data"]
        lines.append(f"  {prm['name']:<28}{prm['value']:>12.5g} +- {prm['std']:<10.2g}"
                     f"{('log alone +- ' + format(sd, '.2g')) if math.isfinite(sd) else 'not alone':<22}"
                     f"URDF {prm['urdf']:.5g}")
    if "files" in report:
        lines += ["", "files:"] + [f"  {v}" for v in report["files"].values()]
    return "\n".join(lines) + "\n"


def _jsonable(v):
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else ("inf" if f > 0 else "-inf" if f < 0 else "nan")
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    return v
