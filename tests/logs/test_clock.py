"""A log's sample clock found from the data (codegen.logs.clock): receive-time stamps rebuilt on the
robot's tick, repeated rows dropped, a jittering sampler's stamps kept, a robot-time column used."""
import numpy as np
import pytest

from codegen.core.columns import write_columns
from codegen.logs.clock import parse_mode, rebuild, repeated_rows
from codegen.logs.recording import RecordingError, read_csv, read_log
from receive_log import motion, receive_time

JOINTS = ["a", "b", "c", "d", "e", "f"]


def _log(N=4000, seed=0, resolution=1e-6, noise=0.0, **clock):
    """A 6-joint receive-time log: (stamps, Q, TAU, true tick of each row, repeated)."""
    stamps, source, repeated = receive_time(N, seed=seed, **clock)
    q, _ = motion(np.arange(N) * 1e-3, len(JOINTS), seed)
    rng = np.random.default_rng(seed + 7)
    q = q + noise * rng.standard_normal(q.shape)
    q = np.round(q / resolution) * resolution if resolution else q
    tau = rng.standard_normal(q.shape)
    return stamps, q[source], tau[source], source, repeated


def _right(clock, source):
    """Fraction of the kept rows whose tick (from the first kept row's) is the true one."""
    true = source[clock.kept] - source[clock.kept[0]]
    return float(np.mean(clock.ticks == true))


@pytest.mark.parametrize("seed, resolution, noise", [(0, 1e-6, 0.0), (1, 2 * np.pi / 2 ** 16, 0.0), (2, 1e-9, 2e-5)])
def test_receive_time_stamps_are_rebuilt_on_the_tick(seed, resolution, noise):
    """The sensors of a real log (1e-6 rad decimals; a 2^16 encoder; white noise 2e-5 rad), stamps
    0.4 ms std behind a 1 ms tick, 5 % repeated rows: every repeated row dropped and nothing else,
    every kept row on its true tick (measured: all of them), the period to 2e-5 (the least-squares
    slope of the stamps on the ticks: its std is the delays' std sqrt(12 / N^3), 3e-6 here, more with
    bunching)."""
    stamps, Q, TAU, source, repeated = _log(seed=seed, resolution=resolution, noise=noise)
    clock = rebuild(stamps, Q, TAU)
    assert clock.kind == "ticks" and clock.rebuilt
    assert np.array_equal(np.setdiff1d(np.arange(len(stamps)), clock.kept), np.flatnonzero(repeated))
    assert _right(clock, source) >= 0.999
    assert clock.period == pytest.approx(1e-3, rel=2e-5) and abs(clock.period - 1e-3) <= 4 * clock.delay["period_std"]
    assert np.all(np.diff(clock.t) > 0) and np.all(clock.t <= stamps[clock.kept] + 1e-12)
    assert clock.certain >= 0.99
    text = clock.describe()
    assert "receive-time stamps" in text and "behind a 1 ms tick" in text and "repeated rows" in text
    assert clock.delay["std"] == pytest.approx(0.4e-3, rel=0.3)


@pytest.mark.slow
def test_wide_delays_and_bunching_still_find_the_tick():
    """Delays of 0.8 ms std (the stamps' phase at 1 kHz nearly uniform, a fifth of them tied):
    the period from q's whole-tick runs, every row right."""
    stamps, Q, TAU, source, _ = _log(seed=3, delay_std=0.8e-3)
    clock = rebuild(stamps, Q, TAU)
    assert clock.kind == "ticks" and _right(clock, source) >= 0.999
    assert abs(clock.period - 1e-3) <= 4 * clock.delay["period_std"]        # as sure as it says


def test_a_jittering_sampler_keeps_its_stamps():
    """Sample times that really jitter (U(0.7, 1.6) ms, 1 us clock): q is smoother on them than
    on any tick, so they are kept, every row."""
    rng = np.random.default_rng(5)
    t = np.round(np.concatenate([[0.0], np.cumsum(rng.uniform(0.7e-3, 1.6e-3, 3000))]), 6)
    q, _ = motion(t, len(JOINTS), 5)
    clock = rebuild(t, np.round(q / 1e-6) * 1e-6)
    assert clock.kind == "stamps" and not clock.rebuilt and np.array_equal(clock.t, t)
    assert len(clock.kept) == len(t) and "a sampler that jitters" in clock.describe()


def test_uniform_stamps_are_kept_as_they_are():
    t = np.arange(3000) * 1e-3
    q, _ = motion(t, 2)
    clock = rebuild(t, q)
    assert clock.kind == "stamps" and "uniform" in clock.reason and np.array_equal(clock.t, t)


def test_a_robot_time_column_is_the_clock():
    stamps, Q, TAU, source, repeated = _log(N=2000)
    t_robot = source * 1e-3
    clock = rebuild(stamps, Q, TAU, t_robot=t_robot)
    assert clock.kind == "robot" and clock.repeated == int(repeated.sum())
    assert np.array_equal(clock.t, t_robot[clock.kept]) and "t_robot" in clock.describe()


def test_a_given_period_and_the_modes():
    stamps, Q, TAU, source, _ = _log(N=3000)
    clock = rebuild(stamps, Q, TAU, mode="ticks", period=1e-3)
    assert clock.period == 1e-3 and _right(clock, source) >= 0.999
    with pytest.raises(ValueError, match="must increase strictly"):
        rebuild(stamps, Q, TAU, mode="stamps")                # the stamps tie
    assert parse_mode("ticks=0.002") == ("ticks", 0.002) and parse_mode("auto") == ("auto", None)
    for bad in ("tick", "stamps=1", "ticks=-1", "ticks=x"):
        with pytest.raises(ValueError, match="clock"):
            parse_mode(bad)
    with pytest.raises(ValueError, match="go back"):
        rebuild(np.array([0.0, 2e-3, 1e-3] + [3e-3] * 0), np.zeros((3, 1)))


def test_repeated_rows_are_whole_rows():
    v = np.array([[1.0, 2.0], [1.0, 2.0], [1.0, 3.0], [1.0, 3.0]])
    assert repeated_rows(v).tolist() == [False, True, False, True]


def test_a_receive_time_csv_is_read_on_its_clock(tmp_path):
    """read_csv refuses the tied stamps and says what would read them; read_log rebuilds the
    clock; the clock maps every row of the file to the kept row whose sample it carries."""
    stamps, Q, TAU, source, repeated = _log(N=3000)
    cols = {"t": stamps, **{f"q_{j}": Q[:, i] for i, j in enumerate(JOINTS)},
            **{f"tau_{j}": TAU[:, i] for i, j in enumerate(JOINTS)}}
    path = write_columns(tmp_path / "log.csv", cols)
    with pytest.raises(RecordingError, match="--clock auto rebuilds"):
        read_csv(path, JOINTS)
    rec, clock = read_log(path, JOINTS)
    assert clock.kind == "ticks" and len(rec.t) == len(clock.kept) == len(stamps) - repeated.sum()
    rows = clock.row_of()
    assert len(rows) == len(stamps) and np.array_equal(Q, rec.q[rows])
    with pytest.raises(RecordingError, match="log.csv.*must increase strictly"):
        read_log(path, JOINTS, "stamps")


@pytest.mark.long            # experiment-scale: `make test-long`
def test_memory_does_not_grow_with_the_neighbours():
    """Issue 34, R4: a 200 MB log (1.4 M rows, 7 joints) took 16 GB to rebuild its clock (the local
    fits held rows x 97 neighbours x joints at once, the tick fit rows x 24^2 candidates); the fits
    now go in blocks of rows (measured: 1.8 GB for that log, the same ticks). Here: doubling the
    rows adds less memory than 100 copies of the added positions (measured: 48, the whole-log arrays
    of 24 candidate ticks a row, costs and forward-backward; it was 209), and the ticks are still
    all right."""
    import tracemalloc
    peaks = []
    for N in (20000, 40000):
        stamps, Q, TAU, source, _ = _log(N=N, seed=4)
        tracemalloc.start()
        clock = rebuild(stamps, Q, TAU)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert clock.kind == "ticks" and _right(clock, source) >= 0.999
    added = 20000 * len(JOINTS) * 8
    assert peaks[1] - peaks[0] < 100 * added, (peaks, added)
