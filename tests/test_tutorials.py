"""The tutorials of the documentation site run as written (docs/tutorials/*.md).

Each page's fenced blocks are taken in order, in an empty folder: a block with a title
(```` ```c title="main.c" ````) writes that file; a ``python`` block runs in one namespace per
page (the folder as working directory); an ``sh`` block runs in bash (``set -euo pipefail``) with
``python`` this interpreter and the repository importable. A ``sh`` block whose first line is
``# needs: TOOL ...`` is skipped, and said so, when a tool is missing (the Cortex-M flow of
``make embedded``). A ``text`` block is what the runnable block before it prints (stdout):
each of its lines, in order, is one of the printed lines, ``…`` in a line standing for any text
(a path of your machine) and a line ``...`` marking where printed lines are left out. Blocks of
other languages without a title are not run.
"""
import contextlib
import io
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = ROOT / "docs" / "tutorials"
PAGES = ("your-robot.md", "your-microcontroller.md", "your-log.md", "your-log-from-a-bag.md")
FENCE = re.compile(r"^```(\w*)([^\n]*)\n(.*?)^```[ \t]*$", re.M | re.S)


def blocks(page):
    """(language, title or None, body) of every fenced block of ``page``, in order."""
    out = []
    for m in FENCE.finditer(page.read_text(encoding="utf-8")):
        title = re.search(r'title="([^"]+)"', m.group(2))
        out.append((m.group(1), title.group(1) if title else None, m.group(3)))
    return out


def shown_in(shown, printed):
    """The lines of ``shown`` (a ``text`` block) that are not among the lines of ``printed`` in
    order: ``…`` in a shown line matches any text, a shown line ``...`` is left out (it marks
    elided output); trailing blanks are ignored. Empty: the block shows what was printed."""
    lines = [line.rstrip() for line in printed.splitlines()]
    missing, at = [], 0
    for want in shown.splitlines():
        want = want.rstrip()
        if want.strip() in ("", "..."):
            continue
        pattern = re.compile(".*".join(map(re.escape, want.split("…"))))
        hit = next((i for i in range(at, len(lines)) if pattern.fullmatch(lines[i])), None)
        if hit is None:
            missing.append(want)
        else:
            at = hit + 1
    return missing


def run_page(page, folder, monkeypatch):
    """Run the blocks of ``page`` in ``folder``; returns the names of the skipped sh blocks."""
    bin_dir = folder / ".bin"
    bin_dir.mkdir()
    wrapper = bin_dir / "python"                    # not a symlink: a venv's python finds its
    wrapper.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')   # packages from its own path
    wrapper.chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}",
               PYTHONPATH=os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]),
               CODEGEN_BUILD=str(folder / "build"), MPLBACKEND="Agg")
    monkeypatch.chdir(folder)
    monkeypatch.setenv("CODEGEN_BUILD", env["CODEGEN_BUILD"])
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace, skipped, printed = {"__name__": "__tutorial__"}, [], None
    for i, (lang, title, body) in enumerate(blocks(page)):
        where = f"{page.name}, block {i + 1} ({lang or 'text'})"
        if lang == "text" and not title:
            if printed is not None:         # None: the block before it was skipped
                missing = shown_in(body, printed)
                assert not missing, (f"{where} shows lines its block did not print:\n"
                                     + "\n".join(missing) + f"\n--- printed\n{printed[-4000:]}")
            continue
        printed = None
        if title:
            path = folder / title
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body)
        elif lang == "python":
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                exec(compile(body, where, "exec"), namespace)      # noqa: S102 (the page's own code)
            printed = out.getvalue()
        elif lang == "sh":
            needs = re.match(r"#\s*needs:\s*(.*)", body)
            missing = [t for t in (needs.group(1).split() if needs else []) if shutil.which(t) is None]
            if missing:
                skipped.append(f"{where}: {', '.join(missing)} missing")
                continue
            run = subprocess.run(["bash", "-euo", "pipefail", "-c", body], cwd=folder, env=env,
                                 capture_output=True, text=True)
            assert run.returncode == 0, (f"{where} exited {run.returncode}:\n{body}\n--- stdout\n"
                                         f"{run.stdout[-4000:]}\n--- stderr\n{run.stderr[-4000:]}")
            printed = run.stdout
    return skipped


def test_the_pages_have_runnable_blocks():
    """Each tutorial runs code (a page of prose only would pass its test vacuously)."""
    for name in PAGES:
        langs = [lang for lang, title, _ in blocks(TUTORIALS / name) if not title]
        assert "python" in langs or "sh" in langs, f"{name}: no python or sh block"


def test_shown_in_matches_printed_lines_in_order():
    printed = "a: 1\nb: /tmp/x/lib.so (2 s)\nc: 3\n"
    assert shown_in("a: 1\n...\nc: 3\n", printed) == []
    assert shown_in("b: … (2 s)", printed) == []
    assert shown_in("c: 3\na: 1", printed) == ["a: 1"]           # out of order
    assert shown_in("a: 2", printed) == ["a: 2"]                  # a number the code no longer prints


def test_a_page_showing_what_its_code_does_not_print_fails(tmp_path, monkeypatch):
    page = tmp_path / "page.md"
    shown = "```python\nprint('k0 =', 2 * 13)\n```\n\n```text\nk0 = {}\n```\n"
    (tmp_path / "run").mkdir()
    page.write_text(shown.format(26))
    assert run_page(page, tmp_path / "run", monkeypatch) == []
    (tmp_path / "run2").mkdir()
    page.write_text(shown.format(27))
    with pytest.raises(AssertionError, match="shows lines its block did not print"):
        run_page(page, tmp_path / "run2", monkeypatch)


def test_every_output_block_follows_a_runnable_block():
    """A ``text`` block shows what the block before it printed: that block runs (python or sh)."""
    for name in PAGES:
        previous = None
        for lang, title, _ in blocks(TUTORIALS / name):
            if lang == "text" and not title:
                assert previous in ("python", "sh"), f"{name}: a text block after a {previous} block"
            previous = None if title else lang


@pytest.mark.long          # minutes each: make test-long (CI), not make test
@pytest.mark.parametrize("name", PAGES)
def test_tutorial_runs(name, tmp_path, monkeypatch, capsys):
    skipped = run_page(TUTORIALS / name, tmp_path, monkeypatch)
    with capsys.disabled():
        for s in skipped:
            print(f"\nskipped {s}")
