"""The identification's report: a JSON-able dict of everything found (residuals, noise,
friction, links, base combinations, parameters) and its readable text, and the message of a log
that does not determine the model."""
from __future__ import annotations

import math

import numpy as np

from .parametrisation import inertial_to_urdf, pseudo_inertia

STILL = 0.01                    # a joint slower than this x its velocity limit (RMS) does not move


FIXED = 0.3                     # posterior std / prior std of a combination at most this: the log fixed it
KEPT = 0.9                      # at least this: it kept the URDF's value (the prior dominates)


def _still(arm, speed):
    """(message, remedy) of a log in which no joint moves (RMS speed ``speed`` (n,) rad/s below
    STILL of its velocity limit): the remedy, as data, an excitation trajectory of the robot."""
    motion = ", ".join(f"{j} {v:.3g} rad/s" for j, v in zip(arm.joint_names, speed))
    return (f"recording: the log does not move (RMS speed {motion}; below {STILL:g} x each joint's velocity "
            f"limit): it determines nothing of the model. Record a log along an excitation trajectory "
            f"(excitation()) and identify on it"), {"excite": {"robot": arm.name, "urdf": str(arm.path),
                                                               "locked_joints": dict(arm.locked)}}


def _determined(post, prior):
    """"log" (the log fixed it), "urdf" (it kept the URDF's value) or "both", of a combination's
    posterior and prior std."""
    r = post / prior
    return "log" if r <= FIXED else "urdf" if r >= KEPT else "both"


def _report(arm, fit, estimate, options):
    """The report dict of an identification: ``fit`` the log's split (t, train, test, t_split,
    cutoff, wide, decimation, test_fraction, v_stick, stuck, speed), ``estimate`` what was found
    (x, sigma, std_post, std_beta and prior_beta in scaled units, effect, residual, cond, rounds),
    ``options`` (prior)."""
    t, t_split, train, test = fit["t"], fit["t_split"], fit["train"], fit["test"]
    cutoff, wide, decimation, tf = fit["cutoff"], fit["wide"], fit["decimation"], fit["test_fraction"]
    v_stick, stuck = fit["v_stick"], fit["stuck"]
    x, sigma, std_post, std_beta, prior_beta = (estimate[k] for k in ("x", "sigma", "std_post", "std_beta",
                                                                      "prior_beta"))
    effect, residual, cond, rounds = (estimate[k] for k in ("effect", "residual", "cond", "rounds"))
    J = arm.joint_names
    per = lambda v: {j: float(a) for j, a in zip(J, v)}  # noqa: E731
    fv, fc, fo = arm.friction_value(x)
    sv, sc, so = arm.friction_value(std_post)
    bodies = {}
    for i, link in enumerate(arm.links):
        m, c, Ic = inertial_to_urdf(x[10 * i:10 * i + 10] - arm.attached[10 * i:10 * i + 10])
        m0, c0, _ = inertial_to_urdf(arm.primary_urdf[10 * i:10 * i + 10]) if arm.primary_urdf[10 * i] > 0 \
            else (0.0, np.zeros(3), None)
        S = 0.5 * np.trace(Ic) * np.eye(3) - Ic
        b = arm.bounds[i]
        bodies[link] = {"joint": J[i], "mass": m, "mass_urdf": m0, "com": c.tolist(), "com_urdf": c0.tolist(),
                        "inertia_com": Ic.tolist(),
                        "principal_second_moments": np.linalg.eigvalsh(S).tolist(),
                        "bounds": {"mass_min": b.mass, "com_reach": b.reach, "rho": b.rho},
                        "pseudo_inertia_min_eigenvalue": float(np.linalg.eigvalsh(
                            pseudo_inertia(x[10 * i:10 * i + 10]))[0])}
    beta = (arm.T @ (x / arm.scale)) * arm.scale[arm.indep]
    beta_urdf = (arm.T @ (arm.x_prior / arm.scale)) * arm.scale[arm.indep]
    unit = arm.scale[arm.indep]
    return {
        "robot": arm.name, "urdf": str(arm.path), "locked_joints": arm.locked, "joints": J,
        "model": "tau = Y(q, qd, qdd) pi + f_v qd + f_c tanh(qd / w) + f_o",
        "log": {"samples": len(t), "duration_s": float(t[-1] - t[0]),
                "median_step_s": float(np.median(np.diff(t))), "cutoff_hz": float(cutoff),
                "coulomb_column_cutoff_hz": float(wide), "fit_every": int(decimation),
                "train_samples": int(train.sum()), "test_samples": int(test.sum()),
                "test_from_s": float(t_split), "test_fraction": tf, "v_stick": float(v_stick),
                "stuck_fraction": per(stuck), "rms_speed": per(fit["speed"]),
                "torque_not_measured": list(fit["unmeasured"])},
        "coulomb_width": arm.width, "coulomb_width_source": arm.width_source,
        **({"selection": arm.selection} if arm.selection else {}),
        "noise_std": per(sigma),
        "residual_rms": {k: per(v) for k, v in residual.items()},
        "condition_number": cond,
        "condition_number_definition": "base regressor on the training samples, columns in units of "
                                       "the parameter scales, rows in units of the joint torque scales",
        "prior": {"relative_std": options["prior"],
                  "rule": "the URDF's values, each with a std of relative_std x its scale (friction: of the RMS of the "
                          "joint's measured torque where larger); links outside the physical bounds projected "
                          "into them first",
                  "projected": arm.projected},
        "bounds_rule": "mass >= max(0.1 x the URDF link's, 1e-3 x the robot's moving mass); each coordinate "
                       "of the centre of mass within +-(the farthest child joint or the URDF centre of mass "
                       "+ 0.1 m) of the joint frame; every principal second moment about the centre of mass "
                       ">= m rho^2, rho = min(1 mm, 0.1 x the body's length scale)",
        "solver": rounds,
        "base_parameters": [{"combination": arm.combination(k), "value": float(beta[k]),
                             "urdf": float(beta_urdf[k]), "std": float(std_beta[k] * unit[k]),
                             "prior_std": float(prior_beta[k] * unit[k]),
                             "relative_std": float(std_beta[k] * effect[arm.indep[k]]),
                             "determined_by": _determined(std_beta[k], prior_beta[k])}
                            for k in range(len(arm.indep))],
        "parameters": [{"name": arm.names[i], "joint": J[arm.owner[i]], "urdf": float(arm.x_urdf[i]),
                        "prior": float(arm.x_prior[i]), "value": float(x[i]), "std": float(std_post[i]),
                        "scale": float(arm.scale[i])}
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
              *([f"torque not measured (a constant column; its rows left out, its residual meaningless): "
                  + ", ".join(lg["torque_not_measured"])] if lg.get("torque_not_measured") else []),
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
    pr = report["prior"]
    if pr["projected"]:
        lines += ["", "the URDF is not physical: its values projected into the physical bounds before they "
                      "serve as the prior:"]
        lines += [f"  {link}: {'; '.join(ch)}" for link, ch in pr["projected"].items()]
    bp = report["base_parameters"]
    count = {k: sum(b["determined_by"] == k for b in bp) for k in ("log", "both", "urdf")}
    worst = max(bp, key=lambda b: b["relative_std"]) if bp else None
    lines += ["", f"base combinations: {count['log']} of {len(bp)} fixed by the log (posterior std <= "
                  f"{FIXED:g} x the prior's), {count['urdf']} kept the URDF's values (>= {KEPT:g} x), "
                  f"{count['both']} from both" + (f"; the largest relative std {worst['relative_std']:.2g} "
                                                  f"({worst['combination'][:60]})" if worst else ""),
              f"  {'value':>12} {'+- std':<10} {'URDF':>12} {'prior std':>10} {'rel. std':>9}  by    combination"]
    for b in bp:
        lines.append(f"  {b['value']:>12.5g} +- {b['std']:<7.2g} {b['urdf']:>12.5g} {b['prior_std']:>10.2g} "
                     f"{b['relative_std']:>9.1e}  {b['determined_by']:<5} {b['combination']}")
    lines += ["", "parameters (value +- std from log and prior; URDF):"]
    for prm in report["parameters"]:
        lines.append(f"  {prm['name']:<28}{prm['value']:>12.5g} +- {prm['std']:<10.2g}URDF {prm['urdf']:.5g}")
    if "files" in report:
        lines += ["", "files:"] + [f"  {v}" for v in report["files"].values()]
    return "\n".join(lines) + "\n"


SCREEN_SECTIONS = 3             # the summary: the header, the held-out residual, the friction


def summary_text(report):
    """The first sections of ``report_text`` (what was identified, on which log, the held-out
    residual per joint, the friction), the base combinations' one-line count and the files: a
    screen; the links, combinations and parameters stay in the report file."""
    blocks = report_text(report).rstrip("\n").split("\n\n")
    keep = blocks[:SCREEN_SECTIONS]
    keep += [b.splitlines()[0] for b in blocks if b.startswith("base combinations:")]
    keep += [b for b in blocks if b.startswith("files:")]
    return "\n\n".join(keep) + "\n"


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
