"""The three tutorials of the documentation site run as written (docs/tutorials/*.md).

Each page's fenced blocks are taken in order, in an empty folder: a block with a title
(```` ```c title="main.c" ````) writes that file; a ``python`` block runs in one namespace per
page (the folder as working directory); an ``sh`` block runs in bash (``set -euo pipefail``) with
``python`` this interpreter and the repository importable. A ``sh`` block whose first line is
``# needs: TOOL ...`` is skipped, and said so, when a tool is missing (the Cortex-M flow of
``make embedded``). Blocks of other languages without a title (``text``: printed output) are
not run.
"""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = ROOT / "docs" / "tutorials"
PAGES = ("your-robot.md", "your-microcontroller.md", "your-log.md")
FENCE = re.compile(r"^```(\w*)([^\n]*)\n(.*?)^```[ \t]*$", re.M | re.S)


def blocks(page):
    """(language, title or None, body) of every fenced block of ``page``, in order."""
    out = []
    for m in FENCE.finditer(page.read_text(encoding="utf-8")):
        title = re.search(r'title="([^"]+)"', m.group(2))
        out.append((m.group(1), title.group(1) if title else None, m.group(3)))
    return out


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
    namespace, skipped = {"__name__": "__tutorial__"}, []
    for i, (lang, title, body) in enumerate(blocks(page)):
        where = f"{page.name}, block {i + 1} ({lang or 'text'})"
        if title:
            path = folder / title
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body)
        elif lang == "python":
            exec(compile(body, where, "exec"), namespace)          # noqa: S102 (the page's own code)
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
    return skipped


def test_the_pages_have_runnable_blocks():
    """Each tutorial runs code (a page of prose only would pass its test vacuously)."""
    for name in PAGES:
        langs = [lang for lang, title, _ in blocks(TUTORIALS / name) if not title]
        assert "python" in langs or "sh" in langs, f"{name}: no python or sh block"


@pytest.mark.long          # minutes each: make test-long (CI), not make test
@pytest.mark.parametrize("name", PAGES)
def test_tutorial_runs(name, tmp_path, monkeypatch, capsys):
    skipped = run_page(TUTORIALS / name, tmp_path, monkeypatch)
    with capsys.disabled():
        for s in skipped:
            print(f"\nskipped {s}")
