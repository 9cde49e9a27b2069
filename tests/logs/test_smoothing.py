"""Zero-phase derivatives of a jittered, quantised log against the analytic truth."""
import numpy as np
import pytest

from codegen.logs.smoothing import derivatives, reference_velocity


def _log(seed=0, T=6.0, quantum=2 * np.pi / 2 ** 16):
    rng = np.random.default_rng(seed)
    steps = rng.uniform(0.7e-3, 1.6e-3, size=int(T / 1.15e-3))
    t = np.cumsum(steps)
    t = t[rng.random(len(t)) > 0.01]                     # 1 % dropped samples
    w = np.array([2.0, 5.0, 9.0])
    q = np.sin(np.outer(t, w))
    qd = np.cos(np.outer(t, w)) * w
    qdd = -np.sin(np.outer(t, w)) * w ** 2
    return t, quantum * np.round(q / quantum), qd, qdd


def test_velocity_and_acceleration_of_a_jittered_quantised_sine():
    t, q, qd, qdd = _log()
    d = derivatives(t, q, cutoff=10.0)
    v = d.valid
    assert v.mean() > 0.6
    # 9 rad/s = 1.4 Hz: the 4th-order filtfilt at 10 Hz passes it to 1e-6; what is left is the
    # encoder's noise (quantum 9.6e-5 rad) differentiated through a 10 Hz band
    assert np.sqrt(np.mean((d.qd[v] - qd[v]) ** 2)) < 3e-3
    assert np.max(np.abs(d.qd[v] - qd[v])) < 1.5e-2
    assert np.sqrt(np.mean((d.qdd[v] - qdd[v]) ** 2)) < 0.3


def test_reference_spread_bounds_its_error():
    t, q, qd, _ = _log(seed=1)
    ref, spread, valid = reference_velocity(t, q, 10.0)
    err = np.abs(ref - qd)[valid]
    assert np.median(spread[valid]) > 0
    # the spread between the two cut-offs is of the size of the reference's own error
    assert np.sqrt(np.mean(err ** 2)) < 3 * np.sqrt(np.mean(spread[valid] ** 2))


@pytest.mark.parametrize("t,q,cutoff,words", [
    (np.arange(5.0), np.zeros(5), 1.0, "at least 8"),
    (np.r_[0.0, 2.0, 1.0, 3, 4, 5, 6, 7], np.zeros(8), 0.1, "increase"),
    (np.arange(10.0) * 1e-3, np.zeros((9, 2)), 10.0, "shape"),
    (np.arange(10.0) * 1e-3, np.zeros(10), 600.0, "Nyquist"),
    (np.arange(10.0) * 1e-3, np.r_[np.zeros(9), np.nan], 10.0, "NaN"),
])
def test_bad_input_is_named(t, q, cutoff, words):
    with pytest.raises(ValueError, match=words):
        derivatives(t, q, cutoff)
