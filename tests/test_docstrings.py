"""Every public callable of ``models`` and ``codegen`` is documented, in the
manner of python-control's docstring test: a public function or class defined in a module (not
imported into it) has a docstring, and a public function or method with parameters documents each
of them, in a numpy-style "Parameters" section or, for small helpers, by naming it in the text."""
import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _public_callables():
    for pkg in ("models", "codegen"):
        for f in sorted((ROOT / pkg).rglob("*.py")):
            if any(part.startswith("_") and part != "__init__.py" for part in f.relative_to(ROOT).parts):
                continue            # private modules (_ii_common.py, ...) are not public API
            tree = ast.parse(f.read_text())
            for node in tree.body:
                if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith("_"):
                    yield f, node, None
                    if isinstance(node, ast.ClassDef):
                        for m in node.body:
                            if isinstance(m, ast.FunctionDef) and not m.name.startswith("_"):
                                yield f, m, node


def _parameters(fn):
    args = [a.arg for a in fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs]
    if fn.args.vararg:
        args.append(fn.args.vararg.arg)
    if fn.args.kwarg:
        args.append(fn.args.kwarg.arg)
    return [a for a in args if a not in ("self", "cls")]


def _documents(doc, name):
    return re.search(rf"(?<![\w.]){re.escape(name)}(?!\w)", doc) is not None


def test_public_callables_have_docstrings():
    missing = [f"{f.relative_to(ROOT)}:{n.lineno} {(c.name + '.') if c else ''}{n.name}"
               for f, n, c in _public_callables() if not ast.get_docstring(n)
               and not (c is not None and any(isinstance(d, ast.Name) and d.id == "property"
                                              for d in n.decorator_list))]
    assert not missing, f"{len(missing)} public callables without a docstring:\n" + "\n".join(missing)


def test_parameters_are_documented():
    bad = []
    for f, n, c in _public_callables():
        if not isinstance(n, ast.FunctionDef):
            continue
        doc = ast.get_docstring(n) or ""
        if not doc:
            continue                # reported by the test above
        undocumented = [a for a in _parameters(n) if not _documents(doc, a)]
        if undocumented:
            bad.append(f"{f.relative_to(ROOT)}:{n.lineno} {(c.name + '.') if c else ''}{n.name}: "
                       + ", ".join(undocumented))
    assert not bad, f"{len(bad)} public functions with undocumented parameters:\n" + "\n".join(bad)
