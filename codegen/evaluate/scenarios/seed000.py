"""Examples 1–3 of seed 000 (Cristofaro & De Luca), docs/papers/experiments.md §12.1.

    seed000-ex1a  open loop (18), noisy + quantised y: reduced-order vs Nicosia–Tomei
    seed000-ex1b  open loop (18), plant masses +10 %: reduced-order vs Nicosia–Tomei
    seed000-ex2   open loop (19), high noise: hybrid (switching k_r) vs fixed high gains
    seed000-ex3   output feedback (docs/papers/seed000.md §1.4) on the hybrid observer's estimate, from an
                  initial tracking error (EX3_ASSUMPTION); the docs' quintic (docs/papers/seed000.md §1.4) as a variant

Plant: compiled RK4 at PLANT_STEP (1e-4 s, 10 sub-steps per 1 kHz sample), torque held over a
sample. Observers: compiled C (``reference=False``) or the numpy reference, at 1 kHz, RK4 with
y and tau held over a step (zero-order hold; Example 1a adds a first-order-hold baseline).
Control laws: compiled blocks (codegen.families.controllers.seed000) in both cases. Each scenario writes
<out>/run.csv, PNG figures and returns a summary dict.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.target import Discretization
from ..sim import plots
from ..sim.blocks import block
from ..sim.engine import Law, rms, settling_time, simulate
from ..sim.plant import Plant
from ..sim.sensors import Sensor

Q0 = np.array([-2 * np.pi / 3, np.pi / 10])      # [S000 §V] q(0)
QD0 = np.array([-0.5, 1.0])                      # [S000 §V] qd(0)
DT = 1e-3                                        # 1 kHz sampling [docs/papers/experiments.md §12.1]
PLANT_STEP = 1e-4                                # plant RK4 step (see tests/test_sim.py)
T_OPEN, T_CLOSED = 20.0, 12.0                    # [ASSUMPTION docs/papers/experiments.md §12.1] horizons
NOISE_1A = dict(noise_std=2e-4, quantum=7e-4)    # [S000 Ex. 1a] Delta_q; sigma [ASSUMPTION]
NOISE_HIGH = dict(noise_std=1e-3, quantum=7e-4)  # [ASSUMPTION docs/papers/experiments.md §12.1] "high level of noise"
ETA, VMAX, VBAR = 1.0, 2.0, 2.0                  # [S000 §V]
DELTA_SPEC = 0.1                                 # [ASSUMPTION docs/papers/seed000.md §1.3] down-jump tolerance
PAPER = "guarantee"                              # the papers' gains: (12), (16), K_P = 500 I
DELTA_HIGH_NOISE = 0.3   # [ASSUMPTION docs/papers/seed000.md §1.3 "scale delta with the noise"]: > noise peak of x2hat (~0.2)
DELTA_WHY = ("Example 2 uses delta = 0.3, not the docs' 0.1: with sigma = 1e-3 rad at 1 kHz the noise "
             "alone moves ||x2hat|| by more than 0.1 rad/s about ||x2|| (noise_on_speed_peak), so with "
             "0.1 the logic chatters across the down threshold (with_delta_0.1: switches, min dwell); "
             "docs/papers/seed000.md §1.3 says to scale delta with the noise")
LEVELS = (1e-2, 1e-3)
_ROBOTS = {}


# ----------------------------------------------------------------------------- building blocks
def robot(mass_scale=1.0):
    """seed000_2r [docs/papers/experiments.md §11.1] with link masses x ``mass_scale``, one instance per scale (so the
    gain designs are cached)."""
    from models.closed_form import seed000_2r
    if mass_scale not in _ROBOTS:
        _ROBOTS[mass_scale] = seed000_2r(mass_scale)
    return _ROBOTS[mass_scale]


def observer(spec, reference, dt=DT, prefix=None, hold="zoh"):
    """The observer of ``spec`` (RK4, one step of ``dt`` s per sample, measurement ``hold`` "zoh" or
    "foh") as compiled C, or the numpy reference if ``reference``; ``prefix`` names the C symbols."""
    return block(spec, Discretization(dt=dt, method="rk4", hold=hold), reference=reference, prefix=prefix)


def law(spec, dt=DT):
    """The control law ``spec`` (stateless, so the hold changes nothing) as a compiled block
    sampled every ``dt`` s."""
    return block(spec, Discretization(dt=dt, method="rk4", hold="zoh"))


def plant(mass_scale=1.0, dt=DT):
    """The simulated seed000_2r (masses x ``mass_scale``): compiled RK4 at PLANT_STEP, sampled every
    ``dt`` s."""
    return Plant(robot(mass_scale), dt, substeps=max(1, int(round(dt / PLANT_STEP))))


def open_loop_law(example, dt=DT):
    """Torque [S000 (18)] or (19) for ``example`` 1 or 2, sampled every ``dt`` s. [ASSUMPTION] its
    gravity term g(q) uses the true q: the command is an open-loop profile, so sensor noise does
    not enter the plant."""
    from ...families.controllers.seed000 import open_loop

    def assemble(t, y, est, x, out):
        out[:2] = x[:2]
        out[2] = t
    return Law(law(open_loop(robot(), example), dt), assemble)


def tracking_law(feedback, dt=DT, q_start=Q0):
    """Example-3 law fed by measured q and the estimate of observer ``feedback``; reference
    quintic from ``q_start`` (rad) to qbar over [0, 8] s (q_start = qbar: a constant set-point);
    sampled every ``dt`` s [docs/papers/seed000.md §1.4]."""
    from ...families.controllers.seed000 import tracking

    def assemble(t, y, est, x, out):
        out[:2] = y
        out[2:4] = est[feedback]
        out[4] = t
    return Law(law(tracking(robot(), q_start), dt), assemble, feedback=(feedback,))


# ----------------------------------------------------------------------------- figures of merit
def accuracy(t, qd, est, t_from):
    """Times until ||qd - est|| stays below 1e-2 and 1e-3 (inf: never) and the RMS of
    ||qd - est|| over t >= t_from (after the transient)."""
    e = qd - est
    out = {f"t_below_{lv:g}": settling_time(t, e, lv) for lv in LEVELS}
    out["rms_after_transient"] = rms(e[t >= min(t_from, t[-1])])
    out["max_error"] = float(np.max(np.linalg.norm(e, axis=1)))
    return out


def logic_trace(res, name):
    """Logic state r active at each sample (after that sample's jumps) of hybrid observer ``name``
    in the Result ``res`` (which logged its states): the state before step k+1 (the flow leaves r
    unchanged), the final state for the last sample. Returns (N,) int."""
    r = np.append(res.states[name][1:, -1], res.extra[f"{name}_state_final"][-1])
    return np.rint(r).astype(int)


def logic_summary(t, r, r0=1):
    """Switches of the logic state ``r`` (N,) over times ``t`` (N,) s, starting from ``r0``: their
    number, times and levels, the highest and final r and the shortest dwell (s)."""
    jumps = np.nonzero(np.diff(np.concatenate([[r0], r])))[0]
    dwell = np.diff(t[jumps]) if len(jumps) > 1 else np.array([np.inf])
    return {"r_max_reached": int(r.max()), "r_final": int(r[-1]), "switches": int(len(jumps)),
            "switch_times": [round(float(t[j]), 4) for j in jumps],
            "r_after_switch": [int(r[j]) for j in jumps],
            "min_dwell_s": float(dwell.min())}


# ----------------------------------------------------------------------------- Example 1
def example1(reference=False, noisy=True, mass_scale=1.0, T=T_OPEN, dt=DT, seed=1, hold="zoh"):
    """Open loop (18): reduced-order and Nicosia–Tomei (K_D = k0 I, K_P = 500 I) on the nominal
    model; plant masses x mass_scale; ``hold`` of the observers' measurements (codegen.discrete.discretize).
    Observers in C or the numpy ``reference``; ``noisy``: Example 1a's sensor with ``seed``;
    horizon ``T`` and sample period ``dt`` in s. Returns (Result, summary)."""
    from ...families.observers import build
    nominal = robot()
    obs = {f: observer(build(f, nominal, eta=ETA, v_max=VMAX, design=PAPER), reference, dt, hold=hold)
           for f in ("reduced_order", "nicosia_tomei")}
    sensor = Sensor(**NOISE_1A, seed=seed) if noisy else Sensor()
    res = simulate(plant(mass_scale, dt), Q0, QD0, T, dt, open_loop_law(1, dt), obs, sensor=sensor)
    summary = {name: accuracy(res.t, res.qd, E, T / 2) for name, E in res.est.items()}
    summary["max_speed"] = float(np.max(np.linalg.norm(res.qd, axis=1)))
    return res, summary


def _ex1_figures(res, out, tag):
    errs = {k: res.qd - E for k, E in res.est.items()}
    plots.per_joint(out / "velocities.png", res.t, res.qd, res.est, title=f"Example {tag}")
    plots.error_norms(out / "error_norms.png", res.t, errs, title=f"Example {tag}: estimation error")
    zoom = res.t <= 5.0
    plots.per_joint(out / "velocities_zoom.png", res.t[zoom], res.qd[zoom],
                    {k: E[zoom] for k, E in res.est.items()}, title=f"Example {tag} (first 5 s)")


def ex1a(reference=False, out=Path("build/sim/seed000-ex1a"), T=T_OPEN):
    """Example 1a: noisy, quantised measurement; plus noise-free baselines at 1 kHz and, to
    expose the O(dt) zero-order-hold bias of the reduced-order observer, at 10 kHz and at 1 kHz
    with the first-order hold (which removes most of that bias).
    ``reference``: numpy reference observers instead of C; ``out``: folder written; ``T``: horizon, s."""
    out = Path(out)
    res, s = example1(reference, noisy=True, T=T)
    res.write_csv(out / "run.csv")
    _ex1_figures(res, out, "1a (noise + quantisation)")
    _, clean = example1(reference, noisy=False, T=T)
    _, fine = example1(reference, noisy=False, T=T, dt=1e-4)
    _, foh = example1(reference, noisy=False, T=T, hold="foh")
    return {"noisy": s, "noise_free_1kHz": clean, "noise_free_10kHz": fine, "noise_free_1kHz_foh": foh,
            "setup": {"dt": DT, "plant_step": PLANT_STEP, **NOISE_1A, "rms_window_from_s": T / 2,
                      "observers": "C" if not reference else "numpy reference"}}


def ex1b(reference=False, out=Path("build/sim/seed000-ex1b"), T=T_OPEN):
    """Example 1b: plant masses +10 %, no noise.
    ``reference``: numpy reference observers instead of C; ``out``: folder written; ``T``: horizon, s."""
    out = Path(out)
    res, s = example1(reference, noisy=False, mass_scale=1.1, T=T)
    res.write_csv(out / "run.csv")
    _ex1_figures(res, out, "1b (masses +10 %)")
    return {"mismatch_1kHz": s,
            "setup": {"dt": DT, "plant_step": PLANT_STEP, "mass_scale": 1.1, "rms_window_from_s": T / 2,
                      "observers": "C" if not reference else "numpy reference"}}


# ----------------------------------------------------------------------------- Example 2
def example2(reference=False, T=T_OPEN, dt=DT, seed=2, fixed=None, delta=None):
    """Open loop (19), high noise: the hybrid observer and fixed-gain reduced-order observers
    with k = k_r for r in ``fixed`` (default 2..r_max), down-jump tolerance ``delta`` (default
    DELTA_HIGH_NOISE) [docs/papers/seed000.md §1.3]. C or numpy ``reference`` observers; sensor NOISE_HIGH with ``seed``;
    horizon ``T`` and period ``dt`` in s. Returns (Result, summary, gains k_r)."""
    from ...families.observers import build
    nominal = robot()
    hyb = build("reduced_order_hybrid", nominal, eta=ETA, vbar=VBAR, design=PAPER,
                delta=DELTA_HIGH_NOISE if delta is None else delta)
    gains = hyb.p_default[:-3]
    fixed = range(2, len(gains) + 1) if fixed is None else fixed
    obs = {"hybrid": observer(hyb, reference, dt)}
    for r in fixed:
        spec = build("reduced_order", nominal, k0=float(gains[r - 1]))
        obs[f"fixed_k{r}"] = observer(spec, reference, dt, prefix=f"{spec.target().prefix}_fixed_k{r}")
    res = simulate(plant(1.0, dt), Q0, QD0, T, dt, open_loop_law(2, dt), obs,
                   sensor=Sensor(**NOISE_HIGH, seed=seed), log_states=("hybrid",))
    r = logic_trace(res, "hybrid")
    speed = np.linalg.norm(res.qd, axis=1)
    s = {"hybrid": {**accuracy(res.t, res.qd, res.est["hybrid"], T / 2), **logic_summary(res.t, r)},
         "bound_margin_min": float(np.min(r * VBAR - speed)),     # >= 0: ||x2|| <= r vbar throughout
         "max_speed": float(speed.max())}
    top = s["hybrid"]["r_max_reached"]
    for name in obs:
        if name.startswith("fixed_k"):
            s[name] = accuracy(res.t, res.qd, res.est[name], T / 2)
    s["fixed_compared"] = f"fixed_k{top}" if f"fixed_k{top}" in obs else None
    res.extra["r"] = r
    return res, s, gains


def ex2(reference=False, out=Path("build/sim/seed000-ex2"), T=T_OPEN):
    """Example 2: hybrid vs fixed high gain under high noise, figures and the delta study (DELTA_WHY).
    ``reference``: numpy reference observers instead of C; ``out``: folder written; ``T``: horizon, s."""
    out = Path(out)
    res, s, gains = example2(reference, T=T)
    res.write_csv(out / "run.csv")
    r = res.extra["r"]
    plots.positions_and_bound(out / "positions_bound.png", res.t, res.q, res.qd, res.est["hybrid"], r, VBAR,
                              title="Example 2: positions; velocity norms and scheduled bound")
    shown = {"switching gain": res.est["hybrid"]}
    if s["fixed_compared"]:
        shown[f"fixed gain {s['fixed_compared'][6:]}"] = res.est[s["fixed_compared"]]
    plots.per_joint(out / "velocities.png", res.t, res.qd, shown, title="Example 2")
    plots.error_norms(out / "error_norms.png", res.t, {k: res.qd - E for k, E in shown.items()},
                      title="Example 2: estimation error")
    _, spec_delta, _ = example2(reference, T=T, fixed=(), delta=DELTA_SPEC)
    h = spec_delta["hybrid"]
    late = res.t >= 1.0
    speed_noise = np.abs(np.linalg.norm(res.est["hybrid"], axis=1) - np.linalg.norm(res.qd, axis=1))[late]
    s["delta"] = {"used": DELTA_HIGH_NOISE, "spec": DELTA_SPEC, "why": DELTA_WHY,
                  "noise_on_speed_peak": float(speed_noise.max()),
                  f"with_delta_{DELTA_SPEC:g}": {"switches": h["switches"], "min_dwell_s": h["min_dwell_s"]}}
    s["setup"] = {"dt": DT, "plant_step": PLANT_STEP, **NOISE_HIGH, "eta": ETA, "vbar": VBAR,
                  "delta": DELTA_HIGH_NOISE, "k_r": [round(float(k), 4) for k in gains],
                  "rms_window_from_s": T / 2, "observers": "C" if not reference else "numpy reference"}
    return s


# ----------------------------------------------------------------------------- Example 3
EX3_ASSUMPTION = (
    "[ASSUMPTION] main run: q_d(t) = qbar = (pi/4, -pi/3) from t = 0 (a set-point), so the run starts "
    "with the tracking error qbar - q(0) = (2.88, -1.36) rad and the robot reaches qbar at steady "
    "state, after about 8 s: the reading under which the seed's Figs. 6-7 (initial velocity peak, "
    "r rising and returning to 1) can occur. Variant (docs/papers/experiments.md §12.1): a quintic rest-to-rest q(0) -> "
    "qbar over [0, 8] s, which starts on the robot and never leaves r = 1")
ZOOM = (0.0, 0.3)                                # Fig. 7's zoomed box [s] [ASSUMPTION]


def example3(reference=False, T=T_CLOSED, dt=DT, seed=3, setpoint=True):
    """Output feedback (docs/papers/seed000.md §1.4) using the hybrid observer's estimate, noise as in 1a.

    Reference: with ``setpoint`` (main run, EX3_ASSUMPTION) the constant q_d = qbar, else the
    quintic q(0) -> qbar of docs/papers/experiments.md §12.1. C or numpy ``reference`` observer; sensor as in 1a with
    ``seed``; horizon ``T`` and period ``dt`` in s. Returns (Result, summary)."""
    from ...families.controllers.seed000 import Q_GOAL, T_MOVE, quintic
    from ...families.observers import build
    hyb = build("reduced_order_hybrid", robot(), eta=ETA, vbar=VBAR, delta=DELTA_SPEC, design=PAPER)
    q_start = np.asarray(Q_GOAL) if setpoint else Q0
    res = simulate(plant(1.0, dt), Q0, QD0, T, dt, tracking_law("hybrid", dt, q_start),
                   {"hybrid": observer(hyb, reference, dt)}, sensor=Sensor(**NOISE_1A, seed=seed),
                   log_states=("hybrid",))
    r = logic_trace(res, "hybrid")
    q_d = quintic(res.t, q_start, Q_GOAL, T_MOVE)[0]
    en = np.linalg.norm(q_d - res.q, axis=1)
    speed = np.linalg.norm(res.qd, axis=1)
    peak = int(np.argmax(speed))
    s = {"hybrid": {**accuracy(res.t, res.qd, res.est["hybrid"], T_MOVE), **logic_summary(res.t, r)},
         "peak_speed": float(speed[peak]), "peak_speed_time_s": float(res.t[peak]),
         "peak_speed_per_joint": [float(v) for v in np.abs(res.qd).max(axis=0)],
         "speed_at_t0": float(speed[0]),
         "tracking_error_initial": float(en[0]),
         "tracking_error_final": float(en[-1]),
         "tracking_error_max_after_move": float(en[res.t >= min(T_MOVE, T)].max()),
         "tracking_error_max": float(en.max()),
         "bound_margin_min": float(np.min(r * VBAR - speed))}
    res.extra.update(r=r, q_d=q_d)
    return res, s


def _ex3_figures(res, out, tag, what):
    r, q_d = res.extra["r"], res.extra["q_d"]
    plots.positions_and_bound(out / f"fig6_positions_bound{tag}.png", res.t, res.q, res.qd, res.est["hybrid"],
                              r, VBAR, q_ref=q_d,
                              title=f"Example 3 ({what}): positions; velocity norms and scheduled bound (cf. Fig. 6)")
    plots.per_joint(out / f"fig7_velocities{tag}.png", res.t, res.qd, {"hybrid observer": res.est["hybrid"]},
                    title=f"Example 3 ({what}): velocities, zoom {ZOOM[0]:g}-{ZOOM[1]:g} s (cf. Fig. 7)",
                    zoom=ZOOM)
    plots.tracking(out / f"tracking{tag}.png", res.t, q_d - res.q, res.u,
                   title=f"Example 3 ({what}): tracking error, torque")
    plots.error_norms(out / f"error_norms{tag}.png", res.t, {"hybrid": res.qd - res.est["hybrid"]},
                      title=f"Example 3 ({what}): estimation error")


def ex3(reference=False, out=Path("build/sim/seed000-ex3"), T=T_CLOSED):
    """Example 3: the main run from an initial tracking error (set-point qbar; run.csv, fig6_*,
    fig7_*) and the docs' quintic (docs/papers/seed000.md §1.4) from q(0) as a variant (run_quintic.csv, *_quintic.png).
    ``reference``: numpy reference observers instead of C; ``out``: folder written; ``T``: horizon, s."""
    out = Path(out)
    res, s = example3(reference, T=T)
    res.write_csv(out / "run.csv")
    _ex3_figures(res, out, "", "set-point qbar")
    res2, s2 = example3(reference, T=T, setpoint=False)
    res2.write_csv(out / "run_quintic.csv")
    _ex3_figures(res2, out, "_quintic", "quintic from q(0)")
    setup = {"dt": DT, "plant_step": PLANT_STEP, **NOISE_1A, "eta": ETA, "vbar": VBAR, "delta": DELTA_SPEC,
             "zoom_s": list(ZOOM), "observers": "C" if not reference else "numpy reference"}
    return {"assumption": EX3_ASSUMPTION, "setpoint_qbar": s, "variant_quintic_from_q0": s2, "setup": setup}


SCENARIOS = {"seed000-ex1a": ex1a, "seed000-ex1b": ex1b, "seed000-ex2": ex2, "seed000-ex3": ex3}
# one line each for `simulate list`: the paper, the experiment, the figures (docs/papers/experiments.md §12.1)
DESCRIPTIONS = {
    "seed000-ex1a": "seed 000 (Cristofaro & De Luca), Example 1a: reduced-order vs Nicosia-Tomei, noisy quantised q",
    "seed000-ex1b": "seed 000 (Cristofaro & De Luca), Example 1b: reduced-order vs Nicosia-Tomei, plant masses +10 %",
    "seed000-ex2": "seed 000 (Cristofaro & De Luca), Example 2: hybrid gains vs a fixed high gain under high noise",
    "seed000-ex3": "seed 000 (Cristofaro & De Luca), Example 3: output feedback with the hybrid observer (Figs. 6-7)",
}
