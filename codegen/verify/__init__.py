"""Verification, owned by neither side: random inputs per family, the error measure, and the
C-vs-reference cross-check (docs/architecture.md §3). The CLI and the tests call it from here.

    from codegen.verify import cross_check
    worst = cross_check(spec, count=1000)       # dict of worst relative errors
"""
from .cross import cross_check
from .inputs import random_inputs, run_inputs
from .measure import relative_error, saturated_samples, saturation_mask

__all__ = ["cross_check", "random_inputs", "relative_error", "run_inputs", "saturated_samples", "saturation_mask"]
