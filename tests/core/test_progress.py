"""Progress bars only on a terminal, whole lines elsewhere (codegen.core.progress)."""
import io

from codegen.core import progress
from codegen.core.progress import Lines, bar


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_off_a_terminal_progress_is_whole_lines(monkeypatch):
    """A pipe gets a line per stage (the postfix changing) and no carriage return, so an error
    written after it starts on its own line; a count alone writes at most every LINE_SECONDS."""
    out = io.StringIO()
    with bar(total=3, desc="identify arm", unit="step", file=out, disable=False, leave=False) as b:
        assert isinstance(b, Lines)
        b.set_postfix_str("smoothing")
        b.update()
        b.set_postfix_str("Coulomb width")
        b.update(2)
    out.write("error: something\n")
    assert "\r" not in out.getvalue()
    assert out.getvalue().splitlines() == ["identify arm: 0/3 step (smoothing)", "identify arm: 1/3 step (Coulomb width)",
                                           "error: something"]
    monkeypatch.setattr(progress, "LINE_SECONDS", 0.0)           # every update is due
    out = io.StringIO()
    assert [k for k in bar(range(3), desc="simulate", file=out)] == [0, 1, 2]
    assert out.getvalue().splitlines() == ["simulate: 1/3 it", "simulate: 2/3 it", "simulate: 3/3 it"]


def test_on_a_terminal_a_tqdm_bar_and_disabled_means_nothing():
    from tqdm import tqdm
    term = Terminal()
    with bar(total=2, desc="compare", file=term, leave=False) as b:
        assert isinstance(b, tqdm)
        b.update(2)
    assert "compare" in term.getvalue()
    for disable in (True, None):                 # None: tqdm's "not on a terminal": nothing here
        out = io.StringIO()
        with bar(total=2, desc="x", file=out, disable=disable) as b:
            b.set_postfix_str("a")
            b.update(2)
        assert out.getvalue() == ""
