"""The real-log folder (``$CODEGEN_REAL_LOGS`` or ``../shared/data/real``): the one test collected
here without it, skipped with the one line that says where to put the logs."""
import pytest

from codegen.evaluate.scenarios import real_logs

pytestmark = pytest.mark.real


def test_the_real_log_folder_holds_every_arm():
    where = real_logs.folder()
    if where is None:
        pytest.skip(real_logs.skip_reason())
    missing = [s["file"] for s in real_logs.ARMS.values() if not (where / s["file"]).is_file()]
    assert not missing, f"{where}: missing {', '.join(missing)}"
