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
    assert set(row) == {"rms", "max", "t_conv", "gain", "lag", "diverged"}
    with pytest.raises(ValueError, match="t0 = 2 s is after the last sample"):
        metrics.rms_after(t, err, 2.0)
