"""The arms example-robot-data ships, in the catalog: each loads with its gripper locked, and
`python -m codegen build <arm>` then `check` work at the defaults (the default family, 1 kHz,
substeps "auto")."""
import json

import numpy as np
import pytest

from codegen.cli import main
from models import load_robot, names
from models.catalog import ARMS

# name -> (joints, locked joints, movable joints that stay, first joint)
EXPECTED = {
    "ur3": (6, {}, "shoulder_pan_joint"),
    "ur10": (6, {}, "shoulder_pan_joint"),
    "kinova": (6, {}, "j2s6s200_joint_1"),        # fingers are fixed joints in the URDF
    "xarm7": (7, {}, "joint1"),                   # no gripper in the URDF
    "z1": (6, {"jointGripper": 0.0}, "joint1"),
    "so100": (5, {"gripper": 0.0}, "shoulder_pan"),
    "so101": (5, {"gripper": 0.0}, "shoulder_pan"),
}
SMALL = "so100"          # 5 joints, light: the fast end-to-end test


def test_every_arm_is_in_the_catalog():
    assert set(ARMS) == set(EXPECTED) and set(ARMS) <= set(names())


@pytest.mark.parametrize("arm", ARMS)
def test_arm_loads_with_its_gripper_locked(arm):
    """Joint count, the locked gripper (recorded in the robot's source), no gripper or finger among
    the joints left, finite velocity limits (the observers' velocity bound) and M(q) positive
    definite at 64 sampled configurations."""
    n, locked, first = EXPECTED[arm]
    robot = load_robot(arm)
    assert robot.n == n and robot.joint_names[0] == first
    assert robot.source["locked_joints"] == locked
    assert not [j for j in robot.joint_names if any(w in j.lower() for w in ("finger", "gripper", "hand"))]
    assert np.all(np.isfinite(robot.v_limit)) and np.all(np.asarray(robot.v_limit) > 0)
    robot.check_mass_matrix()


def _build_and_check(arm, tmp_path, monkeypatch, capsys):
    """`build <arm>` then `check <arm>` from an empty folder; the metadata of the build."""
    monkeypatch.chdir(tmp_path)
    assert main(["build", arm]) == 0, capsys.readouterr().err
    meta = json.loads((tmp_path / "generated" / f"{arm}_reduced_order" / f"{arm}_reduced_order.json").read_text())
    assert main(["check", arm, "--count", "100"]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert out.splitlines()[-1].startswith("OK: worst ")
    return meta


def test_small_arm_builds_and_checks_at_the_defaults(tmp_path, monkeypatch, capsys):
    meta = _build_and_check(SMALL, tmp_path, monkeypatch, capsys)
    assert meta["discretization"]["substeps"] == 1 and meta["stability"]["stable"]
    assert meta["options"]["v_bound"] == pytest.approx(list(2 * load_robot(SMALL).v_limit))


@pytest.mark.slow
@pytest.mark.parametrize("arm", [pytest.param(a, marks=pytest.mark.long) if a == "xarm7" else a
                                 for a in ARMS if a != SMALL])   # xarm7: 19 sub-steps, 2 minutes
def test_arm_builds_and_checks_at_the_defaults(arm, tmp_path, monkeypatch, capsys):
    """Every arm at the defaults, with the fewest stable sub-steps: one less is unstable. The arms
    whose URDF declares friction get more than one (xarm7: viscous 2 + Coulomb 1 N m over the
    0.2 rad/s smooth sign on a 1.3e-4 kg m^2 wrist, 19; z1: 3); the others 1."""
    from codegen.discrete.stability import check
    from codegen.families import observers
    from codegen.core.target import Discretization
    meta = _build_and_check(arm, tmp_path, monkeypatch, capsys)
    m = meta["discretization"]["substeps"]
    assert meta["stability"]["stable"]
    robot = load_robot(arm)
    if not np.any(robot.coulomb) and not np.any(robot.viscous):
        assert m == 1
    if m > 1:
        spec = observers.build("reduced_order", robot)
        assert not check(spec, Discretization(substeps=m - 1)).stable
