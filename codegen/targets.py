"""The default targets of `make generate` and the helpers the CLI and tests share."""
from __future__ import annotations

DEFAULT_ROBOTS = ["seed000_2r", "seed002_2r", "seed003_2r_abs", "ur5", "panda"]
DEFAULT_FAMILY = "reduced_order"


def default_spec(robot_name, family=DEFAULT_FAMILY):
    from models import load_robot

    from . import observers
    return observers.build(family, load_robot(robot_name))
