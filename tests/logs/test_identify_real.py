"""`identify` on the real arms' logs (``real_identify``: each log with its true sample clock),
judged on held-out logs by the torque residual through a 10 Hz zero-phase low-pass, per joint,
against the shipped URDF without friction: at most it on every joint and 0.7 x it on average;
every URDF written physical within its bounds and loadable as every command loads one."""
import time

import numpy as np
import pytest

import real_identify as R

pytestmark = [pytest.mark.real, pytest.mark.long]
FOLDER = R.real_dir()
if FOLDER is None:
    pytest.skip("no real-log folder ($CODEGEN_REAL_LOGS or ../shared/data/real)", allow_module_level=True)


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    return R.logs(FOLDER, tmp_path_factory.mktemp("real"))


@pytest.fixture(scope="module")
def identified(cases, tmp_path_factory):
    """case -> (identified robot, report, CPU seconds), identified once per module."""
    from codegen.logs.identify import identify
    from codegen.logs.recording import read_log
    from models import load_robot
    out, done = tmp_path_factory.mktemp("identified"), {}

    def get(case):
        if case not in done:
            robot, train, _ = cases[case]
            rec, _ = read_log(train, robot.joint_names, robot=robot)
            t0 = time.process_time()
            ident = identify(rec, robot)
            cpu = time.process_time() - t0
            paths = ident.write(out / case)
            model = load_robot(urdf=paths["urdf"], locked_joints=robot.source.get("locked_joints") or None)
            done[case] = (model, ident.report, cpu)
        return done[case]
    return get


def _torque_is_zero(csv, robot):
    from codegen.logs.recording import read_log
    rec, _ = read_log(csv, robot.joint_names, robot=robot)
    return not np.any(rec.tau)


REVERSE = pytest.param("ur10e_loaded_reverse", marks=pytest.mark.xfail(
    strict=True, reason="UR10e loaded, 15-harmonic -> 14-harmonic log: wrist 1 at 1.10 x the shipped URDF's "
                        "residual (mean 0.50), measured 7 Dec 2026: the payload's mass shared between the "
                        "wrist bodies, which the log separates poorly"))


@pytest.mark.parametrize("case", ["panda", "gen3", "ur10e", "ur10e_loaded", REVERSE])
def test_identified_beats_the_shipped_urdf_on_held_out_logs(cases, identified, case):
    robot, _, held_out = cases[case]
    model, report, cpu = identified(case)
    # physical within the margin: every link's mass, centre of mass and second moments in its
    # bounds, the inertia about the centre of mass within the triangle inequalities
    assert not R.physical(model)
    for link, b in report["links"].items():
        lim = b["bounds"]
        assert b["mass"] >= lim["mass_min"] * (1 - 1e-9), (link, b["mass"], lim)
        assert np.all(np.abs(b["com"]) <= lim["com_reach"] * (1 + 1e-9)), (link, b["com"], lim)
        assert min(b["principal_second_moments"]) >= b["mass"] * lim["rho"] ** 2 * (1 - 1e-6), (link, b)
    judged = 0
    for csv in held_out:
        if _torque_is_zero(csv, robot):        # gen3's RecordTrajectory_quadratic: no torque logged
            continue
        shipped, ident = R.judge(robot, csv), R.judge(robot, csv, model)
        ratio = ident / shipped
        assert np.all(ratio <= 1.0), (csv.name, ratio, ident, shipped)
        assert ratio.mean() <= 0.7, (csv.name, ratio)
        judged += 1
    assert judged
    if robot.n == 7 and report["log"]["duration_s"] <= 20:
        assert cpu < 60, cpu


def test_gen3_urdf_is_projected(identified):
    """The Gen3's shipped URDF breaks the triangle inequality on two links: projected, and said."""
    _, report, _ = identified("gen3")
    assert set(report["prior"]["projected"]) == {"shoulder_link", "spherical_wrist_1_link"}


def test_a_payload_is_identified(cases, identified):
    """UR10e with its 2.805 kg payload: on the loaded held-out log the loaded model's residual on
    the shoulder-lift and elbow joints at most 0.6 x the no-load model's."""
    robot, _, held_out = cases["ur10e_loaded"]
    loaded, _, _ = identified("ur10e_loaded")
    no_load, _, _ = identified("ur10e")
    ratio = R.judge(robot, held_out[0], loaded) / R.judge(robot, held_out[0], no_load)
    assert np.all(ratio[1:3] <= 0.6), ratio
