"""Synthetic real-arm logs (codegen.evaluate.scenarios.log_grid on codegen.evaluate.sim.real_plant):
the receive clock's statistics and bookkeeping, the sensors, the drifts-and-bursts task, the
default clock's files unchanged, byte-identical reruns, and the truth-side yardsticks on cases
whose answer is known.

Statistical checks use the draw's own size: a fraction within 4 sigma of its probability, a
standard deviation within 10 % (the brief's tolerance; 200 000 draws put its own sampling error
under 1 %).
"""
import hashlib
import json

import numpy as np
import pytest

from codegen.evaluate.scenarios.log_grid import (CLOCKS, TORQUE_SENSORS, cells, kalman_truth, read_rows,
                                                  score_clock)
from codegen.evaluate.sim.real_plant import (RealPlant, drifts_and_bursts, fourier_excitation, point_to_point,
                                             urdf_joint_limits)
from models import load_robot


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")


@pytest.fixture(scope="module")
def receive(ur5):
    """ur5's plant on the receive clock with the grid's sensors (2^20 counts logged to 1e-6 rad,
    0.05 N m torque noise)."""
    return RealPlant(ur5, seed=0, **CLOCKS["receive"], **TORQUE_SENSORS["abs"], counts_per_rev=2 ** 20,
                     position_decimals=6)


@pytest.fixture(scope="module")
def receive_run(receive, ur5):
    """1.5 s of ur5's multi-sine on the receive clock."""
    return receive.run(fourier_excitation(ur5), 1.5, seed=(0, 7))


# ------------------------------------------------------------------------------ the receive clock
def test_receive_delays_have_the_stated_std_and_a_tail(receive):
    """The raw delays and the stamps' delay behind their tick (queued and rounded) have a std
    within 10 % of 0.4 ms over 200 000 rows; every delay is >= 0; 20 000-row logs reach 2.5-6 ms
    (occasional delays up to ~4 ms), far beyond the body (median < 0.6 ms)."""
    N = 200_000
    d = receive.delays(N, seed=11)
    assert np.all(d >= 0)
    assert abs(d.std() - 0.4e-3) < 0.1 * 0.4e-3
    stamps, _, _ = receive.receive_rows(N, seed=11)
    lag = stamps - np.arange(N) * 1e-3
    assert lag.min() >= -1e-12
    assert abs(lag.std() - 0.4e-3) < 0.1 * 0.4e-3, lag.std()
    assert np.median(lag) < 0.6e-3
    for seed in range(3):
        stamps, _, _ = receive.receive_rows(20_000, seed=seed)
        worst = np.max(stamps - np.arange(20_000) * 1e-3)
        assert 2.5e-3 < worst < 6e-3, worst
    # another delay_std scales the delays
    half = RealPlant(receive.robot, seed=0, **{**CLOCKS["receive"], "delay_std": 0.2e-3})
    assert np.allclose(half.delays(1000, seed=11), receive.delays(1000, seed=11) / 2, rtol=1e-12, atol=0)


def test_receive_stamps_are_rounded_increasing_and_bunch(receive):
    """Stamps on the 0.1 ms grid, strictly increasing; each is max(round(s_k + d_k), t_k-1 + r):
    after a late row the next rows are written 0.1 ms apart (bunching); 5 % of the rows repeat,
    never the first; a repeat carries the previous row's tick, the others their own."""
    N = 200_000
    stamps, source, repeat = receive.receive_rows(N, seed=5)
    units = np.round(stamps * 1e4)
    assert np.max(np.abs(stamps * 1e4 - units)) < 1e-6
    assert np.all(np.diff(stamps) > 0)
    own = np.round((np.arange(N) * 1e-3 + receive.delays(N, seed=5)) * 1e4)
    prev = np.concatenate([[-np.inf], units[:-1] + 1])
    assert np.array_equal(units, np.maximum(own, prev))
    bunched = np.diff(units) == 1
    assert 0.01 < bunched.mean() < 0.2                   # rows written back to back after late ones
    p = 0.05
    assert not repeat[0]
    assert abs(repeat.mean() - p) < 4 * np.sqrt(p * (1 - p) / N)
    k = np.flatnonzero(repeat)
    assert np.array_equal(source[k], source[k - 1])
    assert np.array_equal(source[~repeat], np.flatnonzero(~repeat))
    # reproducible, and another seed draws other rows
    again = receive.receive_rows(N, seed=5)
    assert all(np.array_equal(a, b) for a, b in zip(again, (stamps, source, repeat)))
    assert not np.array_equal(receive.receive_rows(1000, seed=6)[0], stamps[:1000])


def test_receive_run_truth_bookkeeping(receive_run, receive, tmp_path):
    """Every tick gives a row; the truth of each row is the state of the tick it carries (a repeat
    the previous row's, written again exactly in q and tau); the files hold the same."""
    run = receive_run
    N = len(run.t)
    assert N == 1501 and np.array_equal(run.t, np.arange(N) / 1000)
    log, truth = run.write(tmp_path, "task")
    rows = read_rows(tmp_path, "task")
    names = receive.robot.joint_names
    assert rows["joint_names"] == list(names)
    assert len(rows["t"]) == N
    tick, rep = rows["tick"], rows["repeat"]
    assert np.array_equal(rows["t_sample"], tick / 1000)
    assert np.array_equal(tick[~rep], np.flatnonzero(~rep))
    k = np.flatnonzero(rep)
    assert len(k) > 0 and np.array_equal(tick[k], tick[k - 1])
    assert np.array_equal(rows["q"], run.q[tick]) and np.array_equal(rows["qd"], run.qd[tick])
    from codegen.core.columns import read_columns
    header, data = read_columns(log)
    tau = data[:, [header.index(f"tau_{j}") for j in names]]
    assert np.array_equal(rows["q_meas"][k], rows["q_meas"][k - 1]) and np.array_equal(tau[k], tau[k - 1])
    assert np.array_equal(tau, run.tau_meas[tick])
    # the tick of each repeated row is nowhere in the log
    assert np.array_equal(np.setdiff1d(np.arange(N), tick), k)
    assert np.array_equal(run.logged, np.isin(np.arange(N), tick))
    stats = run.stats()
    assert stats["rows"] == N and stats["repeats"] == len(k)
    assert stats["delay_ms"]["min"] >= 0


def test_sensors_resolution_and_noise(receive_run, receive):
    """Positions: a 2^20-count encoder written to 1e-6 rad (within D/2 + 0.5e-6 of the truth);
    torque: 0.05 N m white noise on every joint with the plant's offset."""
    run = receive_run
    D = 2 * np.pi / 2 ** 20
    assert run.encoder_step == D
    q = run.q_meas[run.logged]
    assert np.array_equal(np.round(q, 6), q) and np.max(np.abs(q * 1e6 - np.round(q * 1e6))) < 1e-6
    assert np.max(np.abs(q - run.q[run.logged])) <= D / 2 + 0.5e-6 + 1e-12
    err = (run.tau_meas - run.tau)[run.logged] - run.torque_offset
    assert np.array_equal(run.torque_noise_std, np.full(6, 0.05))
    z = err / 0.05
    assert abs(z.mean()) < 4 / np.sqrt(z.size) and abs(z.std() - 1) < 4 / np.sqrt(2 * z.size)
    sensors = receive.truth()["sensors"]
    assert sensors["torque_noise_of"] == "absolute" and sensors["position_decimals"] == 6
    assert sensors["log_clock"] == "receive" and sensors["repeat"] == 0.05


def test_position_noise_before_the_encoder(ur5):
    """White position noise sigma_q: q_m - q has std sqrt(sigma_q^2 + D^2 / 12); none by default
    (D round(q / D) exactly)."""
    q = np.tile(np.linspace(-1, 1, 20_000)[:, None], (1, 6))
    plant = RealPlant(ur5, seed=0, position_noise=1e-4)
    e = plant.measure_position(q, seed=3) - q
    D = plant.encoder_step
    sd = np.sqrt(1e-8 + D * D / 12)
    assert abs(e.std() - sd) < 4 * sd / np.sqrt(2 * e.size) and abs(e.mean()) < 4 * sd / np.sqrt(e.size)
    plain = RealPlant(ur5, seed=0)
    assert np.array_equal(plain.measure_position(q), D * np.round(q / D))


# ------------------------------------------------------------------------------ the default and reruns
# sha256 of the 1.5 s ur5 logs and truths (seed 0) as the plant wrote them before the receive
# clock existed (MuJoCo 4.0.0): the default (jitter) clock must keep writing them bit for bit
TODAY = {"mujoco": "4.0.0",
         "task": ("c1e3e93ce0429536953e4a829c9da70786f011050f10f31be4e3b20ead30cc6c",
                  "9bcf2eecfbdbbfa5f708bf5ef1681e56135bc7a3556d1330e0e255afb22a6240"),
         "task_rms": ("214c06484505c902a2f8e2707dd4242dd7b61a20c6786edc6bc38c8dc0cdb766",
                      "9bcf2eecfbdbbfa5f708bf5ef1681e56135bc7a3556d1330e0e255afb22a6240"),
         "exc": ("a57a754c49df372e97af0b95830b2da58a7ca69e043b8877435c18028cf1cb88",
                 "0684b42d8f127b55fdaa53fb6d832a1969d317e2af6149832745d321f1ad479f")}


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_default_clock_writes_todays_files(ur5, tmp_path):
    import mujoco
    if mujoco.__version__ != TODAY["mujoco"]:
        pytest.skip(f"the pinned files were written with MuJoCo {TODAY['mujoco']}, this is {mujoco.__version__}")
    cases = {"task": ({}, point_to_point(ur5, seed=0), (0, 2)),
             "task_rms": ({"torque_noise_of": "rms"}, point_to_point(ur5, seed=0), (0, 2)),
             "exc": ({"log_clock": "jitter"}, fourier_excitation(ur5), (0, 1))}
    for name, (options, ref, seed) in cases.items():
        run = RealPlant(ur5, seed=0, **options).run(ref, 1.5, seed=seed)
        log, truth = run.write(tmp_path, name)
        assert (_sha(log), _sha(truth)) == TODAY[name], name


def test_reruns_are_byte_identical(receive, ur5, tmp_path):
    """Two runs with the same seed write the same bytes (receive clock, bursts task)."""
    ref = drifts_and_bursts(ur5, T=1.0, bursts=1, seed=4)
    digests = []
    for folder in ("a", "b"):
        run = receive.run(ref, 1.0, seed=(4, 2))
        digests.append([_sha(p) for p in run.write(tmp_path / folder, "task")])
    assert digests[0] == digests[1]


# ------------------------------------------------------------------------------ the bursts task
def _robots():
    from codegen.evaluate.scenarios.mujoco_real import robot_model
    return {name: robot_model(name) for name in ("ur5", "panda", "kinova")}


def test_bursts_task_within_limits_and_fast():
    """20 s on a 0.5 ms grid: within fill x range of the middle, 0.8 x the velocity limit and an
    acceleration of 5 v / s (the bursts') + the drifts' 0.1 v x 2 pi 0.1 Hz, at rest at the
    middle at t = 0, the derivatives derivatives; the bursts reach >= 0.5 x the velocity limit,
    each fast stretch (|qd| > 0.2 v) shorter than 0.5 s, and they are brief (a few % of the
    time); every joint drifts."""
    for name, robot in _robots().items():
        lo, hi = robot.q_lower, robot.q_upper
        v = urdf_joint_limits(robot.source["path"], robot.joint_names)["velocity"]
        c, A = 0.5 * (lo + hi), np.minimum(0.3 * (hi - lo), 1.0)
        ref = drifts_and_bursts(robot, seed=1)
        tt = np.arange(0, 20.0 + 1e-9, 5e-4)
        Q = np.array([ref(t) for t in tt])
        assert np.all(np.abs(Q[:, 0] - c) <= A + 1e-12), name
        assert np.all(np.abs(Q[:, 1]) <= 0.8 * v + 1e-12), name
        assert np.all(np.abs(Q[:, 2]) <= (5.0 + 0.1 * 2 * np.pi * 0.1) * v + 1e-12), name
        assert np.array_equal(Q[0, 0], c) and np.array_equal(Q[0, 1], np.zeros(robot.n))
        assert np.max(np.abs(Q[:, 1]) / v) >= 0.5, name
        fast = np.any(np.abs(Q[:, 1]) > 0.2 * v, axis=1)
        edges = np.flatnonzero(np.diff(fast.astype(int)))
        assert len(edges) >= 2 and not fast[0] and not fast[-1]
        assert np.max(np.diff(edges)[::2]) * 5e-4 < 0.5, name
        assert 0.005 < fast.mean() < 0.2, (name, fast.mean())
        assert np.all(np.abs(Q[:, 0] - c).max(0) > 1e-3), name
        h = 1e-6
        for t in (0.3, 5.0, 11.7, 17.2):
            assert np.allclose((ref(t + h)[0] - ref(t - h)[0]) / (2 * h), ref(t)[1], atol=1e-6)
            assert np.allclose((ref(t + h)[1] - ref(t - h)[1]) / (2 * h), ref(t)[2], atol=1e-4)


@pytest.mark.slow
def test_bursts_run_within_the_effort_limits(ur5):
    """ur5's 20 s bursts task on the real plant (1 kg payload): the applied torque stays within
    the URDF's effort limits (the shoulder needed 159 N m of 150 before bursts were limited to
    5 v / s) and the controller tracks to 1 mrad."""
    plant = RealPlant(ur5, seed=0, log_clock="receive")
    run = plant.run(drifts_and_bursts(ur5, seed=0), 20.0, seed=(0, 5))
    assert np.all(np.abs(run.tau).max(0) < run.effort), np.abs(run.tau).max(0)
    assert np.max(run.tracking_error) < 1e-3


def test_bursts_task_refuses_what_does_not_fit(ur5):
    with pytest.raises(ValueError, match="no room for 4 bursts"):
        drifts_and_bursts(ur5, T=2.0, bursts=4)
    with pytest.raises(ValueError, match="drift_speed"):
        drifts_and_bursts(ur5, drift_speed=0.4)
    assert drifts_and_bursts(ur5, T=1.0)(0.5)[0].shape == (6,)          # too short for a burst: drifts


# ------------------------------------------------------------------------------ yardsticks
def _rows(t_sample, tick, repeat, q_meas, qd):
    return {"t_sample": np.asarray(t_sample, float), "tick": np.asarray(tick), "repeat": np.asarray(repeat, bool),
            "q_meas": np.asarray(q_meas, float), "qd": np.asarray(qd, float), "t": np.asarray(t_sample, float)}


def test_score_clock_on_a_known_case():
    """10 rows, rows 3 and 7 repeats (ticks 0 1 2 2 3 4 5 5 6 7): the true rebuild scores 1 and
    drops exactly the repeats; a tick off by one from row 5 on gets 4 of the 8 kept rows wrong; keeping a
    repeat or dropping another row is counted."""
    tick = np.array([0, 1, 2, 2, 3, 4, 5, 5, 6, 7])
    repeat = np.zeros(10, bool)
    repeat[[3, 7]] = True
    rows = {"tick": tick, "repeat": repeat}
    kept = np.flatnonzero(~repeat)
    s = score_clock(rows, kept, tick[kept] + 100)              # the offset does not matter
    assert s == {"tick_fraction": 1.0, "repeats_dropped_exactly": True, "repeats_kept": 0, "others_dropped": 0}
    wrong = tick[kept] + (kept >= 5)                            # rows 5, 6, 8, 9 off by one
    assert score_clock(rows, kept, wrong)["tick_fraction"] == 4 / 8
    s = score_clock(rows, np.arange(9), tick[:9])
    assert s["repeats_kept"] == 2 and s["others_dropped"] == 1 and not s["repeats_dropped_exactly"]
    with pytest.raises(ValueError, match="ticks: expected 8 integers"):
        score_clock(rows, kept, tick[kept].astype(float))
    with pytest.raises(ValueError, match="kept: expected increasing"):
        score_clock(rows, kept[::-1], tick[kept])


def test_kalman_truth_on_a_known_case():
    """Positions exact on a constant-acceleration motion (the filter's own model), ticks lost
    and rows repeated: the tuned filter's error over the second half is ~0; the repeats must be
    dropped (their sample time is the previous row's)."""
    N = 3000
    tick = np.arange(N)
    repeat = np.zeros(N, bool)
    repeat[50::37] = True
    tick = np.where(repeat, np.roll(tick, 1), tick)             # a repeat carries the previous tick
    t = tick * 1e-3
    a, v = np.array([0.3, -1.0]), np.array([0.5, 0.2])
    q = 0.5 * np.outer(t * t, a) + np.outer(t, v)
    qd = np.outer(t, a) + v
    res = kalman_truth(_rows(t, tick, repeat, q, qd), r=1e-14)
    assert res["rms"] < 1e-6 and res["rows"] == N - repeat.sum()
    with pytest.raises(ValueError, match="sample times must be >= 3 and increase"):
        kalman_truth(_rows(t, tick, np.zeros(N, bool), q, qd), r=1e-14)


def test_kalman_truth_finds_the_best_q():
    """On a quantised sinusoid the golden-section result is at least as good as every value of
    a 0.05-decade grid around it (and of the coarse grid)."""
    from codegen.evaluate.baselines import Kalman
    from codegen.evaluate.metrics import rms_after
    t = np.arange(2000) * 1e-3
    D = 1e-4
    q = np.column_stack([np.sin(3 * t), 0.5 * np.cos(5 * t)])
    qd = np.column_stack([3 * np.cos(3 * t), -2.5 * np.sin(5 * t)])
    rows = _rows(t, np.arange(2000), np.zeros(2000, bool), D * np.round(q / D), qd)
    res = kalman_truth(rows, r=D * D / 12)
    assert res["rms"] <= res["rms_grid"]

    def rms(logq):
        k = Kalman(2, 1e-3, q=10 ** logq, r=D * D / 12)
        k.reset(rows["q_meas"][0])
        return rms_after(t, k.run(rows["q_meas"], t=t) - qd, res["t_ss"])
    x = np.log10(res["q"])
    dense = [rms(v) for v in np.arange(x - 0.5, x + 0.5, 0.05)]
    assert res["rms"] <= min(dense) * (1 + 1e-9), (res, min(dense))
    assert abs(res["rms"] - rms(x)) <= 1e-12 * res["rms"]


# ------------------------------------------------------------------------------ the grid
def test_grid_cells_and_registry():
    names = cells()
    assert len(names) == 36 == len(set(names))
    assert "ur5-bursts-abs-receive" in names and "kinova-p2p-rms-jitter" in names
    with pytest.raises(ValueError, match="task: expected one of p2p, multisine, bursts, got sine"):
        cells(tasks=["sine"])
    from codegen.evaluate.scenarios import registry
    assert "log-grid" in registry()


def test_bad_clock_options_are_refused(ur5):
    with pytest.raises(ValueError, match="log_clock must be one of jitter, receive"):
        RealPlant(ur5, log_clock="sampled")
    with pytest.raises(ValueError, match="tick must be a positive whole number of clock units"):
        RealPlant(ur5, log_clock="receive", tick=1.5e-7)
    with pytest.raises(ValueError, match="repeat must be a probability"):
        RealPlant(ur5, repeat=0.7)
    with pytest.raises(ValueError, match="position_decimals must be None or an integer"):
        RealPlant(ur5, position_decimals=1.5)
    with pytest.raises(ValueError, match="stamp_resolution must be <= tick"):
        RealPlant(ur5, stamp_resolution=2e-3)


@pytest.mark.long  # experiment-scale: `make test-long`
def test_cell_files_and_rerun(tmp_path):
    """A 1.5 s cell of the grid (receive clock, bursts): the files, cell.json's record, the
    yardstick, and a rerun (through ``grid``) that writes the same bytes."""
    from codegen.evaluate.scenarios.log_grid import cell, grid
    name = "ur5-bursts-abs-receive"
    s = cell(name, tmp_path / "a", T=1.5, T_excitation=1.0)
    folder = tmp_path / "a" / name
    assert sorted(p.name for p in folder.iterdir()) == sorted(s["files"])
    record = json.loads((folder / "cell.json").read_text())
    assert record["clock_settings"]["delay_std"] == 0.4e-3 and record["sensors"]["torque"]["torque_noise"] == 0.05
    assert record["plant"]["coulomb"] and record["measured"]["task"]["rows"] == 1501
    assert 0 < record["yardstick"]["kalman_truth"]["rms"] < 0.05
    rows = read_rows(folder, "excitation")
    assert np.array_equal(rows["t_sample"], rows["tick"] / 1000)
    again = grid(tmp_path / "b", names=[name], T=1.5, T_excitation=1.0, progress=False)
    assert again[name]["kalman_truth_rms"] == s["yardstick"]["kalman_truth"]["rms"]
    for f in s["files"]:
        assert _sha(folder / f) == _sha(tmp_path / "b" / name / f), f
