"""From a log to a C folder: `design`'s build line pastes into a shell and builds a folder whose
design report and header say where each value came from; `compare LOG --build DIR` writes the
winner's folder, whose C gives on the log the error compare found (a URDF outside the catalog, a
realistic synthetic log of it)."""
import contextlib
import io
import json
import shlex
from pathlib import Path

import pytest

from codegen.cli import main, parser

pytest.importorskip("mujoco", reason="the mujoco extra is not installed")

URDF = Path(__file__).resolve().parents[1] / "data" / "damped_arm.urdf"


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    """(log, truth): 10 s of simulate-log's multisine on damped_arm (3 joints), receive-time stamps
    (compare tunes on a log twice as long as its start-up skip: 10 s is enough)."""
    from codegen.evaluate.scenarios.log_grid import synthetic_log
    from models import load_robot
    path, truth, _ = synthetic_log(load_robot(urdf=URDF), tmp_path_factory.mktemp("log") / "log.csv", T=10.0)
    return Path(path), Path(truth)


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


@pytest.mark.slow
def test_designs_build_line_pastes_and_builds_what_it_says(log, tmp_path):
    """The printed line, split as a POSIX shell splits it, parses and builds; the folder's gains are
    the tuned ones, and its design report and header name their sources (the log, the user)."""
    path, _ = log
    status, out, err = _run(["design", str(path), "--urdf", str(URDF), "--family", "kalman_model",
                             "--torque-uncertainty", "2.5,1.25,0.5", "--json", str(tmp_path / "d.json")])
    assert status == 0, err
    line = next(ln for ln in out.splitlines() if ln.startswith("build it: ")).removeprefix("build it: ")
    words = shlex.split(line)
    assert words[:4] == ["python", "-m", "codegen", "build"]
    argv = words[3:] + ["--out", str(tmp_path / "gen")]
    args = parser().parse_args(argv)
    assert args.urdf == str(URDF) and "torque_uncertainty=[2.5,1.25,0.5]" in args.design
    status, built, err = _run(argv)
    assert status == 0, err
    import codegen
    obs = codegen.load(next((tmp_path / "gen").iterdir()))
    tuned = json.loads((tmp_path / "d.json").read_text())["tuned"]["params"]
    report = obs.design
    for k, v in tuned.items():
        assert obs.meta["p_default"][obs.meta["names"]["p"].index(k)] == pytest.approx(v, rel=1e-5)
        assert report["parameters"][k]["source"] == f"tuned on the log {path.name}"
        assert f"{k} = " in built and f": tuned on the log {path.name}" in built
    assert report["inputs"]["torque_uncertainty"]["source"] == "given by the user (2.5,1.25,0.5)"
    assert report["inputs"]["noise"]["source"] == f"measured on the log {path.name}"
    folder = next((tmp_path / "gen").iterdir())
    header = (folder / f"{folder.name}.h").read_text()
    assert f"omega = {tuned['omega']:.6g}: tuned on the log {path.name}" in header
    assert "built with" in str(report) and f"tuned on the log {path.name}" in str(report)


@pytest.mark.slow
def test_compare_builds_the_winner_whose_c_gives_the_error_compare_found(log, tmp_path):
    """compare LOG --build DIR: the winner by the truth-free criterion (the lowest forward-validation
    estimate of the observers that did not fail) written as `build` writes it; its C, run on the
    log at the log's times, gives compare's own estimate (so the error compare found against the
    truth, within 10 %: to 1e-6), near the one compare predicted without truth (validation_rms);
    the folder declares the log's interval range and states each value's source."""
    import numpy as np

    import codegen
    from codegen.core.columns import read_columns
    from codegen.evaluate.winner import interval_range
    from codegen.logs.recording import read_log
    from models import load_robot
    path, truth = log
    status, out, err = _run(["compare", str(path), "--urdf", str(URDF), "--observers", "kalman_model,extended_state",
                             "--baselines", "kalman", "--out", str(tmp_path / "cmp"), "--build", str(tmp_path / "c")])
    assert status == 0, err
    data = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    ok = [r for r in data["rows"] if r["kind"] == "observer" and not r["failed"]]
    best = min(ok, key=lambda r: r["validation_rms"])
    assert f"built the winner, {best['name']} " in out
    [folder] = list((tmp_path / "c").iterdir())
    obs = codegen.load(folder)
    robot = load_robot(urdf=URDF)
    rec, clock = read_log(path, robot.joint_names, robot=robot)
    d = obs.meta["discretization"]
    assert (d["dt_min"], d["dt_max"]) == pytest.approx(interval_range(rec.t, rec.dt))
    assert d["dt"] == pytest.approx(rec.dt)
    tuned = {k: v for k, v in best["params"].items() if k in obs.design.get("parameters", {})}
    assert tuned, "the winner's tuned gains are in the folder"
    for k, v in tuned.items():
        assert obs.design["parameters"][k]["source"].startswith(f"tuned on the log {path.name}")
        assert obs.meta["p_default"][obs.meta["names"]["p"].index(k)] == pytest.approx(v, rel=1e-12)
    header = (folder / f"{folder.name}.h").read_text()
    assert "Where the default parameters come from:" in header and f"dt_max: the longest interval of the log " \
        f"{path.name}" in header and f"measured on the log {path.name}" in header
    obs.reset(rec.q[0])
    est = obs.run(rec.q, rec.tau, t=rec.t)[:, [obs.meta["names"]["est"].index(f"qd_hat_{j}") for j in robot.joint_names]]
    eh, ev = read_columns(tmp_path / "cmp" / "estimates.csv")
    theirs = ev[clock.kept][:, [eh.index(f"{best['name']}.qd_{j}") for j in robot.joint_names]]
    th, tv = read_columns(truth)
    qd = tv[clock.kept][:, [th.index(f"qd_{j}") for j in robot.joint_names]]
    w = rec.t >= data["t_ss"]
    rms = lambda e: float(np.sqrt(np.mean(np.sum(e[w] ** 2, axis=1))))  # noqa: E731
    assert rms(est - theirs) <= 1e-6 * rms(est - qd)                     # compare's estimate
    # the error compare found on this run (its estimate against the truth): the C's within 10 %
    assert rms(est - qd) == pytest.approx(rms(theirs - qd), rel=0.10)
    # and what compare predicted without truth: its forward validation's estimate (16 % under the
    # truth on this log; the prediction's own accuracy, not the build's)
    assert rms(est - qd) == pytest.approx(best["validation_rms"], rel=0.25)
