"""The log-grid judged end to end (codegen.evaluate.scenarios.log_judge), on one short cell written
here: ur5's multi-sine through the MuJoCo real plant (perturbed inertials, payload, friction, 1 %
torque noise, a 2^20 encoder logged to 1e-6 rad), its rows stamped by a logger's receive times
(0.4 ms std behind the 1 ms tick, 5 % repeated rows). Only the task log is given to ``compare``;
the truth, kept aside, judges the issue's bars: the ticks, the best observer and kalman_model
against the Kalman filter tuned on the truth, every family against its own best gain."""
import math

import pytest

from codegen.evaluate.scenarios import log_grid, log_judge


@pytest.mark.long
def test_a_receive_time_log_judged_against_its_truth(tmp_path):
    name = "ur5-multisine-rms-receive"
    log_grid.cell(name, tmp_path, T=8.0, T_excitation=4.0)
    r = log_judge.judge(tmp_path / name, "urdf")
    assert r["all_finite"]
    assert r["clock"]["kind"] == "ticks" and r["clock"]["tick_fraction"] >= 0.999
    assert r["clock"]["repeats_dropped_exactly"]
    assert r["best_observer_ratio"] <= 1.2, r["best_observer_ratio"]
    assert r["kalman_model_ratio"] <= 1.0, r["kalman_model_ratio"]
    worst = {k: v["ratio"] for k, v in r["families"].items() if v["ratio"] > 1.3}
    assert not worst, worst
    for k, m in r["methods"].items():
        assert math.isfinite(m["rms"]), k
