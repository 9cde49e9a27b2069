"""Control laws the experiments need, as ObserverSpecs (stateless blocks, emitted like observers).

| family               | law                                                        |
|----------------------|------------------------------------------------------------|
| seed000_torque_ex1   | open-loop torque of seed 000 Example 1 [S000 (18)]         |
| seed000_torque_ex2   | open-loop torque of seed 000 Example 2 [S000 (19)]         |
| seed000_tracking     | seed 000 Example-3 output-feedback law (docs/papers/seed000.md §1.4)         |
| spong_fl             | Spong's feedback linearisation (docs/papers/seed004.md §9)                   |
| spong_manifold       | Spong's integral-manifold controller (docs/papers/seed004.md §10)            |
"""
from __future__ import annotations

import importlib
import pkgutil


def _modules():
    return [importlib.import_module(f"{__name__}.{m.name}") for m in pkgutil.iter_modules(__path__)
            if not m.name.startswith("_")]


def _laws():
    """law name -> builder, from the ``LAWS`` of every module of this package."""
    return {name: law for module in _modules() for name, law in module.LAWS.items()}


# a module's ELASTIC = True: its laws need an ElasticRobot (the others: a rigid one)
FAMILIES = tuple(sorted(_laws()))
ELASTIC = tuple(sorted(name for m in _modules() if getattr(m, "ELASTIC", False) for name in m.LAWS))


def build(family, robot, **kwargs):
    """The ObserverSpec of control law ``family`` for ``robot`` (keyword arguments recorded in
    ``spec.build_args`` so that a Target can rebuild it).

    Parameters
    ----------
    family : str
        One of ``FAMILIES``.
    robot : RobotModel or ElasticRobot
    **kwargs
        Arguments of the law's builder (gains, reference, saturation).

    Returns
    -------
    codegen.core.spec.ObserverSpec
    """
    from ...core.spec import checked_args, plain
    laws = _laws()
    if family not in laws:
        raise KeyError(f"unknown control law {family!r}; known: {', '.join(FAMILIES)}")
    spec = laws[family](robot, **checked_args(kwargs))
    spec.build_args = {k: plain(v) for k, v in kwargs.items()}
    return spec
