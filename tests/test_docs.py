"""The repository's documentation is self-contained and its citations resolve.

The code cites the equations' pages as ``docs/papers/<page>.md §N.M`` and the architecture as
``docs/architecture.md §N``: each such citation must name a heading "§N.M" of that page
(``## §1.3 Hybrid switching logic``). Inside ``docs/`` pages cite each other by relative name
(``seed000.md §1.3``, ``[seed000.md](seed000.md) §1.3``). A list or range after a citation
(``§11.3–§11.4``, ``§0, §1.2``) is checked item by item.

``docs/papers/sections.json`` maps every section number to the one page that holds it (and
"DESIGN" to the architecture page), so that older citations of the form "SPEC §N.M" and
"DESIGN §N" can be rewritten mechanically; while any remain, each must be in the map.

Relative Markdown links of the pages (docs/, README.md, c_harness/, generated/README.md) must
name an existing file, and an anchor (``page.md#tags``) a heading of that page (GitHub's rule for
heading anchors). The ambiguity ids the code cites (A0-3, A4-6, ...) are in the register.
Two kinds of target exist only in the built site (mkdocs.yml): the page tools/docs_hooks.py
generates (the C API, ``docs/reference/c-api.md``), and the anchors mkdocstrings gives the
objects of a ``::: module`` line (``families.md#codegen.families.observers.tomei``).
"""
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAPERS = DOCS / "papers"
SECTIONS = PAPERS / "sections.json"
REGISTER = PAPERS / "ambiguities.md"

# where citations are looked for, and which files are read as text
SCAN_DIRS = ("codegen", "models", "tests", "docs", "c_harness")
SCAN_FILES = ("README.md", "targets.toml", "Makefile")
TEXT_SUFFIXES = {".py", ".md", ".toml", ".in", ".c", ".h", ".cpp", ".txt", ".json", ".sh", ".cfg"}
SKIP_PARTS = {"__pycache__", ".venv", ".git", "build", "observer_codegen.egg-info"}
# pages whose links are checked
LINK_PAGES = ("README.md", "docs/**/*.md", "c_harness/**/*.md", "generated/README.md")

NUM = r"\d+(?:\.\d+)*"
TAIL = rf"((?:\s*(?:,|–|-|and|or|to)\s*§{NUM})*)"           # further sections in a list/range
FULL = re.compile(rf"(?<![\w/.])(docs/[\w/.-]+\.md) §({NUM}){TAIL}")   # docs/papers/seed000.md §1.3
LINKED = re.compile(rf"\]\(([^)\s#]+\.md)(?:#[^)\s]*)?\) §({NUM}){TAIL}")  # [x](seed000.md) §1.3
BARE = re.compile(rf"(?<![\w/.(\[])([\w-]+\.md) §({NUM}){TAIL}")          # seed000.md §1.3
OLD = re.compile(rf"\bSPEC §({NUM})")
OLD_DESIGN = re.compile(rf"\bDESIGN §({NUM})")
HEADING = re.compile(rf"^#{{1,6}}\s+§({NUM})\s", re.M)
AMBIGUITY = re.compile(r"\bA[0-4]-\d{1,2}\b")
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
GENERATED = {DOCS / "reference" / "c-api.md"}        # written by tools/docs_hooks.py at build time


def _text_files():
    files = [ROOT / f for f in SCAN_FILES if (ROOT / f).is_file()]
    for d in SCAN_DIRS:
        for f in sorted((ROOT / d).rglob("*")):
            rel = f.relative_to(ROOT).parts
            if f.is_file() and not SKIP_PARTS.intersection(rel) and \
                    (f.suffix in TEXT_SUFFIXES or f.name == "Makefile"):
                files.append(f)
    return files


def _read(f):
    try:
        return f.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return ""


def _headings(page):
    """Section numbers of the "§N.M" headings of ``page`` (a Path), [] if it has none."""
    return HEADING.findall(_read(page)) if page.is_file() else []


def _line(text, pos):
    return text.count("\n", 0, pos) + 1


def _citations():
    """(file, line, page Path, section) for every citation of a docs page by path or name."""
    out = []
    for f in _text_files():
        text = _read(f)
        in_docs = DOCS in f.parents
        patterns = [(FULL, ROOT)] + ([(LINKED, f.parent), (BARE, f.parent)] if in_docs else [])
        for pattern, base in patterns:
            for m in pattern.finditer(text):
                page = (base / m.group(1)).resolve()
                for sec in [m.group(2)] + re.findall(rf"§({NUM})", m.group(3)):
                    out.append((f.relative_to(ROOT), _line(text, m.start()), page, sec))
    return out


def _slug(heading):
    """GitHub's anchor of a Markdown heading: formatting and links stripped, lower case,
    characters other than letters, digits, "_", "-" and spaces dropped, spaces to "-"."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = text.replace("`", "").replace("*", "").strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(page):
    seen, out = {}, set()
    for line in _read(page).splitlines():
        directive = re.match(r":::\s+([\w.]+)\s*$", line)        # mkdocstrings: the object's path
        if directive:
            out.add(directive.group(1))
        m = re.match(r"#{1,6}\s+(.*)", line)
        if m:
            s = _slug(m.group(1))
            out.add(f"{s}-{seen[s]}" if s in seen else s)
            seen[s] = seen.get(s, 0) + 1
    return out


def _strip_code_and_math(text):
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    text = re.sub(r"`[^`\n]*`", "", text)
    return re.sub(r"\$[^$\n]*\$", "", text)


def _sections():
    return json.loads(SECTIONS.read_text())


def test_sections_map_every_heading_to_its_one_page():
    """sections.json and the "§" headings of docs/papers/*.md agree both ways; each number is the
    heading of exactly one page."""
    mapping = _sections()
    assert mapping.pop("DESIGN") == "docs/architecture.md"
    found = {}
    for page in sorted(PAPERS.glob("*.md")):
        for sec in _headings(page):
            rel = page.relative_to(ROOT).as_posix()
            assert sec not in found, f"§{sec} is a heading of both {found[sec]} and {rel}"
            found[sec] = rel
    assert found == mapping, (f"headings not in sections.json: {sorted(set(found) - set(mapping))}; "
                              f"entries without a heading: {sorted(set(mapping) - set(found))}; "
                              f"wrong page: {sorted(k for k in found if k in mapping and found[k] != mapping[k])}")
    for top in ("0", "1", "3", "4", "6", "11", "12", "14"):          # the seeds' sections and the register
        assert top in found, f"§{top} has no page"


def test_architecture_has_the_design_sections():
    """docs/architecture.md keeps its numbered sections §1-§5 (cited as docs/architecture.md §N)."""
    assert {"1", "2", "3", "4", "5"} <= set(_headings(DOCS / "architecture.md"))


def test_citations_of_docs_pages_resolve():
    """Every ``docs/.../<page>.md §N.M`` in the code, tests, README and docs (and every relative
    ``<page>.md §N.M`` inside docs/) names a heading of an existing page."""
    cites = _citations()
    bad = [f"{f}:{line}: {page.relative_to(ROOT) if ROOT in page.parents else page} §{sec}"
           + ("" if page.is_file() else " (no such page)")
           for f, line, page, sec in cites if sec not in _headings(page)]
    assert not bad, f"{len(bad)} citations name no heading:\n" + "\n".join(bad)
    # the docs cite themselves, so the scan found something: the patterns are not dead
    assert any(page == (PAPERS / "seed000.md").resolve() for _, _, page, _ in cites)


def test_remaining_old_citations_are_mapped():
    """Until they are rewritten, "SPEC §N.M" citations name a section of sections.json (so the
    rewrite lands on a heading) and "DESIGN §N" a heading of docs/architecture.md."""
    mapping = _sections()
    arch = set(_headings(DOCS / "architecture.md"))
    bad = []
    for f in _text_files():
        text = _read(f)
        bad += [f"{f.relative_to(ROOT)}:{_line(text, m.start())}: SPEC §{m.group(1)}"
                for m in OLD.finditer(text) if m.group(1) not in mapping]
        bad += [f"{f.relative_to(ROOT)}:{_line(text, m.start())}: DESIGN §{m.group(1)}"
                for m in OLD_DESIGN.finditer(text) if m.group(1) not in arch]
    assert not bad, f"{len(bad)} old citations without a section:\n" + "\n".join(bad)


def _link_pages():
    pages = []
    for pattern in LINK_PAGES:
        pages += [p for p in sorted(ROOT.glob(pattern)) if p.is_file()]
    return pages


@pytest.mark.parametrize("page", _link_pages(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(page):
    """Every relative link of the page names an existing file (and an anchor a heading)."""
    bad = []
    for target in LINK.findall(_strip_code_and_math(_read(page))):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):          # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists() and dest not in GENERATED:
            bad.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            bad.append(f"{target}: no heading with anchor #{anchor}")
    assert not bad, f"{page.relative_to(ROOT)}: " + "; ".join(bad)


def test_cited_ambiguity_ids_are_in_the_register():
    """Every ambiguity id cited in the code (A0-3, ...) is an entry of docs/papers/ambiguities.md."""
    register = set(re.findall(r"^\|\s*(A[0-4]-\d{1,2})\s*\|", _read(REGISTER), re.M))
    assert register, "no entries found in the register"
    bad = []
    for f in _text_files():
        if f == REGISTER:
            continue
        text = _read(f)
        bad += [f"{f.relative_to(ROOT)}:{_line(text, m.start())}: {m.group(0)}"
                for m in AMBIGUITY.finditer(text) if m.group(0) not in register]
    assert not bad, f"{len(bad)} ambiguity ids not in the register:\n" + "\n".join(bad)
