"""The real arms' logs (codegen.evaluate.scenarios.real_logs): from ``$CODEGEN_REAL_LOGS`` or
``../shared/data/real`` beside the repository; without either the whole folder is skipped with
one line (a clone has no ``../shared``). One ``Bed`` per worker runs each command once; `make
test-real` keeps an arm's tests on one worker (``xdist_group`` by arm, ``--dist loadgroup``)."""
import pytest

from codegen.evaluate.scenarios import real_judge, real_logs

if real_logs.folder() is None:
    pytest.skip(real_logs.skip_reason(), allow_module_level=True)


@pytest.fixture(scope="session")
def bed(tmp_path_factory):
    """The real logs' CSVs and the commands' outputs, in a temporary folder."""
    return real_judge.Bed(tmp_path_factory.mktemp("real"))


def arm(name):
    """The xdist group of the log or arm ``name``: its arm."""
    return real_logs.LOGS[name][0] if name in real_logs.LOGS else name


def by_arm(names, failing=None):
    """pytest params of ``names`` (logs, arms or (train, test) pairs), each in its arm's xdist
    group; ``failing`` {name: what it measures today} marks those xfail (not strict: the fixes of
    issue 38 land one by one, then the mark goes)."""
    out = []
    for n in names:
        marks = [pytest.mark.xdist_group(arm(n if isinstance(n, str) else n[0]))]
        if n in (failing or {}):
            marks.append(pytest.mark.xfail(strict=False, reason=f"measured today: {failing[n]}"))
        out.append(pytest.param(n, marks=marks, id=n if isinstance(n, str) else "->".join(n)))
    return out
