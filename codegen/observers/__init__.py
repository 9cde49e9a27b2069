"""Observer families: one module each, each with ``build(robot, **gains) -> ObserverSpec``.

A family is any module of this package with a ``build`` function; adding a file adds a family.
"""
from __future__ import annotations

import importlib
import pkgutil

FAMILIES = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def build(family, robot, **gains):
    """ObserverSpec of observer ``family`` for ``robot``; gains designed when not given."""
    if family not in FAMILIES:
        raise KeyError(f"unknown observer family {family!r}; known: {', '.join(FAMILIES)}")
    return importlib.import_module(f"{__name__}.{family}").build(robot, **gains)
