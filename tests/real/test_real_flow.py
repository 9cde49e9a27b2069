"""The user's flow on each real arm: ``describe`` (the held-out log) -> ``identify`` (one part) ->
``compare`` (the held-out part, the identified model) -> ``build`` of the winning observer, as
subprocesses (codegen.evaluate.scenarios.real_judge.Bed). Bars of issue 38: no refusal of the
project's own outputs. Each step's wall time is measured and shown on docs/guide/real-logs.md (a figure
of the machine it ran on, never a timed assertion)."""
import pytest

from codegen.evaluate.scenarios import real_judge

from .real_params import params

pytestmark = pytest.mark.real
ARMS = tuple(real_judge.FLOWS)


@pytest.mark.parametrize("arm", params(ARMS))
def test_the_flow_runs(arm, bed):
    steps = bed.flow(arm)
    failed = {k: s["error"] for k, s in steps.items() if not s["ok"]}
    assert not failed, failed
