"""The default gains of the reduced-order families: which design, at which discretisation, and
kept inside the stable region (shared by reduced_order, reduced_order_hybrid, nicosia_tomei).

    design="noise"      (default) the gain minimising the predicted error for the sensor noise
                        and model uncertainty (codegen.families.design.noise), with (12) in the report
    design="guarantee"  the gain of (12) (seed 000's, the papers' experiments)
"""
from __future__ import annotations

from ...core.target import DEFAULT_DISCRETIZATION, discretization

DESIGNS = ("noise", "guarantee")


def design_discretization(dt=None):
    """The discretisation a default is designed for: the default one, at ``dt`` if given."""
    return discretization(None, dt=dt)


def check_design(design):
    if design not in DESIGNS:
        raise ValueError(f"design must be one of {DESIGNS}, got {design!r}")
    return design


def stable_report(spec, disc=DEFAULT_DISCRETIZATION):
    """``spec`` with designed gains inside the stable region of ``disc`` (codegen.discrete.stability),
    its design report completed with what the check found (and the gains it lowered)."""
    from ...discrete.stability import stable_defaults
    stable, report = stable_defaults(spec, disc)
    lowered = {} if stable is spec else {"lowered_to_stable": dict(zip(spec.p_names, stable.p_default.tolist()))}
    stable.design = {**spec.design, "stability": {"discretization": disc.to_dict(), **report.as_dict()},
                     **lowered}
    return stable
