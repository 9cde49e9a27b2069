"""The parameters of the real-log tests, the ones failing today marked xfail (strict: a bar met
turns the mark into a failure until it goes)."""
import pytest


def params(names, failing=None):
    """pytest params of ``names`` (logs, arms or (train, test) pairs); ``failing`` {name: what it
    measures today} marks those xfail, strict (a bar that starts to hold fails the run until its mark
    goes)."""
    out = []
    for n in names:
        marks = []
        if n in (failing or {}):
            marks.append(pytest.mark.xfail(strict=True, reason=f"measured today: {failing[n]}"))
        out.append(pytest.param(n, marks=marks, id=n if isinstance(n, str) else "->".join(n)))
    return out
