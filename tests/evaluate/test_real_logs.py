"""The real-log judge's own parts on data whose truth we wrote (no real log needed): the intervals
q's increments against a velocity signal give, the repeated rows, the CSV a log is written as."""
import numpy as np
import pytest

from codegen.core.columns import read_columns
from codegen.evaluate.scenarios import real_judge, real_logs


def _motion(t, n=3):
    f = np.array([0.3, 0.7, 1.1, 0.4, 0.9, 1.3])[:n]
    return np.sin(2 * np.pi * t[:, None] * f), 2 * np.pi * f * np.cos(2 * np.pi * t[:, None] * f)


def test_intervals_of_a_jittered_sampler_are_found_from_the_velocity_signal():
    rng = np.random.default_rng(0)
    dt = rng.choice([0.987e-3, 1.05e-3, 1.974e-3], size=3000, p=[0.85, 0.1, 0.05])
    t = np.concatenate([[0.0], np.cumsum(dt)])
    q, dq = _motion(t)
    q = q + 1e-7 * rng.standard_normal(q.shape)
    # the velocity at each row's end over the interval before it: the exact mean velocity
    dq[1:] = np.diff(q, axis=0) / dt[:, None] + 1e-5 * rng.standard_normal(dq[1:].shape)
    got, known, repeat, conv, rel = real_logs.true_intervals(q, dq, 25e-6)
    assert conv == "cur" and not repeat.any()
    assert known.mean() > 0.8
    assert np.max(np.abs(got[known] - dt[known])) < 25e-6      # the tolerance it is known for


def test_whole_ticks_and_repeated_rows():
    rng = np.random.default_rng(1)
    ticks = rng.choice([1, 2, 3], size=2000, p=[0.9, 0.07, 0.03])
    t = 1e-3 * np.concatenate([[0], np.cumsum(ticks)])
    q, dq = _motion(t)
    q[500] = q[499]                               # a stale row while the arm moves
    got, known, repeat, _, _ = real_logs.true_intervals(q, dq, 1e-4, tick=1e-3)
    assert repeat[499] and got[499] == 0
    fine = known & ~np.isin(np.arange(len(ticks)), [499, 500])
    assert np.array_equal(np.round(got[fine] / 1e-3), ticks[fine])


def _log(arm, tmp_path):
    t = np.arange(50) * 1e-3
    q, dq = _motion(t, 6)
    spec = real_logs.ARMS[arm]
    names = [f"j{i}" for i in range(6)]
    return real_logs.Log("x", arm, t, q, dq, np.zeros_like(q), names,
                         None if spec["robot"] else "<robot name='x'/>")


@pytest.mark.parametrize("arm, qdm", [("gen3", True), ("ur10e", False)])
def test_the_velocity_signal_is_written_only_where_the_product_gets_it(arm, qdm, tmp_path):
    path, options = real_logs.write_log(_log(arm, tmp_path), tmp_path)
    header, data = read_columns(path, ValueError)
    assert header[:7] == ["t"] + [f"q_j{i}" for i in range(6)]
    assert any(h.startswith("qdm_") for h in header) == qdm
    assert options["urdf"].read_text() == "<robot name='x'/>"


def test_the_folder_is_the_environments(tmp_path, monkeypatch):
    monkeypatch.setenv(real_logs.ENV, str(tmp_path))
    assert real_logs.folder() == tmp_path
    monkeypatch.setenv(real_logs.ENV, str(tmp_path / "absent"))
    assert real_logs.folder() is None


def test_an_error_line_without_its_progress_bar():
    text = "identify x: 0it [00:00, ?it/s]\ridentify x: 0it [00:00, smoothing]error: recording: no motion\n   \n"
    assert real_judge._last_line(text) == "error: recording: no motion"
