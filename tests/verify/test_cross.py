"""The cross-check: emitted C against the independent reference (codegen.verify.cross_check)."""
import numpy as np
import pytest

from codegen.verify import cross_check
from conftest import DEFAULT

TOL = 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("name", DEFAULT)
def test_emitted_c_equals_reference(name, spec_of):
    """>= 1000 random inputs per default target: single steps (estimate and next state, at dt and
    after a random elapsed time), the RHS, and 1000-sample runs at dt and over jittered time
    stamps; relative error <= 1e-9."""
    r = cross_check(spec_of(name), count=1000)
    assert r["samples"] >= 1000
    for key in ("step_est", "step_state", "step_dt_est", "step_dt_state", "rhs", "run", "run_t"):
        assert r[key] <= TOL, (key, r)


@pytest.mark.parametrize("name,method,substeps,hold", [("seed000_2r", "euler", 1, "zoh"),
                                                       ("seed000_2r", "rk4", 3, "zoh"),
                                                       ("seed000_2r", "rk4", 2, "foh"),
                                                       ("ur5", "rk4", 1, "foh"),
                                                       ("seed000_2r", "expmid", 2, "zoh"),
                                                       ("seed000_2r", "expmid", 1, "foh"),
                                                       ("seed000_2r", "expmid1", 2, "zoh")])
def test_other_discretizations_match_reference(name, method, substeps, hold, spec_of):
    """The C against the reference (1e-9) under the other methods, holds and sub-steps."""
    r = cross_check(spec_of(name), count=300, dt=2e-3, method=method, substeps=substeps, hold=hold)
    assert np.max([v for k, v in r.items() if k != "samples"]) <= TOL


@pytest.mark.parametrize("family,robot", [("reduced_order_hybrid", "seed000_2r"),
                                          ("reduced_order_switched", "seed000_2r"),
                                          ("extended_state", "seed000_2r"),
                                          ("nicosia_tomei", "seed000_2r"),
                                          ("lotfi_namvar", "seed002_2r"),
                                          ("su_nonsmooth", "seed002_2r"),
                                          ("ii_speed", "seed003_2r_abs"),
                                          # minutes (its quadrature kernel): the long tier
                                          pytest.param("ii_aov", "seed003_2r_abs", marks=pytest.mark.long)])
@pytest.mark.slow
def test_cli_check_works_for_every_rigid_family(family, robot):
    """`python -m codegen check ROBOT --family F` (the generic cross-check with the family's own
    random inputs where it has them) for every rigid-robot family; elastic families are
    cross-checked in tests/papers/test_seed004.py."""
    from codegen.cli import main
    assert main(["check", robot, "--family", family, "--count", "100"]) == 0
