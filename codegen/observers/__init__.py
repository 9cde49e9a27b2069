"""Observer families: one module each, each with ``build(robot, **gains) -> ObserverSpec``."""
from __future__ import annotations

import importlib

FAMILIES = ["reduced_order"]


def build(family, robot, **gains):
    """ObserverSpec of observer ``family`` for ``robot``; gains designed when not given."""
    if family not in FAMILIES:
        raise KeyError(f"unknown observer family {family!r}; known: {', '.join(FAMILIES)}")
    return importlib.import_module(f"{__name__}.{family}").build(robot, **gains)
