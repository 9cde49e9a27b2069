"""substeps = "auto": the default of the targets file, the CLI and compile_observer, resolved
after the design into the fewest stable sub-steps (the folder records the number); a number is
taken as given, and an unstable one is refused naming the stiff joint, its cause and the fix in
the words of where the user is."""
import json
from pathlib import Path

import pytest

from codegen import compile_observer
from codegen.cli import main
from codegen.core.target import Discretization
from codegen.discrete.stability import UnstableDiscretization, check
from codegen.families import observers
from codegen.pipeline.stages import make, resolve_substeps
from codegen.pipeline.targets_file import build_spec, load_targets, make_target
from models import load_robot
from models.urdf import example_robot_data_dir

ROOT = Path(__file__).resolve().parents[2]
DAMPED = ROOT / "tests" / "data" / "damped_arm.urdf"


def test_discretization_takes_auto():
    assert Discretization(substeps="auto").substeps == "auto"
    assert Discretization.from_dict(Discretization(substeps="auto").to_dict()).substeps == "auto"
    for bad in (0, -1, 1.5, "Auto", "2", True):
        with pytest.raises(ValueError, match="substeps"):
            Discretization(substeps=bad)


def test_targets_file_defaults_to_auto(tmp_path):
    """Unstated substeps are "auto"; "auto" and a number are taken as written; a bad value is
    one line naming the target."""
    path = tmp_path / "t.toml"
    path.write_text('[[target]]\nrobot = "seed000_2r"\n[[target]]\nrobot = "seed002_2r"\nsubsteps = "auto"\n'
                    '[[target]]\nrobot = "seed003_2r_abs"\nsubsteps = 3\n')
    assert [t.discretization.substeps for t, _ in load_targets(path)] == ["auto", "auto", 3]
    path.write_text('[[target]]\nrobot = "seed000_2r"\nsubsteps = "many"\n')
    with pytest.raises(ValueError, match=r"target 1 .*substeps"):
        load_targets(path)


def test_cli_parses_substeps(capsys):
    from codegen.cli import parser
    assert parser().parse_args(["build", "ur5", "--substeps", "auto"]).substeps == "auto"
    assert parser().parse_args(["build", "ur5", "--substeps", "4"]).substeps == 4
    with pytest.raises(SystemExit):
        parser().parse_args(["build", "ur5", "--substeps", "0"])
    assert "positive integer or \"auto\"" in capsys.readouterr().err


def test_substeps_are_bounded_everywhere(tmp_path, capsys):
    """Every sub-step is unrolled into the C step (issue 22, F7: --substeps 1000000 ran with no
    bound): above SUBSTEPS_MAX the Python value, the targets file and the CLI refuse in one line
    naming the bound and the fix; SUBSTEPS_MAX itself and "auto" are taken, and auto searches
    no further than that."""
    import inspect

    from codegen.core.target import SUBSTEPS_MAX
    from codegen.discrete.stability import auto_substeps
    assert Discretization(substeps=SUBSTEPS_MAX).substeps == SUBSTEPS_MAX
    assert inspect.signature(auto_substeps).parameters["limit"].default == SUBSTEPS_MAX
    for big in (SUBSTEPS_MAX + 1, 9223372036854775807):
        with pytest.raises(ValueError, match=f"substeps must be at most {SUBSTEPS_MAX}, got {big}: .*lower dt"):
            Discretization(substeps=big)
    path = tmp_path / "t.toml"
    path.write_text('[[target]]\nrobot = "seed000_2r"\nsubsteps = 9223372036854775807\n')
    with pytest.raises(ValueError, match=rf"{path}, target 1 .*substeps must be at most {SUBSTEPS_MAX}") as e:
        load_targets(path)
    assert "\n" not in str(e.value)
    with pytest.raises(SystemExit) as exit_:
        main(["build", "seed000_2r", "--substeps", "1000000", "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert f"substeps must be at most {SUBSTEPS_MAX}, got 1000000" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_make_resolves_auto_and_recognises_its_folder(tmp_path):
    """The damped URDF with plain RK4 at its guarantee gain needs 2 sub-steps: "auto" builds it
    with 2 (folder, metadata and C), and building the same target again (force=False) finds the
    folder its own; a stable target resolves to 1, the default's Target unchanged."""
    entry = {"urdf": str(DAMPED), "design": {"design": "guarantee"}, "method": "rk4"}
    target, _ = make_target(entry)
    assert target.discretization.substeps == "auto"
    made = make(target, tmp_path)
    meta = json.loads((made.folder / f"{made.folder.name}.json").read_text())
    assert meta["discretization"]["substeps"] == 2 == meta["target"]["discretization"]["substeps"]
    assert made.target.discretization.substeps == 2
    assert make(target, tmp_path, force=False).folder == made.folder
    plain, _ = make_target({"robot": "seed000_2r"})
    resolved = resolve_substeps(plain, build_spec(plain))
    assert resolved.discretization == Discretization() and resolved.to_dict() == \
        plain.with_discretization(None, substeps=1).to_dict()


@pytest.mark.slow
def test_a_number_is_taken_as_given(tmp_path):
    """compile_observer with substeps=1 (or a whole Discretization) is refused where "auto" (the
    default) works; the refusal gives the fix in Python's words, its cli_message in flags. The fix
    covers the default range of the elapsed time up to 2 dt: 3 sub-steps (2 at dt alone, which is
    what "auto" takes, declaring the dt_max they are stable at)."""
    spec = observers.build("reduced_order", load_robot(urdf=DAMPED), design="guarantee")
    with pytest.raises(UnstableDiscretization) as err:
        compile_observer(spec, method="rk4", substeps=1, out_dir=tmp_path)
    assert 'substeps="auto"' in str(err.value) and "substeps >= 3" in str(err.value)
    assert "--substeps auto" in err.value.cli_message and "--substeps 3 (or more)" in err.value.cli_message
    with pytest.raises(UnstableDiscretization):
        compile_observer(spec, Discretization(method="rk4"), out_dir=tmp_path)
    assert compile_observer(spec, method="rk4", out_dir=tmp_path).meta["discretization"]["substeps"] == 2


def test_auto_is_resolved_before_any_check():
    """The stability check and the reference take a number; "auto" is refused there with what
    resolves it."""
    from codegen.reference import reference_observer
    spec = observers.build("reduced_order", load_robot("seed000_2r"), k0=10.0)
    with pytest.raises(ValueError, match="auto_substeps"):
        check(spec, Discretization(substeps="auto"))
    with pytest.raises(ValueError, match="metadata"):
        reference_observer(spec, substeps="auto")


@pytest.mark.long           # 1-2 minutes (the gripper arm's stability search): make test-long
def test_an_unlocked_gripper_is_named_with_the_fix(tmp_path, capsys, monkeypatch):
    """z1 from its URDF without locking jointGripper, at one sub-step: the refusal names the
    gripper joint, the friction on its small inertia (viscous 1 + Coulomb 1 N m over the 0.2 rad/s
    smooth sign), and the fixes runnable from the CLI (--substeps, --lock jointGripper=0) or from
    Python (substeps=, locked_joints=). Both fixes build: "auto" with the fewest stable
    sub-steps, and locking the gripper needs fewer (joint6's friction is next)."""
    from codegen.core.target import Discretization
    urdf = example_robot_data_dir() / "z1_description" / "urdf" / "z1.urdf"
    monkeypatch.chdir(tmp_path)
    assert main(["build", "--urdf", str(urdf), "--substeps", "1"]) == 2
    err = capsys.readouterr().err
    assert "on the small inertia of jointGripper" in err and "a gripper joint" in err
    assert "Coulomb 1 N m / width 0.2 rad/s" in err
    assert "--substeps auto" in err and "--lock jointGripper=0" in err
    spec = observers.build("reduced_order", load_robot(urdf=urdf))
    with pytest.raises(UnstableDiscretization, match=r"locked_joints=\{'jointGripper': 0.0\}"):
        compile_observer(spec, substeps=1, out_dir=tmp_path)
    subs = {}
    for name, lock in (("free", []), ("locked", ["--lock", "jointGripper=0"])):
        assert main(["build", "--urdf", str(urdf), *lock, "--name", name]) == 0
        subs[name] = json.loads((tmp_path / "generated" / name / f"{name}.json").read_text())[
            "discretization"]["substeps"]
    assert 1 < subs["locked"] < subs["free"]
    assert not check(spec, Discretization(substeps=subs["free"] - 1)).stable
