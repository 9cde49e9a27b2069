"""The documentation site (mkdocs.yml, docs/) covers what it must: every public module, function
and class on a Python API page, every declared C function on the C API page, every observer family
on a page of its own in the navigation.

"Public": a module of codegen/ or models/ none of whose path parts starts with "_", and in it
every top-level function and class whose name does not start with "_" and that the module itself
defines (found by parsing the source, nothing imported). The API pages render a module with a
``::: module`` line and mkdocstrings' options of mkdocs.yml (``filters: ["!^_"]``,
``show_if_no_docstring: true``), so a module named there shows every such member; a ``:::`` line
with options of its own could hide some and is refused.
"""
import ast
import importlib.util
import os
import re
import sys
from pathlib import Path

import pytest

from codegen.families import observers

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
API = DOCS / "reference" / "python"
MKDOCS = ROOT / "mkdocs.yml"
TEMPLATE = ROOT / "codegen" / "pipeline" / "templates" / "observer.h.in"
FAMILY_SECTIONS = ("## The equations, in our words", "## The design rule", "## When to use it")


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "tools" / "docs_hooks.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("docs_hooks", module)          # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def public_modules():
    """Dotted names of the public modules of codegen/ and models/."""
    out = []
    for path in sorted(list((ROOT / "codegen").rglob("*.py")) + list((ROOT / "models").rglob("*.py"))):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if parts[-1] == "__main__" or any(p.startswith("_") for p in parts) or "__pycache__" in parts:
            continue
        out.append(".".join(parts))
    return out


def public_members(module):
    """Top-level functions and classes ``module`` defines whose names do not start with "_"."""
    path = ROOT / Path(*module.split("."))
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
            and not n.name.startswith("_")]


def api_directives():
    """module -> (page, options text) of every ``::: module`` line of the Python API pages."""
    out = {}
    for page in sorted(API.glob("*.md")):
        lines = page.read_text(encoding="utf-8").splitlines()
        for i, line in enumerate(lines):
            m = re.match(r":::\s+([\w.]+)\s*$", line)
            if m:
                following = lines[i + 1] if i + 1 < len(lines) else ""
                out[m.group(1)] = (page.name, following if following.startswith(" ") else "")
    return out


def test_every_public_function_is_on_an_api_page():
    directives = api_directives()
    missing = [m for m in public_modules() if m not in directives]
    assert not missing, (f"public modules on no page of docs/reference/python/ (add '::: <module>' "
                         f"to the page of its folder): {missing}")
    with_options = [f"{m} ({page})" for m, (page, opts) in directives.items() if opts]
    assert not with_options, f"':::' lines with options of their own (may hide members): {with_options}"
    stale = [m for m in directives if m not in public_modules()]
    assert not stale, f"API pages name modules that are not public modules: {stale}"
    # the members themselves: rendered because their module is, and not filtered out
    config = MKDOCS.read_text(encoding="utf-8")
    assert 'filters: ["!^_"]' in config and "show_if_no_docstring: true" in config
    assert sum(len(public_members(m)) for m in directives) > 300     # the scan is not dead


def test_the_api_pages_and_family_pages_are_in_the_navigation():
    nav = MKDOCS.read_text(encoding="utf-8")
    pages = [p.relative_to(DOCS).as_posix() for p in sorted(API.glob("*.md"))]
    pages += [f"observers/{f}.md" for f in observers.FAMILIES] + ["reference/c-api.md", "bibliography.md"]
    pages += [f"tutorials/{p}" for p in ("your-robot.md", "your-microcontroller.md", "your-log.md")]
    missing = [p for p in pages if p not in nav]
    assert not missing, f"pages not in mkdocs.yml's nav: {missing}"


@pytest.mark.parametrize("family", observers.FAMILIES)
def test_every_family_has_a_page(family):
    """docs/observers/<family>.md: the equations, the paper, the design rule, when to use it."""
    page = DOCS / "observers" / f"{family}.md"
    assert page.is_file(), f"{family}: no docs/observers/{family}.md (see docs/observers/reduced_order.md)"
    text = page.read_text(encoding="utf-8")
    for section in FAMILY_SECTIONS:
        assert section in text, f"{page.name}: no section '{section}'"
    assert "**Paper.**" in text and re.search(r"\((?:\.\./)?(?:papers/\w+\.md|bibliography\.md)", text), \
        f"{page.name}: cites no paper page or bibliography entry"
    assert f"(../reference/python/families.md#codegen.families.observers.{family})" in text
    assert f"(./{family}.md)" in (DOCS / "observers" / "index.md").read_text() or \
        f"({family}.md)" in (DOCS / "observers" / "index.md").read_text()


def test_no_family_page_without_a_family():
    pages = {p.stem for p in (DOCS / "observers").glob("*.md")} - {"index"}
    assert pages == set(observers.FAMILIES), sorted(pages ^ set(observers.FAMILIES))


def _template_header():
    """The header template with its placeholders filled by dummies (prefix "obs")."""
    text = TEMPLATE.read_text(encoding="utf-8")
    text = text.replace("{{prefix}}", "obs").replace("{{PREFIX}}", "OBS")
    text = re.sub(r"^\{\{\w+\}\}$", "", text, flags=re.M)       # whole-line blocks (slot macros)
    return re.sub(r"\{\{\w+\}\}", "1", text)


def test_the_c_api_page_names_every_declared_function():
    """Every function the header template declares is a heading (or an "Also:") of the page the
    hook renders, with the comment above it; and the parser keeps every #define with a value."""
    hooks = _hooks()
    header = _template_header()
    declared = re.findall(r"^(?:void|int|long)\s+(obs_\w+)\s*\(", header, flags=re.M)
    assert len(declared) >= 14
    page = hooks.c_api_markdown(header, "obs.h")
    missing = [f for f in declared if f"### `{f}`" not in page and f"`{f}`" not in page]
    assert not missing, f"declared but not on the C API page: {missing}"
    _, blocks = hooks.parse_header(header)
    parsed = [f for b in blocks for f, _ in b.functions]
    assert parsed == declared
    commented = {f for b in blocks if b.comment for f, _ in b.functions}
    assert "obs_step" in commented and "obs_init" in commented and "obs_run_t" in commented
    assert "One sample" in page and "Bumpless" in page
    macros = re.findall(r"^#define[ \t]+(OBS_\w+)[ \t]+\S", header, flags=re.M)
    assert macros and [m for m in macros if f"`{m}`" not in page] == []


def test_the_built_site_has_an_anchor_per_public_member():
    """Run by `make docs` on the site it has just built (``DOCS_SITE=build/site``; skipped
    without, so that an older site left in build/ is never judged): every public module, function
    and class has its mkdocstrings anchor (``id="codegen.core.target.Target"``) on a Python API
    page, and the C API page exists."""
    if not os.environ.get("DOCS_SITE"):
        pytest.skip("no freshly built site named (make docs sets DOCS_SITE)")
    site = ROOT / os.environ["DOCS_SITE"]
    html = "".join(p.read_text(encoding="utf-8") for p in (site / "reference" / "python").glob("*.html"))
    ids = set(re.findall(r'id="([\w.]+)"', html))
    wanted = [m for m in public_modules()] + [f"{m}.{f}" for m in public_modules() for f in public_members(m)]
    missing = [w for w in wanted if w not in ids]
    assert not missing, f"{len(missing)} public names without an anchor on the built API pages: {missing[:20]}"
    assert (site / "reference" / "c-api.html").is_file()
