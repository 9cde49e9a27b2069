"""Cross-check inputs (codegen.verify.inputs) drawn where each family declares them
(``spec.inputs``, codegen.core.options.InputRanges): finite, inside the declared ranges, integer slots
integers, and the compiled C equal to the independent reference on them (docs/architecture.md §4: 1e-9)."""
import copy
import importlib

import numpy as np
import pytest

from codegen.families import observers
from codegen.verify import cross_check, random_inputs
from codegen.core.options import InputRanges
from codegen.pipeline.targets_file import build_spec, make_target

TOL = 1e-9
COUNT = 100
SIGMAS = 6.0         # a normal draw beyond 6 standard deviations is a bug, not bad luck (p ~ 2e-9)


def _cases():
    """case -> targets-file entry, from every family's declared ``EXAMPLES`` (the first one is
    named after the family, the others ``<family>_<i>``): a new family is covered by declaring them."""
    cases = {}
    for family in observers.FAMILIES:
        for i, entry in enumerate(importlib.import_module(f"{observers.__name__}.{family}").EXAMPLES):
            cases[family if i == 0 else f"{family}_{i}"] = dict(entry, family=family)
    return cases


CASES = _cases()
_SPECS = {}


def spec_of(case):
    if case not in _SPECS:
        _SPECS[case] = build_spec(make_target(CASES[case], where=case)[0])
    return _SPECS[case]


def _within(a, lo, hi):
    return bool(np.all((a >= lo) & (a <= hi)))


def _u_bound(ir, G):
    """|u - centre| bound of the declared u draw, and the centre."""
    if ir.u == "gravity":
        return SIGMAS * ir.u_scale, G
    if ir.u == "scaled":
        return SIGMAS * ir.u_scale * np.maximum(1.0, np.abs(G).max(axis=0)), 0.0
    return SIGMAS * ir.u_scale, 0.0


@pytest.mark.parametrize("case", list(CASES))
def test_drawn_inputs_are_finite_and_in_the_declared_ranges(case):
    spec = spec_of(case)
    ir, robot, n = spec.inputs, spec.robot, spec.robot.n
    X, Y, U = random_inputs(spec, COUNT, seed=5)
    assert (X.shape, Y.shape, U.shape) == ((COUNT, spec.nx), (COUNT, spec.ny), (COUNT, spec.nu))
    assert all(np.all(np.isfinite(A)) for A in (X, Y, U))
    if hasattr(robot, "sample_states"):
        return      # elastic: y is read off drawn true states (verify.inputs), not drawn in ranges
    slack = 0.0 if ir.y_jitter is None else SIGMAS * ir.y_jitter
    assert _within(Y[:, :n], robot.q_lower - slack, robot.q_upper + slack)
    for k, (mean, std) in enumerate(ir.y_extra):
        assert _within(Y[:, n + k], mean - SIGMAS * std, mean + SIGMAS * std), spec.y_names[n + k]
    G = np.asarray(robot.g.map(COUNT)(Y[:, :n].T)).T[:, :spec.nu]
    bound, centre = _u_bound(ir, G)
    assert np.all(np.abs(U - centre) <= bound)
    x = {name: X[:, i] for i, name in enumerate(spec.x_names)}
    y = {name: Y[:, i] for i, name in enumerate(spec.y_names)}
    for name, lo, hi in ir.x_uniform:
        assert _within(x[name], lo, hi), name
    for name, lo, hi in ir.x_integer:
        assert np.array_equal(x[name], np.round(x[name])) and _within(x[name], lo, hi), name
        assert set(np.unique(x[name])) == set(range(lo, hi + 1)), name    # every value is drawn
    for name, mean, std in ir.x_normal:
        assert _within(x[name], mean - SIGMAS * std, mean + SIGMAS * std), name
    scale = np.broadcast_to(np.asarray(ir.x_scale, dtype=float), (spec.nx,))
    for xs, ys in ir.x_about_y:
        assert np.all(np.abs(x[xs] - y[ys]) <= SIGMAS * scale[spec.x_names.index(xs)]), xs


def test_fine_draws_sit_inside_the_boundary_layer():
    """su_nonsmooth (tanh layer 1e-4): about half of the qhat draws within 6e-4 of q."""
    spec = spec_of("su_nonsmooth_1")
    X, Y, _ = random_inputs(spec, 400, seed=2)
    fine = np.all(np.abs(X[:, :2] - Y) <= SIGMAS * spec.inputs.x_fine, axis=1)
    assert 0.35 <= fine.mean() <= 0.65


def test_jittered_configurations_are_one_fixed_draw():
    """I&I (y_jitter = 1e-2 rad): two seeds differ by the jitter only, not by whole configurations."""
    spec = spec_of("ii_speed")
    _, Y1, _ = random_inputs(spec, COUNT, seed=1)
    _, Y2, _ = random_inputs(spec, COUNT, seed=2)
    assert np.abs(Y1 - Y2).max() <= 2 * SIGMAS * spec.inputs.y_jitter


@pytest.mark.slow
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.long) if c.startswith("ciccarella_germani")
                                  else c for c in CASES])   # CG: minutes each (elastic, Q(x)^-1)
def test_c_equals_reference_on_drawn_inputs(case):
    """At the example's discretisation (the default one unless it states dt: the elastic
    observers run at seed 004's 1e-4 s) with the fewest stable sub-steps (the tanh-smoothed Su
    observer, eps = 1e-4, is too stiff for one step at 1 kHz: the stability check refuses it; the
    fewest for dt, 2, are stable up to an elapsed time of 1.67 ms, which auto_substeps declares as
    its dt_max)."""
    from dataclasses import replace

    from codegen.discrete.stability import auto_substeps
    spec = spec_of(case)
    target = make_target(CASES[case], where=case)[0]
    disc = auto_substeps(spec, replace(target.discretization, substeps="auto"))
    r = cross_check(spec, disc, count=COUNT)
    for key in ("step_est", "step_state", "rhs", "run"):
        assert r[key] <= TOL, (key, r)


@pytest.mark.parametrize("field,value,match", [
    ("x_uniform", (("no_such_slot", 0.0, 1.0),), "no_such_slot"),
    ("x_about_y", (("z_q1", "no_such_measurement"),), "no_such_measurement"),
    ("init_p", (("no_such_parameter", 1.0),), "no_such_parameter"),
    ("x_scale", (0.1, 0.2, 0.3), "x_scale"),
    ("y_extra", ((0.0, 1.0),), "measurement slots"),
])
def test_bad_declarations_raise_naming_what(field, value, match):
    spec = copy.copy(spec_of("reduced_order"))
    spec.inputs = InputRanges(**{field: value})
    with pytest.raises(ValueError, match=match):
        random_inputs(spec, 4)


def test_unknown_u_draw_is_refused():
    with pytest.raises(ValueError, match="^u must be one of"):
        InputRanges(u="around")
