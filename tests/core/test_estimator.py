"""One Estimator protocol (codegen.core.estimator): the compiled observers, the numpy reference and
every baseline have it, and ``estimate`` does what ``step`` would without advancing."""
import numpy as np
import pytest

from codegen.core.estimator import Estimator
from codegen.evaluate import baselines
from codegen.reference import reference_observer


def _estimators(compiled, spec_of):
    spec = spec_of("seed000_2r")
    yield "compiled", compiled("seed000_2r")
    yield "reference", reference_observer(spec)
    for name in baselines.BASELINES:
        yield name, baselines.make(name, 2, 1e-3)


def test_every_estimator_follows_the_protocol(compiled, spec_of):
    Y = np.column_stack([np.sin(np.arange(6) * 1e-2), np.cos(np.arange(6) * 1e-2)])
    U = np.zeros((6, 2))
    for name, est in _estimators(compiled, spec_of):
        assert isinstance(est, Estimator), name
        est.reset(Y[0])
        before = est.state
        peek = est.estimate(Y[1], U[1])
        np.testing.assert_array_equal(est.state, before, err_msg=name)
        np.testing.assert_array_equal(est.step(Y[1], U[1]), peek, err_msg=name)
        out = est.run(Y[2:], U[2:])
        assert out.shape == (4, est.nest) and np.all(np.isfinite(out)), name


@pytest.mark.parametrize("thing", [object(), np.zeros(3), "observer"])
def test_other_things_are_not_estimators(thing):
    assert not isinstance(thing, Estimator)
