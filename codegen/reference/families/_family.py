"""A reference family bound to the options its spec declares (codegen.core.options), as a value.

``configure(robot, options)`` of a family module returns ``bound(__name__, **kw)``: the module's
contract functions with the keyword arguments fixed, so nothing is stored on the robot and two
observers of one robot with different options never see each other's.
"""
from __future__ import annotations

import inspect
import sys
from functools import partial
from types import SimpleNamespace

CONTRACT = ("rhs", "rhs_split", "model", "rhs_model", "output", "init", "jump", "sizes", "rate", "rate_states",
            "retune", "phases")


def bound(module, **options):
    """The family ``module`` with ``options`` fixed.

    Parameters
    ----------
    module : module or str
        A reference family module (or its ``__name__``) giving ``rhs``, ``output``, ``init``,
        ``sizes`` and optionally ``rhs_split``, ``model`` with ``rhs_model``, ``jump``, ``rate``,
        ``rate_states``, ``retune``, ``phases`` and ``P_NAMES``.
    **options
        Keyword arguments; each contract function receives those its signature names.

    Returns
    -------
    types.SimpleNamespace
        The contract functions (partials where they take options), ``P_NAMES`` if the module
        has it, and the options themselves as attributes.
    """
    module = sys.modules[module] if isinstance(module, str) else module
    family, used = {}, set()
    for name in CONTRACT:
        f = getattr(module, name, None)
        if f is None:
            continue
        kw = {k: v for k, v in options.items() if k in inspect.signature(f).parameters}
        family[name] = partial(f, **kw) if kw else f
        used.update(kw)
    if set(options) - used:
        raise TypeError(f"{module.__name__}: no contract function takes {sorted(set(options) - used)}")
    if hasattr(module, "P_NAMES"):
        family["P_NAMES"] = module.P_NAMES
    return SimpleNamespace(**family, **options)
