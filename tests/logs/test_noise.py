"""What a log's sensors and motion are, measured from it (codegen.logs.noise): the lattice the
positions sit on, their white noise, the motion's band, the reference's cut-off, the torque's
residual against a model."""
import numpy as np
import pytest

from codegen.logs.noise import lattice, measure, reference_cutoff
from codegen.verify.trajectory import inverse_dynamics_function
from models import load_robot
from receive_log import motion

ENCODER = 2 * np.pi / 2 ** 16


@pytest.mark.parametrize("step", [ENCODER, 1e-6, 1e-3])
def test_the_lattice_of_an_encoder_or_of_the_decimals(step):
    q, _ = motion(np.arange(4000) * 1e-3, 1)
    assert lattice(step * np.round(q[:, 0] / step)) == pytest.approx(step, rel=1e-6)


def test_no_lattice_in_full_precision():
    q, _ = motion(np.arange(4000) * 1e-3, 1)
    assert lattice(q[:, 0] + 1e-7 * np.random.default_rng(0).standard_normal(4000)) == 0.0


@pytest.mark.parametrize("noise, step", [(2e-5, 1e-6), (5e-6, 0.0), (0.0, ENCODER)])
def test_position_noise_is_measured(noise, step):
    """White noise sigma (and an encoder's D / sqrt 12 when that is all there is) within 10 %; the
    design inputs are the measured sensor."""
    t = np.arange(8000) * 1e-3
    q, _ = motion(t, 3, 2)
    q = q + noise * np.random.default_rng(3).standard_normal(q.shape)
    if step:
        q = step * np.round(q / step)
    nz = measure(t, q)
    total = np.sqrt(noise ** 2 + step ** 2 / 12)
    assert nz.sigma == pytest.approx(np.full(3, total), rel=0.1)
    assert nz.resolution == pytest.approx(np.full(3, step), rel=1e-6)
    assert nz.white == pytest.approx(np.full(3, noise), rel=0.15, abs=0.1 * total)
    inputs = nz.design_inputs()
    assert inputs["quantization"] == pytest.approx(step, rel=1e-6) and "torque_uncertainty" not in inputs
    assert all(len(line) < 400 for line in nz.lines())


def test_the_band_and_the_reference_cutoff_follow_the_motion_and_the_noise():
    """More noise: a lower band and a lower cut-off; the cut-off's reference error against the
    truth is within 1.3 x the best of a grid of cut-offs."""
    from codegen.logs.recording import Recording
    from codegen.logs.reference import reference_of
    t = np.arange(10000) * 1e-3
    q, qd = motion(t, 2, 4)
    cuts = []
    for noise in (1e-6, 1e-4):
        y = q + noise * np.random.default_rng(5).standard_normal(q.shape)
        nz = measure(t, y)
        cuts.append(reference_cutoff(nz))
        rec = Recording(t=t, q=y, tau=np.zeros_like(y), qd=None, joint_names=["a", "b"])

        def err(ref):
            v = ref.valid
            return np.sqrt(np.mean(np.sum((ref.qd - qd)[v] ** 2, axis=1)))
        best = min(err(reference_of(rec, c)) for c in (2.0, 3.0, 5.0, 7.0, 10.0, 14.0, 20.0, 30.0, 50.0))
        assert err(reference_of(rec, cuts[-1])) <= 1.3 * best
    assert np.all(cuts[1] < cuts[0])


def test_the_torque_against_the_model():
    """tau = the model's inverse dynamics + an offset + white noise: the offset, the white noise
    (within 10 %) and a model residual far below it are found."""
    robot = load_robot("seed000_2r")
    t = np.arange(6000) * 1e-3
    q, _ = motion(t, 2, 6)
    tau_f = inverse_dynamics_function(robot)
    v = np.gradient(q, t, axis=0, edge_order=2)
    a = np.gradient(v, t, axis=0, edge_order=2)
    tau = np.asarray(tau_f.map(len(t))(q.T, v.T, a.T)).T
    rng = np.random.default_rng(7)
    measured = tau + np.array([0.2, -0.1]) + 0.05 * rng.standard_normal(tau.shape)
    nz = measure(t, np.round(q / 1e-6) * 1e-6, measured, robot)
    assert nz.torque_offset == pytest.approx([0.2, -0.1], abs=0.02)
    assert nz.torque_white == pytest.approx([0.05, 0.05], rel=0.1)
    assert np.all(nz.torque_model_rms < 0.5 * nz.torque_white)
    assert nz.design_inputs()["torque_uncertainty"] == pytest.approx(nz.torque_uncertainty.tolist())
