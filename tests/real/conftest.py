"""The real arms' logs (codegen.evaluate.scenarios.real_logs): from ``$CODEGEN_REAL_LOGS`` or
``../shared/data/real`` beside the repository. Without either (a clone has no ``../shared``) only
test_folder.py is collected, and it skips: one line. One ``Bed`` per worker runs each command
once; `make test-real` keeps an arm's tests on one worker (``xdist_group`` by arm,
real_params.py, ``--dist loadgroup``)."""
import pytest

from codegen.evaluate.scenarios import real_judge, real_logs

if real_logs.folder() is None:
    collect_ignore_glob = ["test_[!f]*.py"]


@pytest.fixture(scope="session")
def bed(tmp_path_factory):
    """The real logs' CSVs and the commands' outputs, in a temporary folder."""
    return real_judge.Bed(tmp_path_factory.mktemp("real"))
