"""Baselines (codegen.evaluate.baselines) on analytic signals, and the metrics they are judged by.

Signal: q = sin(2 pi t) sampled at 1 kHz for 4 s; measures over t >= 1 s (after the start).
Bounds: the gain and lag of each method against its known response (backward difference:
lag dt/2; Butterworth of order N at cutoff fc: lag dt/2 + 1/(2 pi fc sin(pi/(2N))), its
low-frequency group delay; Kalman and Levant: no lag), and noise reduction against the
backward difference on the same Gaussian noise.
"""
import numpy as np
import pytest

from codegen.evaluate import baselines, metrics

DT = 1e-3
T = np.arange(0, 4, DT)
W = 2 * np.pi
Y = np.column_stack([np.sin(W * T), 0.5 * np.cos(W * T)])
QD = np.column_stack([W * np.cos(W * T), -0.5 * W * np.sin(W * T)])
NOISE = 1e-4 * np.random.default_rng(0).normal(size=Y.shape)


def estimate(name, Yin=Y, **options):
    b = baselines.make(name, 2, DT, **options)
    b.reset(Yin[0], QD[0])
    return b.run(Yin)


def butterworth_lag(fc, order):
    return DT / 2 + 1 / (2 * np.pi * fc * np.sin(np.pi / (2 * order)))


@pytest.mark.parametrize("name, options, lag, gain_tol, lag_tol", [
    ("backward", {}, DT / 2, 1e-5, 1e-6),
    ("butterworth", {"cutoff": 50.0}, butterworth_lag(50.0, 2), 1e-4, 0.02 * butterworth_lag(50.0, 2)),
    ("butterworth", {"cutoff": 10.0, "order": 3}, butterworth_lag(10.0, 3), 1e-4,
     0.02 * butterworth_lag(10.0, 3)),
    ("kalman", {"q": 1e6}, 0.0, 1e-3, 1e-5),
    ("levant", {"L": 500.0}, 0.0, 1e-3, 1e-5),
])
def test_sinusoid_gain_and_lag(name, options, lag, gain_tol, lag_tol):
    g, fitted = metrics.gain_lag(T, estimate(name, **options), QD, t0=1.0)
    assert abs(g - 1) < gain_tol
    assert abs(fitted - lag) < lag_tol


@pytest.mark.parametrize("name, options, factor", [
    ("butterworth", {"cutoff": 50.0}, 0.3),
    ("kalman", {"q": 1e2}, 0.15),
    ("levant", {"L": 500.0}, 0.15),
])
def test_noise_reduction(name, options, factor):
    """The noise part of the estimate (noisy run minus clean run) is at most ``factor`` x
    that of the backward difference (sigma sqrt(2) / dt = 0.14 rad/s)."""
    def noise_rms(n, **o):
        return metrics.rms_after(T, estimate(n, Y + NOISE, **o) - estimate(n, **o), 1.0)
    assert noise_rms(name, **options) < factor * noise_rms("backward")


@pytest.mark.parametrize("name", list(baselines.BASELINES))
def test_step_equals_run_and_estimate_does_not_advance(name):
    a, b = baselines.make(name, 2, DT), baselines.make(name, 2, DT)
    a.reset(Y[0])
    b.reset(Y[0])
    stepped = []
    for k in range(300):
        peek = a.estimate(Y[k])
        stepped.append(a.step(Y[k]))
        assert np.array_equal(peek, stepped[-1])
    assert np.allclose(np.array(stepped), b.run(Y[:300]), rtol=1e-12, atol=1e-12)
    assert np.allclose(a.state, b.state, rtol=1e-12, atol=1e-12)


def test_initial_velocity_and_state_round_trip():
    b = baselines.make("kalman", 2, DT)
    b.reset(Y[0], est0=QD[0])
    saved = b.state
    first = b.step(Y[1])
    assert np.allclose(first, QD[1], atol=2e-2)      # started at the true velocity
    b.state = saved
    assert np.array_equal(b.step(Y[1]), first)


@pytest.mark.parametrize("name, options, match", [
    ("butterworth", {"cutoff": 500.0}, "cutoff must be below the Nyquist frequency 500"),
    ("butterworth", {"order": 0}, "order must be a positive integer"),
    ("kalman", {"q": -1.0}, "q must be a positive finite number"),
    ("kalman", {"r": float("nan")}, "r must be a positive finite number"),
    ("levant", {"L": 0.0}, "L must be a positive finite number"),
    ("levant", {"order": 5}, r"order must be one of \[1, 2, 3\]"),
])
def test_bad_options_are_refused(name, options, match):
    with pytest.raises(ValueError, match=match):
        baselines.make(name, 2, DT, **options)


def test_bad_input_is_refused():
    b = baselines.make("butterworth", 2, DT)
    with pytest.raises(ValueError, match=r"y: expected shape \(2,\)"):
        b.step([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="Y: NaN or Inf at row 1"):
        b.run(np.array([[0.0, 0.0], [np.nan, 0.0]]))
    with pytest.raises(ValueError, match="dt must be a positive"):
        baselines.make("backward", 2, 0.0)
    with pytest.raises(ValueError, match="n must be a positive integer"):
        baselines.make("backward", 0, DT)
    with pytest.raises(KeyError, match="unknown baseline 'median'; known: backward"):
        baselines.make("median", 2, DT)


# ------------------------------------------------------------------------------ metrics
def test_gain_lag_recovers_a_known_scale_and_delay():
    for g, lag in ((1.02, 3.3e-3), (0.97, -1.2e-3), (1.0, 0.0)):
        est = g * np.column_stack([W * np.cos(W * (T - lag)), -0.5 * W * np.sin(W * (T - lag))])
        fg, flag = metrics.gain_lag(T, est, QD, t0=0.5)
        # linear interpolation between samples costs O((w dt)^2 / 8) = 5e-6 in the gain
        assert abs(fg - g) < 1e-5 and abs(flag - lag) < 1e-6


def test_error_measures():
    t = np.arange(0, 1.001, 0.01)
    err = np.column_stack([np.exp(-10 * t), np.zeros_like(t)])
    assert metrics.convergence_time(t, err, 1e-2) == pytest.approx(0.47)     # e^-4.7 < 1e-2
    assert metrics.convergence_time(t, err, 2.0) == 0.0
    assert metrics.convergence_time(t, err, 1e-9) == float("inf")
    assert metrics.max_error(t, err, 0.5) == pytest.approx(np.exp(-5))
    assert metrics.rms_after(t, 3 * np.ones((len(t), 2)), 0.2) == pytest.approx(3 * np.sqrt(2))
    truth = np.ones((len(t), 2))
    assert not metrics.diverged(truth + err, truth)
    assert metrics.diverged(truth + 1e4, truth)
    assert metrics.diverged(np.where(t[:, None] > 0.5, np.nan, truth), truth)
    row = metrics.summarize(t, truth + err, truth, t_ss=0.5)
    assert set(row) == {"rms", "max", "t_conv", "t_settle", "gain", "lag", "diverged"}
    with pytest.raises(ValueError, match="t0 = 2 s is after the last sample"):
        metrics.rms_after(t, err, 2.0)


# ------------------------------------------------------------------------------ stamped runs
def _jittered(seed=0):
    """The sinusoid of the module at stamps 1 ms +- 0.3 ms with 2 % of the samples dropped."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(DT + rng.uniform(-3e-4, 3e-4, 4000))
    t = t[rng.random(len(t)) > 0.02]
    return t, np.column_stack([np.sin(W * t), 0.5 * np.cos(W * t)]), \
        np.column_stack([W * np.cos(W * t), -0.5 * W * np.sin(W * t)])


def test_stamped_backward_difference_is_the_velocity_at_the_midpoint():
    """(y_k - y_k-1) / h_k = qd(t_k - h_k/2) + O(h^2 |qddd| / 24): 6e-5 rad/s at h = 2.6 ms."""
    t, Yj, QDj = _jittered()
    b = baselines.make("backward", 2, DT)
    b.reset(Yj[0])
    est = b.run(Yj, t=t)
    mid = t[1:] - np.diff(t) / 2
    truth = np.column_stack([W * np.cos(W * mid), -0.5 * W * np.sin(W * mid)])
    assert np.max(np.abs(est[1:] - truth)) < W ** 3 * np.max(np.diff(t)) ** 2 / 24
    # every step taken as dt: the estimate is qd h_k / dt, off by ||qd|| |h_k - dt| / dt (1 rad/s
    # RMS here), 60 x the half-step lag ||qdd|| h_k / 2 of the stamped estimate
    b.reset(Yj[0])
    unstamped = b.run(Yj)
    jitter = np.linalg.norm(QDj[1:], axis=1) * np.abs(np.diff(t) - DT) / DT
    assert metrics.rms_after(t[1:], unstamped[1:] - QDj[1:], 1.0) == pytest.approx(
        metrics.rms_after(t[1:], jitter, 1.0), rel=0.05)
    assert metrics.rms_after(t, unstamped - QDj, 1.0) > 30 * metrics.rms_after(t, est - QDj, 1.0)


@pytest.mark.parametrize("name, options, lag, gain_tol, lag_tol", [
    ("butterworth", {"cutoff": 50.0}, butterworth_lag(50.0, 2), 1e-3, 0.02 * butterworth_lag(50.0, 2)),
    ("kalman", {"q": 1e6}, 0.0, 1e-3, 2e-5),
    ("levant", {"L": 500.0}, 0.0, 1e-3, 2e-5),
])
def test_stamped_runs_keep_gain_and_lag(name, options, lag, gain_tol, lag_tol):
    """On jittered stamps with gaps, the same gain and lag as on a uniform log (the Butterworth
    designed at the nominal 1 kHz, its input differences over the real steps)."""
    t, Yj, QDj = _jittered()
    b = baselines.make(name, 2, DT, **options)
    b.reset(Yj[0], QDj[0])
    g, fitted = metrics.gain_lag(t, b.run(Yj, t=t), QDj, t0=1.0)
    assert abs(g - 1) < gain_tol
    assert abs(fitted - lag) < lag_tol


@pytest.mark.parametrize("name", list(baselines.BASELINES))
def test_uniform_stamps_are_the_constant_step_path(name):
    a, b = baselines.make(name, 2, DT), baselines.make(name, 2, DT)
    a.reset(Y[0])
    b.reset(Y[0])
    assert np.array_equal(a.run(Y, t=T + 5.0), b.run(Y))


@pytest.mark.parametrize("name", ["backward", "butterworth", "kalman"])
def test_stamped_runs_chain(name):
    """Two stamped runs are one: the second starts from the first's last stamp."""
    t, Yj, _ = _jittered()
    a, b = baselines.make(name, 2, DT), baselines.make(name, 2, DT)
    a.reset(Yj[0])
    b.reset(Yj[0])
    whole = a.run(Yj, t=t)
    parts = np.vstack([b.run(Yj[:1000], t=t[:1000]), b.run(Yj[1000:], t=t[1000:])])
    assert np.allclose(parts, whole, rtol=1e-12, atol=1e-12)


def test_bad_stamps_are_refused():
    b = baselines.make("kalman", 2, DT)
    t = np.arange(10) * DT
    with pytest.raises(ValueError, match=r"t: expected shape \(10,\)"):
        b.run(Y[:10], t=t[:9])
    with pytest.raises(ValueError, match=r"t: time stamps must increase; t\[5\] = 0.004 <= t\[4\] = 0.004"):
        b.run(Y[:10], t=np.r_[t[:5], t[4:9]])
    b.run(Y[:10], t=t)
    with pytest.raises(ValueError, match=r"t\[0\] = 0.009 <= the previous run's last stamp 0.009"):
        b.run(Y[10:20], t=t + 9 * DT)
