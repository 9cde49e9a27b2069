"""Observer families: one module each, each with ``build(robot, **gains) -> ObserverSpec``.

A family is any module of this package with a ``build`` function; adding a file adds a family.
"""
from __future__ import annotations

import importlib
import pkgutil

from ...core.limits import check_given
from ...core.spec import checked_args, plain

FAMILIES = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
__all__ = ["FAMILIES", "build"]


def build(family, robot, **gains):
    """ObserverSpec of an observer family for a robot; gains designed when not given.

    Parameters
    ----------
    family : str
        One of ``FAMILIES`` (a module of this package).
    robot : models.RobotModel or models.elastic.ElasticRobot
        The robot the observer is built for.
    **gains
        Keyword arguments of the family's ``build`` (gains, design inputs, options); recorded
        as plain data in ``spec.build_args`` so that a ``Target`` can rebuild the spec. One
        keyword every family takes: ``limits``, the declared ranges of the inputs the C checks
        each sample against (None, the default: the robot's declared limits with margins;
        "none"; or a dict of ``q_lower``, ``q_upper``, ``tau_max``: codegen.core.limits).

    Returns
    -------
    codegen.core.spec.ObserverSpec
    """
    if family not in FAMILIES:
        raise KeyError(f"unknown observer family {family!r}; known: {', '.join(FAMILIES)}")
    own = {k: v for k, v in gains.items() if k != "limits"}
    limits = check_given(gains.get("limits"), robot.n)
    module = importlib.import_module(f"{__name__}.{family}")
    if getattr(module, "ROBOT", "") == "elastic" and not hasattr(robot, "rigid"):
        from models.catalog import ELASTIC
        raise ValueError(f"{family} needs an elastic robot (link and motor sides, joint stiffness K, motor "
                         f"inertias J); {getattr(robot, 'name', 'the robot')} is rigid. Elastic robots: a rigid one "
                         f"with J and K given, or the catalog's with default J, K ({', '.join(ELASTIC)})")
    spec = module.build(robot, **checked_args(own))
    spec.limits = limits
    spec.build_args = {k: plain(v) for k, v in gains.items()}
    return spec

