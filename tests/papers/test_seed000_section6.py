"""Seed 000 §VI, beyond the paper: the nonlinear gain k(y) = k0 K1(y) by deformation reduction
(codegen.families.design.reduced_order_nonlinear, family reduced_order_nonlinear): its design, the
numerical check of its convergence condition (12'), and C against the reference."""
import numpy as np
import pytest

from codegen.families import observers
from codegen.families.design import reduced_order_gain
from codegen.families.design import reduced_order_nonlinear as D
from codegen.evaluate.scenarios import seed000 as S


@pytest.fixture(scope="module")
def robot():
    return S.robot()


@pytest.fixture(scope="module")
def design(robot):
    return D.nonlinear_gain(robot, eta=S.ETA, v_max=S.VMAX)


def test_k1_equal_y_gives_back_12(robot):
    """(12') with K1 = y (Q1 = 2M) is (12): the same k0 as the paper's design (200 samples)."""
    g = D._Gain(robot, 200, 0)
    C = np.zeros((2, D.feature_count(2)))
    C[:, :2] = np.eye(2)
    k0, _ = D.gain_for(g, C, S.ETA, S.VMAX)
    assert k0 == pytest.approx(reduced_order_gain(robot, eta=S.ETA, v_max=S.VMAX, samples=200).k0, rel=1e-6)


def test_fit_reaches_a_constant_q_when_the_basis_allows():
    """M = I at every sample: K1 = y solves Q1 = 2I exactly, so the fit's residual is zero."""
    rng = np.random.default_rng(0)
    import casadi as ca
    y = ca.SX.sym("y", 2)
    jac = ca.Function("j", [y], [ca.jacobian(D.features(y), y)])
    P = np.stack([np.asarray(jac(q)) for q in rng.uniform(-3, 3, (40, 2))])
    M = np.broadcast_to(np.eye(2), (40, 2, 2))
    C = D.fit_K1(M, P)
    MD = M @ np.einsum("ib,sbl->sil", C, P)
    assert np.abs(MD + MD.transpose(0, 2, 1) - 2 * np.eye(2)).max() < 1e-9


def test_condition_12prime_holds_on_fresh_configurations(robot, design):
    """The numerical proof: on 3000 configurations never used by the design, Q1(y) > 0 and
    k0/2 lambda_min(Q1) + lambda_min(F) - c0(y)(v_max + eta) >= 0; Q1 is less deformed than
    2M (the constant gain's Q1) by the paper's measure."""
    check = D.verify(robot, design, samples=3000, seed=11)
    assert check["min_lambda_Q"] > 0 and check["min_margin"] >= 0, check
    assert check["ratio_Q"] > 5 * design.ratio_M, (check, design.ratio_M)


def test_bad_gains_are_refused(robot):
    with pytest.raises(ValueError, match="both k0 and C"):
        observers.build("reduced_order_nonlinear", robot, k0=10.0)
    with pytest.raises(ValueError, match="C must have shape"):
        observers.build("reduced_order_nonlinear", robot, k0=10.0, C=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="eta and v_max"):
        D.nonlinear_gain(robot, eta=0.0)


def test_designed_observer_converges_and_c_equals_reference(robot, design):
    """Example 1 (open loop (18), noise-free, 3 s): the nonlinear-gain observer's error falls
    below 1e-2; the compiled C and the numpy reference agree over the run."""
    from codegen.evaluate.scenarios.seed000_section6 import example1_both
    res, s = example1_both(T=3.0)
    assert s["reduced_order_nonlinear"]["t_below_0.01"] < 3.0, s
    ref, _ = example1_both(reference=True, T=0.2)
    c = res.est["reduced_order_nonlinear"][:len(ref.t)]
    r = ref.est["reduced_order_nonlinear"]
    assert np.abs(c - r).max() <= 1e-9 * max(1.0, np.abs(r).max())     # docs/architecture.md §4
