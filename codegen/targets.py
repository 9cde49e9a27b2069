"""The default targets of `make generate` and the helpers the CLI and tests share."""
from __future__ import annotations

DEFAULT_ROBOTS = ["seed000_2r", "seed002_2r", "seed003_2r_abs", "ur5", "panda"]
DEFAULT_FAMILY = "reduced_order"


def default_spec(robot_name, family=DEFAULT_FAMILY):
    from models import load_robot

    from . import observers
    return observers.build(family, load_robot(robot_name))


def build_spec(target):
    """The ObserverSpec a Target describes: its robot rebuilt from the source, then the family's
    ``build`` with the target's variant and build arguments (observers, then control laws).

    Parameters
    ----------
    target : codegen.target.Target

    Returns
    -------
    codegen.spec.ObserverSpec
    """
    from models import from_source

    from . import controllers, observers
    kwargs = dict(target.build, **({"variant": target.variant} if target.variant else {}))
    robot = from_source(target.robot)
    if target.family in observers.FAMILIES:
        return observers.build(target.family, robot, **kwargs)
    return controllers.build(target.family, robot, **kwargs)
