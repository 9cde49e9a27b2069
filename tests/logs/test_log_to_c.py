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
    """(log, truth): 4 s of simulate-log's multisine on damped_arm (3 joints), receive-time stamps."""
    from codegen.evaluate.scenarios.log_grid import synthetic_log
    from models import load_robot
    path, truth, _ = synthetic_log(load_robot(urdf=URDF), tmp_path_factory.mktemp("log") / "log.csv", T=4.0)
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
