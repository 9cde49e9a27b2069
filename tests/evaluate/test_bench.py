"""`make bench`'s smoke (`bench --smoke`): every path of the bench runs, so that a refusal (the
stability check once refused seed004's elastic ur5 bench, and no figure came out) cannot break it
unseen. Its figures are timings: nothing here asserts a speed, only that the rows are there, finite
and consistent."""
import json
import shutil

import numpy as np
import pytest

from codegen.cli import main
from codegen.verify import c_programs

PIN_MISSING = c_programs.pin_bench_missing()


@pytest.mark.long
@pytest.mark.skipif(PIN_MISSING is not None, reason=f"pin_aba cannot be built: {PIN_MISSING}")
def test_bench_smoke_runs_every_row(tmp_path, capsys):
    """About a minute: the observer-RHS table on ur5, kalman_model's step with the model on
    seed000_2r, Ciccarella-Germani O1 on elastic ur5 (cross-checked against the reference)."""
    path = tmp_path / "bench.json"
    assert main(["bench", "--smoke", "--json", str(path)]) == 0
    out = json.loads(path.read_text())
    (row,) = out["observer_rhs"]
    assert row["robot"] == "ur5"
    for key in ("ns_rhs", "ns_step", "ns_rk4_zoh_step", "ns_pin_aba"):
        assert np.isfinite(row[key]) and row[key] > 0, key
    assert row["ratio_step_over_aba"] == pytest.approx(row["ns_step"] / row["ns_pin_aba"])
    km = out["scenarios"]["kalman_model"]
    assert km["variant"] == "model" and km["design_wall_s"] > 0 and km["ns_step"] > 0
    if shutil.which("valgrind"):
        assert row["instructions_step"] > 0 and row["instructions_pin_aba"] > 0
        assert row["ratio_instructions_step_over_aba"] == pytest.approx(
            row["instructions_step"] / row["instructions_pin_aba"])
        assert km["instructions_step"] > 0
    (cg,) = out["scenarios"]["seed004"]
    assert cg["robot"] == "ur5_elastic" and cg["rhs_rel_err_vs_reference"] < 1e-9
    assert "kalman_model:" in capsys.readouterr().out
