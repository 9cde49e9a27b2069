"""Seed 000 §VI, beyond the paper: the reduced-order observer with the nonlinear gain
k(y) = k0 K1(y) (deformation reduction, ``reduced_order_nonlinear``) against the constant gain
k(y) = k0 y of (12), for the same region (13) (same eta, v_max):

    seed000-section6   the designs of both for seed000_2r and ur5 (k0, the spread of Q1, the
                       noise gain max ||k0 dK1/dy||, (12') checked on fresh configurations), and
                       Example 1's open-loop run (18) on seed000_2r with both observers:
                       convergence time (noise-free) and steady-state error RMS (Example 1a's
                       noise and quantisation), first-order hold (and the zero-order hold's
                       times for reference).
"""
from __future__ import annotations

from pathlib import Path


from ..sim import plots
from ..sim.engine import simulate
from ..sim.sensors import Sensor
from . import seed000 as S

FAMILIES = ("reduced_order", "reduced_order_nonlinear")


def designs(robot):
    """Both designs for ``robot`` at (ETA, VMAX): k0, ratio min lambda_min(Q1) / max lambda_max(Q1),
    noise gain and the (12') margin on fresh configurations."""
    from ...families.design import reduced_order_gain
    from ...families.design.reduced_order_nonlinear import nonlinear_gain, verify
    const, nl = reduced_order_gain(robot, eta=S.ETA, v_max=S.VMAX), nonlinear_gain(robot, eta=S.ETA, v_max=S.VMAX)
    check = verify(robot, nl, samples=2000)
    return {"constant": {"k0": const.k0, "ratio_Q": nl.ratio_M, "noise_gain": const.k0, "radius": const.radius},
            "nonlinear": {"k0": nl.k0, "ratio_Q": check["ratio_Q"], "noise_gain": check["max_noise_gain"],
                          "radius": const.radius, "blend": nl.blend, "min_margin_12prime": check["min_margin"],
                          "min_lambda_Q": check["min_lambda_Q"], "checked_on": check["samples"]}}


def example1_both(reference=False, noisy=False, T=S.T_OPEN, dt=S.DT, seed=1, hold="foh"):
    """Example 1's open-loop run (18) with both observers, first-order hold by default (the
    zero-order hold's O(k dt) bias, docs/guide/sampling.md "Accuracy", would otherwise set the
    error level); C or numpy ``reference`` observers, Example 1a's sensor with ``seed`` if ``noisy``, horizon ``T``
    and period ``dt`` in s; returns (Result, summary)."""
    from ...families.observers import build
    nominal = S.robot()
    obs = {f: S.observer(build(f, nominal, eta=S.ETA, v_max=S.VMAX), reference, dt, hold=hold) for f in FAMILIES}
    sensor = Sensor(**S.NOISE_1A, seed=seed) if noisy else Sensor()
    res = simulate(S.plant(1.0, dt), S.Q0, S.QD0, T, dt, S.open_loop_law(1, dt), obs, sensor=sensor)
    return res, {name: S.accuracy(res.t, res.qd, E, T / 2) for name, E in res.est.items()}


def section6(reference=False, out=Path("build/sim/seed000-section6"), T=S.T_OPEN):
    """The comparison table of docs/papers/reproduced.md (see the module docstring): C or numpy ``reference``
    observers, horizon ``T`` s; writes run.csv and error_norms.png to ``out``, returns the summary."""
    from models import load_robot
    out = Path(out)
    clean, s_clean = example1_both(reference, noisy=False, T=T)
    noisy, s_noisy = example1_both(reference, noisy=True, T=T)
    _, s_zoh = example1_both(reference, noisy=False, T=T, hold="zoh")
    noisy.write_csv(out / "run.csv")
    plots.error_norms(out / "error_norms.png", clean.t, {k: clean.qd - E for k, E in clean.est.items()},
                      title="Example 1 (noise-free): constant vs nonlinear gain")
    table = {}
    for f in FAMILIES:
        table[f] = {"t_below_1e-2_s": s_clean[f]["t_below_0.01"], "t_below_1e-3_s": s_clean[f]["t_below_0.001"],
                    "rms_noisy_after_transient": s_noisy[f]["rms_after_transient"],
                    "zoh_t_below_1e-2_s": s_zoh[f]["t_below_0.01"], "zoh_rms_noise_free": s_zoh[f]["rms_after_transient"]}
    return {"example1_seed000_2r": table,
            "designs": {name: designs(S.robot() if name == "seed000_2r" else load_robot(name))
                        for name in ("seed000_2r", "ur5")},
            "setup": {"eta": S.ETA, "v_max": S.VMAX, **S.NOISE_1A, "dt": S.DT, "hold": "foh"}}


SCENARIOS = {"seed000-section6": section6}
DESCRIPTIONS = {"seed000-section6": "seed 000 (Cristofaro & De Luca) §VI, beyond the paper: nonlinear gain k0 K1(y) vs (12)'s constant gain"}
