"""Control laws as compiled C against the independent numpy references (codegen/reference/):
seed-000 open-loop torques (18)/(19) and the Example-3 tracking law (docs/papers/seed000.md §1.4, docs/papers/experiments.md §12.1), Spong's
feedback-linearising (docs/papers/seed004.md §9) and integral-manifold (docs/papers/seed004.md §10) controllers on the seed-004
elastic 2R and 3R (derivatives y3, y4, F, h0', h0'' exact by hyper-duals on the reference side).
Each law is compiled once; >= 200 random, physically sensible inputs each, relative error <= 1e-9."""
import numpy as np
import pytest

from codegen.reference import reference_observer

TOL = 1e-9
N_CASES = 200
N_SAT = 40
_LAWS = {}


def _rel(a, b):
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


def _law(name):
    """(spec, compiled law, reference) per law, built and compiled once for the module."""
    if name not in _LAWS:
        from codegen import compile_observer
        from codegen.families.controllers import seed000, spong
        from models.catalog import load_elastic, load_robot
        if name.startswith("seed000"):
            robot = load_robot("seed000_2r")
            kind = name.split(":")[1]
            spec = (seed000.tracking(robot, (-np.pi / 2, 0.3)) if kind == "tracking"
                    else seed000.open_loop(robot, int(kind[-1])))
            obs = compile_observer(spec)
        else:
            law, robot_name = name.split(":")
            e = load_elastic(robot_name)
            build = spong.feedback_linearization if law == "fl" else spong.integral_manifold
            spec = build(e)
            obs = compile_observer(spec, inline=e.n < 3)
        _LAWS[name] = spec, obs, reference_observer(spec)
    return _LAWS[name]


def _compare(spec, obs, ref, ys, ps):
    """Worst relative error of the C law against the reference over (y, p) pairs."""
    worst = 0.0
    for y, p in zip(ys, ps):
        obs.reset(y, p=p)
        ref.reset(y, p=p)
        got, want = obs.estimate(y, []), ref.estimate(y, [])
        assert np.all(np.isfinite(want))
        worst = max(worst, _rel(got, want))
    return worst


# ---------------------------------------------------------------- seed 000 (docs/papers/seed000.md §1.4, docs/papers/experiments.md §12.1)
@pytest.mark.parametrize("kind", ["ex1", "ex2", "tracking"])
def test_seed000_laws_match_reference(kind):
    spec, obs, ref = _law(f"seed000:{kind}")
    rng = np.random.default_rng({"ex1": 1, "ex2": 2, "tracking": 3}[kind])
    n = spec.robot.n
    ys, ps = [], []
    for _ in range(N_CASES):
        q, t = rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.0, 12.0)     # t also before/after the move
        if kind == "tracking":
            qh = rng.uniform(-3.0, 3.0, n)
            p = np.r_[rng.uniform(-np.pi, np.pi, 2 * n), rng.uniform(2.0, 10.0), rng.uniform(0.1, 2.0),
                      rng.uniform(10.0, 100.0, 2 * n)]
            ys.append(np.r_[q, qh, t])
            ps.append(p if rng.random() < 0.8 else spec.p_default)
        else:
            ys.append(np.r_[q, t])
            ps.append(spec.p_default)
    worst = _compare(spec, obs, ref, ys, ps)
    print(f"seed000 {kind}: worst relative error {worst:.2e}")
    assert worst <= TOL


# ---------------------------------------------------------------- Spong laws (docs/papers/seed004.md §9, §10, docs/papers/experiments.md §12.4)
def _elastic_inputs(n, rng, count):
    """Measurements y = [x; q_d .. q_d''''] in physical ranges: links within (-pi, pi), speeds of
    a few rad/s, motor positions/speeds close to the links' (elastic torques up to ~200 N m),
    a reference near q1 with moderate derivatives; half of them from the cubic of docs/papers/experiments.md §12.4."""
    from codegen.families.controllers.spong import cubic_reference
    ys = []
    for k in range(count):
        q1, v1 = rng.uniform(-np.pi, np.pi, n), rng.uniform(-3.0, 3.0, n)
        q2 = q1 + rng.uniform(-1e-2, 1e-2, n)
        v2 = v1 + rng.uniform(-0.5, 0.5, n)
        if k % 2:
            ref = cubic_reference(rng.uniform(0.0, 6.0), q1 + rng.uniform(-0.5, 0.5, n),
                                  rng.uniform(-np.pi, np.pi, n), 5.0)
        else:
            ref = np.stack([q1 + rng.uniform(-0.3, 0.3, n)] + [rng.uniform(-s, s, n) for s in (3, 5, 10, 20)])
        ys.append(np.r_[q1, v1, q2, v2, ref.ravel()])
    return ys


@pytest.mark.slow
@pytest.mark.parametrize("law", ["fl", "manifold"])
@pytest.mark.parametrize("robot", ["seed004_2r", pytest.param("seed004_3r", marks=pytest.mark.long)])
def test_spong_laws_match_reference(law, robot):
    """The law itself with u_max = 1e12 on N_CASES inputs (at the default gains most random
    states saturate at 200 N m), then the default +-200 N m saturation on N_SAT of them."""
    spec, obs, ref = _law(f"{law}:{robot}")
    n = spec.robot.n
    rng = np.random.default_rng(40 + n + (law == "manifold"))
    ys = _elastic_inputs(n, rng, N_CASES)
    assert spec.p_names[-1] == "u_max" and spec.p_default[-1] == 200.0
    p_free = np.r_[spec.p_default[:-1], 1e12]
    worst_free = _compare(spec, obs, ref, ys, [p_free] * len(ys))
    worst_sat = _compare(spec, obs, ref, ys[:N_SAT], [spec.p_default] * N_SAT)
    print(f"{law} {robot}: worst relative error unsaturated {worst_free:.2e}, saturated {worst_sat:.2e}")
    assert worst_free <= TOL and worst_sat <= TOL


@pytest.mark.parametrize("robot", ["seed004_2r", "seed004_3r"])
def test_reference_F_one_shot_equals_column_form(robot):
    """The Spong references' F = e1e2 part of y3(x + e1 f + e2 f + e1e2 Df f) against
    ElasticRobot.spong_F (dPhi/dx column by column, both exact): same to rounding."""
    from codegen.reference.families import spong_fl
    from codegen.reference.robots import reference_robot
    from models.catalog import load_elastic
    r = reference_robot(load_elastic(robot).source)
    for y in _elastic_inputs(r.n, np.random.default_rng(7), 6):
        x = y[:4 * r.n]
        y3, y4, F = spong_fl.spong_y3_y4_F(r, x)
        assert _rel(y3, r.y3(x)) < 1e-13 and _rel(y4, r.y4(x)) < 1e-13
        assert _rel(F, r.spong_F(x)) < 1e-11
