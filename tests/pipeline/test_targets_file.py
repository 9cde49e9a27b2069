"""Targets files (codegen.pipeline.targets_file): parsing into Target values, errors naming file, target and the
valid choices, round trips through the metadata JSON, and the folder guard of emit."""
import json
from pathlib import Path

import pytest

from codegen.pipeline.emit import FolderTaken, check_folder, emit
from codegen.core.target import Target
from codegen.pipeline.targets_file import KEYS, TargetError, build_spec, load_targets, make_target

ROOT = Path(__file__).resolve().parents[2]
URDF = ROOT / "tests" / "data" / "gripper_arm.urdf"


def write(tmp_path, text, name="my.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_repository_targets_one_of_each_family():
    """targets.toml (make generate) has every observer family, reduced_order on ur5 and panda,
    catalog robots recorded by name, and the CG variants in their folder names."""
    from codegen.families import observers
    targets = load_targets(ROOT / "targets.toml")
    by_family = {}
    for t, out in targets:
        by_family.setdefault(t.family, []).append(t)
        assert out == Path("generated").resolve()
    assert set(by_family) == set(observers.FAMILIES)
    assert {t.robot["name"] for t in by_family["reduced_order"]} >= {"ur5", "panda"}
    robots = {t.family: t.robot for t in (tt for ts in by_family.values() for tt in ts)}
    assert robots["ii_speed"] == robots["ii_aov"] == {"kind": "catalog", "name": "seed003_2r_abs"}
    assert robots["lotfi_namvar"] == {"kind": "catalog", "name": "seed002_2r"}
    for family in ("tomei", "ciccarella_germani"):
        assert robots[family]["kind"] == "elastic" and robots[family]["rigid"] == {"kind": "catalog",
                                                                                   "name": "seed004_2r"}
    assert sorted(t.prefix for t in by_family["ciccarella_germani"]) == [
        "seed004_2r_elastic_ciccarella_germani_o1", "seed004_2r_elastic_ciccarella_germani_o2"]
    assert "/" not in json.dumps([t.to_dict() for t, _ in targets])   # no installation path


def test_every_key_parsed(tmp_path):
    """Each key of a [[target]] table lands in the Target; URDF and out relative to the file."""
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "arm.urdf").write_bytes(URDF.read_bytes())
    path = write(tmp_path, """
[[target]]
urdf = "robots/arm.urdf"
lock = { finger_left = 0.01, finger_right = 0.02 }
elastic = true
J = [0.5, 0.6, 0.7]
K = 1e4
family = "ciccarella_germani"
variant = "O2"
design = { rcond_min = 1e-10 }
params = { rcond_min = 1e-9 }
sources = { rcond_min = "the vendor's sheet" }
dt = 5e-4
dt_min = 1e-4
dt_max = 5e-3
method = "euler"
hold = "zoh"
substeps = 2
precision = "double"
name = "Arm-CG"
out = "c/out"
""")
    [(t, out)] = load_targets(path)
    assert out == (tmp_path / "c" / "out").resolve()
    assert t.robot == {"kind": "elastic", "name": "arm_elastic", "J": [0.5, 0.6, 0.7], "K": 1e4,
                       "rigid": {"kind": "urdf", "name": "arm", "path": str((tmp_path / "robots" / "arm.urdf").resolve()),
                                 "locked_joints": {"finger_left": 0.01, "finger_right": 0.02}}}
    assert (t.family, t.variant, t.build, t.params) == ("ciccarella_germani", "O2", {"rcond_min": 1e-10},
                                                       {"rcond_min": 1e-9})
    assert t.sources == {"rcond_min": "the vendor's sheet"}
    assert t.discretization.to_dict() == {"dt": 5e-4, "method": "euler", "hold": "zoh", "substeps": 2,
                                          "dt_min": 1e-4, "dt_max": 5e-3}
    assert (t.precision, t.name, t.prefix) == ("double", "arm_cg", "arm_cg")
    assert set(KEYS) == {"robot", "urdf", "lock", "elastic", "J", "K", "family", "variant", "design",
                         "params", "sources", "dt", "dt_min", "dt_max", "method", "hold", "substeps", "precision",
                         "name", "out", "tune", "tune_columns", "tune_topic"}   # tune: tests/logs/test_log_commands.py,
    # tune_columns: tests/logs/test_mapping.py
    # sources name values of params or design only
    path.write_text('[[target]]\nrobot = "seed000_2r"\nsources = { k9 = "a log" }\n')
    with pytest.raises(TargetError, match="sources: k9 is neither a parameter, a design input nor dt"):
        load_targets(path)


def test_a_tune_key_needs_the_command_line_and_a_log(tmp_path):
    """``tune`` names a log beside the file; loaded without the command line's tuner it is refused
    in one line saying who resolves it (codegen.cli tunes: tests/logs/test_log_commands.py)."""
    (tmp_path / "log.csv").write_text("t,q_q1,q_q2,tau_q1,tau_q2\n")
    path = write(tmp_path, '[[target]]\nrobot = "seed000_2r"\ntune = "log.csv"\n')
    with pytest.raises(TargetError, match="tune: a log's gains are tuned by the command line"):
        load_targets(path)
    seen = []
    [(t, _)] = load_targets(path, tuner=lambda target, log: seen.append(log) or target)
    assert seen == [(tmp_path / "log.csv").resolve()] and t.family == "reduced_order"
    with pytest.raises(TargetError, match="tune: log not found"):
        load_targets(write(tmp_path, '[[target]]\nrobot = "seed000_2r"\ntune = "none.csv"\n'), tuner=lambda t, log: t)
    with pytest.raises(TargetError, match="tune must be a string"):
        load_targets(write(tmp_path, '[[target]]\nrobot = "seed000_2r"\ntune = 3\n'), tuner=lambda t, log: t)


def test_defaults_variant_and_folder(tmp_path):
    """Unset keys: reduced_order, the default discretisation, out = ./generated, and the
    family's default variant written into the name (CG O1)."""
    [(t, out)] = load_targets(write(tmp_path, '[[target]]\nrobot = "seed002_2r"\n'))
    assert (t.family, t.variant, t.prefix, out) == ("reduced_order", None, "seed002_2r_reduced_order",
                                                     Path("generated").resolve())
    t, _ = make_target({"robot": "seed004_2r", "elastic": True, "family": "ciccarella_germani"})
    assert (t.variant, t.prefix) == ("O1", "seed004_2r_elastic_ciccarella_germani_o1")
    assert t.robot == {"kind": "elastic", "name": "seed004_2r_elastic", "J": 37.5, "K": 20000.0,
                       "rigid": {"kind": "catalog", "name": "seed004_2r"}}


BAD_FILES = [
    ('[[target]]\nrobot = "ur5"\nnosie = 1e-4\n', ["target 1 (ur5 reduced_order)", "unknown key nosie",
                                                  "valid keys: robot, urdf"]),
    ('[[targets]]\nrobot = "ur5"\n', ["unknown table targets", "[[target]]"]),
    ('[[target]\nrobot = "ur5"\n', ["not valid TOML"]),
    ('title = "x"\n', ["unknown table title"]),
    ('', ["no [[target]] tables"]),
    ('[[target]]\nfamily = "tomei"\n', ["give a robot", "catalog: seed000_2r"]),
    ('[[target]]\nrobot = "ur6"\n', ["unknown robot 'ur6'", "catalog: seed000_2r", "panda"]),
    ('[[target]]\nrobot = "arm.urdf"\n', ["unknown robot 'arm.urdf'", "--urdf PATH"]),
    ('[[target]]\nurdf = "nowhere.urdf"\n', ["URDF file not found", "nowhere.urdf"]),
    ('[[target]]\nrobot = "ur5"\nlock = { a = 0.0 }\n', ["lock applies to a URDF robot"]),
    ('[[target]]\nrobot = "ur5"\nfamily = "kalman"\n', ["unknown family 'kalman'", "families: ciccarella_germani"]),
    ('[[target]]\nrobot = "seed004_2r"\nelastic = true\nfamily = "ciccarella_germani"\nvariant = "O5"\n',
     ["ciccarella_germani has no variant 'O5'", "variants: O1, O2, O3, O4"]),
    ('[[target]]\nrobot = "ur5"\nvariant = "O2"\n', ["reduced_order has no variant 'O2'", "no variants"]),
    ('[[target]]\nrobot = "seed004_3r"\nfamily = "ciccarella_germani"\n',
     ["ciccarella_germani needs an elastic robot", "seed004_3r is rigid", "elastic"]),
    ('[[target]]\nrobot = "seed004_2r"\nelastic = true\n', ["reduced_order needs a rigid robot",
                                                            "seed004_2r_elastic is elastic"]),
    ('[[target]]\nrobot = "seed002_2r"\nelastic = true\nfamily = "tomei"\n',
     ["elastic seed002_2r: give J and K", "catalog defaults for: seed004_2r"]),
    ('[[target]]\nrobot = "seed004_2r"\nJ = 1.0\nfamily = "tomei"\n', ["J and K describe an elastic robot"]),
    ('[[target]]\nrobot = "seed004_2r"\nelastic = true\nJ = -1.0\nfamily = "tomei"\n', ["J must be positive"]),
    ('[[target]]\nrobot = "seed004_2r"\nelastic = "yes"\nfamily = "tomei"\n', ["elastic must be true or false"]),
    ('[[target]]\nrobot = "ur5"\ndesign = { k1 = 3.0 }\n', ["unknown design input k1 of reduced_order",
                                                            "valid: k0, eta, v_max"]),
    ('[[target]]\nrobot = "ur5"\ndesign = 3\n', ["design must be a table"]),
    ('[[target]]\nrobot = "ur5"\nparams = { k0 = "big" }\n', ["params['k0'] must be a number"]),
    ('[[target]]\nrobot = "ur5"\ndt = -1e-3\n', ["dt must be a positive finite number"]),
    ('[[target]]\nrobot = "ur5"\nmethod = "rk45"\n', ["method must be one of"]),
    ('[[target]]\nrobot = "ur5"\nprecision = "quad"\n', ["precision must be one of"]),
    # wrong TOML types are refused naming the key and the type, never converted (issue 22, F8, F9)
    ('target = [1, 2]\n', ["target 1: a target must be a table", "got 1 (an integer)"]),
    ('[[target]]\nrobot = "ur5"\nname = ["a", "b"]\n', ["name must be a string, got ['a', 'b'] (an array)"]),
    ('[[target]]\nrobot = "ur5"\nname = 12\n', ["name must be a string, got 12 (an integer)"]),
    ('[[target]]\nrobot = "ur5"\ndt = "1e-3"\n', ["dt must be a number of seconds, got '1e-3' (a string)",
                                                  "without quotes"]),
    ('[[target]]\nrobot = "ur5"\ndt_max = true\n', ["dt_max must be a number of seconds, got True (a boolean)"]),
    ('[[target]]\nrobot = 5\n', ["robot must be a string, got 5 (an integer)"]),
    ('[[target]]\nrobot = "ur5"\nfamily = ["reduced_order"]\n', ["family must be a string"]),
    ('[[target]]\nrobot = "ur5"\nout = 1\n', ["out must be a string, got 1 (an integer)"]),
    ('[[target]]\nrobot = "ur5"\nsubsteps = 2.0\n', ['substeps must be a positive integer or "auto", got 2.0']),
    ('[[target]]\nrobot = "ur5"\ndesign = []\n', ["design must be a table"]),
    ('[[target]]\nrobot = "ur5"\n\n[[target]]\nrobot = "ur5"\n', ["targets 1 and 2 both write",
                                                                  "ur5_reduced_order", "give one a name"]),
]


@pytest.mark.parametrize("text, words", BAD_FILES, ids=[w[0][:30] for _, w in BAD_FILES])
def test_bad_file_names_file_target_and_choices(tmp_path, text, words):
    path = write(tmp_path, text)
    with pytest.raises(TargetError) as e:
        load_targets(path)
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg
    if "[[target]]\n" in text and "both write" not in msg and "TOML" not in msg:
        assert msg.startswith(f"{path}, target 1 (")


def test_python_values_of_the_wrong_type_are_refused():
    """The Target and Discretization a Python caller builds refuse what the targets file does
    (issue 22, F9): a name or variant that is not a string, a time given as a string."""
    from codegen.core.target import Discretization
    robot = {"kind": "catalog", "name": "ur5"}
    for key, value in (("name", ["a", "b"]), ("name", 12), ("variant", 2)):
        with pytest.raises(ValueError, match=f"{key} must be a string, got"):
            Target(robot=robot, family="reduced_order", **{key: value})
    for key in ("dt", "dt_min", "dt_max"):
        with pytest.raises(ValueError, match=f"{key} must be a positive finite number of seconds, got '1e-3' \\(str\\)"):
            Discretization(**{"dt": 1e-3, key: "1e-3"})
    assert Target(robot=robot, family="reduced_order", name="Arm-1").name == "arm_1"


def test_missing_file():
    with pytest.raises(TargetError, match="targets file not found: .*nothere.toml"):
        load_targets("nothere.toml")


def test_round_trip_through_metadata(tmp_path):
    """File -> Target -> emit: the metadata records the Target exactly (catalog robot by name)
    and Target.from_dict gives it back; build_spec resolves the catalog source."""
    from models import load_robot
    from codegen.pipeline.stages import resolve_substeps
    [(t, _)] = load_targets(write(tmp_path, '[[target]]\nrobot = "seed002_2r"\nfamily = "su_nonsmooth"\n'
                                  'design = { form = "xian" }\nparams = { xian = 1.0 }\ndt = 2e-3\n'))
    assert Target.from_dict(json.loads(json.dumps(t.to_dict()))) == t
    spec = build_spec(t)
    assert spec.robot is load_robot("seed002_2r")
    # unstated substeps are "auto": the folder records the number they resolve into
    assert t.discretization.substeps == "auto"
    t = resolve_substeps(t, spec)
    assert t.discretization.substeps == 1
    folder = emit(t, tmp_path / "gen", spec=spec)
    meta = json.loads((folder / f"{t.prefix}.json").read_text())
    assert meta["target"] == t.to_dict() and Target.from_dict(meta["target"]) == t
    assert meta["target"]["robot"] == {"kind": "catalog", "name": "seed002_2r"}
    assert meta["robot"]["source"] == load_robot("seed002_2r").source      # what the reference reads
    assert meta["p_default"][meta["names"]["p"].index("xian")] == 1.0


def test_folder_guard(tmp_path):
    """check_folder: absent or same target passes; another target or a foreign folder refuses
    naming the differences; emit(force=False) refuses before building, force=True replaces."""
    t, _ = make_target({"robot": "seed002_2r", "family": "su_nonsmooth", "substeps": 1})
    check_folder(tmp_path / "gen" / t.prefix, t)
    folder = emit(t, tmp_path / "gen")
    check_folder(folder, t)
    emit(t, tmp_path / "gen", force=False)
    other = t.with_discretization(dt=5e-4, substeps=2)
    with pytest.raises(FolderTaken, match=r"holds another target \(discretization: .*0.001.* -> .*0.0005"):
        check_folder(folder, other)
    before = (folder / f"{t.prefix}.json").read_text()
    with pytest.raises(FolderTaken, match="--force"):
        emit(other, tmp_path / "gen", force=False)
    assert (folder / f"{t.prefix}.json").read_text() == before
    emit(other, tmp_path / "gen", force=True)
    assert json.loads((folder / f"{t.prefix}.json").read_text())["target"]["discretization"]["dt"] == 5e-4
    (tmp_path / "gen" / "mine").mkdir()
    with pytest.raises(FolderTaken, match="exists and is not a generated target"):
        check_folder(tmp_path / "gen" / "mine", t)
