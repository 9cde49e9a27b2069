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
    clock = rebuild(stamps, Q)
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
    clock = rebuild(stamps, Q)
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
    clock = rebuild(stamps, Q, t_robot=t_robot)
    assert clock.kind == "robot" and clock.repeated == int(repeated.sum())
    assert np.array_equal(clock.t, t_robot[clock.kept]) and "t_robot" in clock.describe()


def test_a_given_period_and_the_modes():
    stamps, Q, TAU, source, _ = _log(N=3000)
    clock = rebuild(stamps, Q, mode="ticks", period=1e-3)
    assert clock.period == 1e-3 and _right(clock, source) >= 0.999
    with pytest.raises(ValueError, match="must increase strictly"):
        rebuild(stamps, Q, mode="stamps")                # the stamps tie
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
        clock = rebuild(stamps, Q)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert clock.kind == "ticks" and _right(clock, source) >= 0.999
    added = 20000 * len(JOINTS) * 8
    assert peaks[1] - peaks[0] < 100 * added, (peaks, added)


def test_a_logger_polling_at_its_own_rate_still_finds_the_tick():
    """Delays uniform over a whole tick (the stamps' phase carries nothing; the real Panda's are
    uniform over 1.1 ms): the period from q's whole-tick runs, not from a chance peak of the stamps'
    phase (it was 0.9849 ms on the real log), every row on its true tick."""
    stamps, source, _ = receive_time(8000, seed=11, delay_std=1.1e-3 / np.sqrt(12.0), delay="uniform")
    q, _ = motion(np.arange(8000) * 1e-3, len(JOINTS), 11)
    clock = rebuild(stamps, np.round(q / 1e-6)[source] * 1e-6)
    assert clock.kind == "ticks" and _right(clock, source) >= 0.999
    assert abs(clock.period - 1e-3) <= 2e-4 * 1e-3


def test_a_row_is_a_new_sample_when_its_positions_are(tmp_path):
    """Issue 42: a torque read apart from the encoders and a counter that changes every row do not
    make a repeated q a new sample: the same rows dropped, the same ticks, as without them."""
    stamps, Q, TAU, source, repeated = _log(N=3000)
    TAU = TAU + 1e-3 * np.arange(len(stamps))[:, None]           # fresh torque on every row
    cols = {"t": stamps, **{f"q_{j}": Q[:, i] for i, j in enumerate(JOINTS)},
            **{f"tau_{j}": TAU[:, i] for i, j in enumerate(JOINTS)}, "counter": np.arange(len(stamps))}
    rec, clock = read_log(write_columns(tmp_path / "log.csv", cols), JOINTS)
    assert clock.kind == "ticks" and clock.repeated == int(repeated.sum()) and _right(clock, source) >= 0.999


def _sampler(N, seed, lag=0.0):
    """A sampler whose intervals take two values (0.985 ms, 1.060 ms a fifth of the time, as a real
    Gen3's) with a row counter x 1 ms as its time column, positions to 1e-7 rad and its own velocity
    signal (lagging by ``lag`` s)."""
    rng = np.random.default_rng(seed)
    h = np.where(rng.random(N - 1) < 0.2, 1.060e-3, 0.985e-3)
    t = np.concatenate([[0.0], np.cumsum(h)])
    q, qd = motion(t, len(JOINTS), seed)
    qdm = motion(t - lag, len(JOINTS), seed)[1]
    return np.arange(N) * 1e-3, np.round(q / 1e-7) * 1e-7 + 2e-6 * rng.standard_normal(q.shape), qdm, h


def test_the_velocity_signal_measures_each_interval():
    """A counter that is not the sample clock: with the robot's velocity signal each interval is
    found (95 % of them to 25 us where the arm moves; the counter's steps get them to 75 us only)."""
    stamps, Q, qdm, h = _sampler(5000, 3)
    clock = rebuild(stamps, Q, qdm)
    assert clock.kind == "velocity" and clock.rebuilt and "velocity signal" in clock.describe()
    err = np.abs(np.diff(clock.t) - h)
    moving = np.linalg.norm(0.5 * (qdm[1:] + qdm[:-1]), axis=1) > 0.1
    assert np.mean(err[moving] < 25e-6) >= 0.95
    assert rebuild(stamps, Q).kind == "stamps"                    # without it: the stamps, uniform


def test_a_velocity_signal_that_lags_does_not_move_true_stamps():
    """Sample-time stamps and a velocity signal 4 ms late (a filtered one): q is no smoother on the
    intervals it implies, so the stamps are kept."""
    rng = np.random.default_rng(4)
    t = np.concatenate([[0.0], np.cumsum(np.where(rng.random(2999) < 0.3, 12e-3, 10e-3))])
    q, _ = motion(t, len(JOINTS), 4)
    qdm = motion(t - 4e-3, len(JOINTS), 4)[1]
    clock = rebuild(t, np.round(q / 1e-6) * 1e-6, qdm)
    assert clock.kind == "stamps" and np.array_equal(clock.t, t)


@pytest.mark.parametrize("clocked", ["receive", "uniform"])
def test_one_glitch_costs_one_row(clocked):
    """Issue 42: one 0.5 rad glitch inside the limits sent the whole log back to its stamps. It is
    one bad row: dropped (and named), every other row read as without it."""
    if clocked == "receive":
        stamps, Q, TAU, source, repeated = _log(N=4000)
    else:
        stamps = np.arange(4000) * 1e-3
        Q = np.round(motion(stamps, len(JOINTS))[0] / 1e-6) * 1e-6
    clean = rebuild(stamps, Q)
    Q = Q.copy()
    Q[2000, 2] += 0.5
    clock = rebuild(stamps, Q)
    assert clock.glitches == [2000] and "glitch" in clock.describe() and "row 2001" in clock.describe()
    assert clock.kind == clean.kind and 2000 not in clock.kept
    keep = clean.kept != 2000
    assert np.array_equal(clock.kept, clean.kept[keep])
    assert np.max(np.abs(clock.t - clean.t[keep])) <= 1e-4 * 1e-3


def test_no_glitch_in_smooth_motion():
    t = np.arange(20000) * 1e-3
    q, _ = motion(t, len(JOINTS), 8)
    assert not rebuild(t, np.round(q / 1e-6) * 1e-6).glitches


def test_a_continuous_joint_wrapping_at_pi_is_unwrapped(tmp_path):
    """Issue 42: a joint reported in [-pi, pi) that turns through pi ruined the clock of the whole
    log (91 % of rows wrong). Unwrapped (and said so), the log reads as the unwrapped one does."""
    stamps, Q, TAU, source, repeated = _log(N=3000)
    Q = Q.copy()
    Q[:, 1] += 3.0 + 2.0 * source / len(Q)                            # through pi and beyond
    wrapped = Q.copy()
    wrapped[:, 1] = (Q[:, 1] + np.pi) % (2 * np.pi) - np.pi
    cols = lambda q: {"t": stamps, **{f"q_{j}": q[:, i] for i, j in enumerate(JOINTS)},   # noqa: E731
                      **{f"tau_{j}": TAU[:, i] for i, j in enumerate(JOINTS)}}
    rec, clock = read_log(write_columns(tmp_path / "w.csv", cols(wrapped)), JOINTS)
    assert clock.unwrapped == ["b"] and "unwrapped" in clock.describe()
    assert clock.kind == "ticks" and _right(clock, source) >= 0.999
    assert np.allclose(rec.q[:, 1], Q[clock.kept, 1] - 2 * np.pi * np.round((Q[0, 1] - wrapped[0, 1]) / (2 * np.pi)), atol=1e-9)


@pytest.mark.parametrize("unit, scale", [("ms", 1e3), ("us", 1e6)])
def test_a_time_column_in_ms_or_us_is_refused_with_its_unit(unit, scale):
    """Issue 42: a time column in ms was read as seconds ("1000 ms tick, 1 Hz") and tuned for 1 Hz."""
    t = np.arange(3000) * 1e-3
    q, _ = motion(t, 2)
    with pytest.raises(ValueError, match=f"looks like {unit} \\(a 1000 Hz log\\)"):
        rebuild(t * scale, q)


def test_jittered_sample_times_are_kept_whatever_a_lagging_velocity_signal_says():
    """Stamps that vary are the sampler's own times: a velocity signal 2 ms late does not move them
    (fitting each interval to q's increments would absorb q's noise and look smoother)."""
    rng = np.random.default_rng(9)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.7e-3, 1.3e-3, 3999))])
    q, _ = motion(t, len(JOINTS), 9)
    qdm = motion(t - 2e-3, len(JOINTS), 9)[1]
    clock = rebuild(t, np.round(q / 1e-6) * 1e-6 + 1e-6 * rng.standard_normal(q.shape), qdm)
    assert clock.kind == "stamps" and np.array_equal(clock.t, t)
