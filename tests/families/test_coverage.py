"""Every family is covered everywhere it must be, in the manner of python-control's kwargs_test:
adding a family file without its reference, its example robot, its default target or its README
row fails here, naming what is missing."""
import importlib
import re
import tomllib
from pathlib import Path

import pytest

from codegen.families import controllers, observers
from codegen.pipeline.targets_file import make_target
from codegen.reference import FAMILIES as REFERENCE

ROOT = Path(__file__).resolve().parents[2]
README_ROWS = set(re.findall(r"^\| `(\w+)` \|", (ROOT / "README.md").read_text(), flags=re.M))
TARGETS = tomllib.loads((ROOT / "targets.toml").read_text())["target"]


@pytest.mark.parametrize("family", observers.FAMILIES)
def test_observer_family_is_covered(family):
    module = importlib.import_module(f"{observers.__name__}.{family}")
    assert family in REFERENCE, f"{family}: no codegen/reference/families/{family}.py"
    examples = getattr(module, "EXAMPLES", None)
    assert examples, f"{family}: declares no EXAMPLES (the robots its cross-checks are built on)"
    for i, entry in enumerate(examples):
        target, _ = make_target(dict(entry, family=family), where=f"{family}.EXAMPLES[{i}]")
        assert target.family == family
    assert any(t.get("family") == family for t in TARGETS), f"{family}: no target in targets.toml"
    assert family in README_ROWS, f"{family}: no row | `{family}` | in README.md's Observers table"


@pytest.mark.parametrize("law", list(controllers.FAMILIES))
def test_control_law_has_a_reference(law):
    assert law in REFERENCE, f"{law}: no codegen/reference/families/{law}.py"


def test_reference_has_no_orphan():
    """Every reference module checks a family or a law that exists."""
    orphans = set(REFERENCE) - set(observers.FAMILIES) - set(controllers.FAMILIES)
    assert not orphans, f"reference modules without a family: {sorted(orphans)}"
