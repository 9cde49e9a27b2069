"""The real arms' logs (codegen.evaluate.scenarios.real_logs): from ``$CODEGEN_REAL_LOGS`` or
``../shared/data/real`` beside the repository. Without either (a clone has no ``../shared``) only
test_real_folder.py is collected, and it skips: one line. The run's workers share one ``Bed`` folder:
each command runs once."""
import os
from pathlib import Path

import pytest

from codegen.evaluate.scenarios import real_judge, real_logs

if real_logs.folder() is None:
    collect_ignore = [p.name for p in Path(__file__).parent.glob("test_*.py") if p.name != "test_real_folder.py"]


@pytest.fixture(scope="session")
def bed(tmp_path_factory):
    """The real logs' CSVs and the commands' outputs, in a temporary folder shared by this run's
    workers (each command run once: ``Bed.run``)."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent                  # popen-gw<k>'s parent: the run's own folder
    return real_judge.Bed(root / "real-bed")
