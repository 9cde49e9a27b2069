"""The import graph points one way (issue 10; DESIGN §1).

Every module of ``models`` and ``codegen`` is parsed (imports inside functions count too) and
each import must point down the layers, with no cycle anywhere:

    values (codegen.target, codegen.options, codegen.cache: stdlib-only paths and JSON memo)
      -> models -> codegen.symbolic -> codegen.design -> observers, controllers, spec, with the
         discrete step and its stability check (discretize, stability, sampling: a family's
         default gains are kept inside the stable region of the default discretisation)
      -> pipeline (discretize, emit, build, runtime, harness, trajectory, codegen itself)
      -> check  <-  reference (which imports only the values)
      -> sim, bench, compare, sweep, embedded (Cortex-M runs checked against the host), jobs, cli
      on top.
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("models", "codegen")

# (prefix, rank): the longest matching prefix decides a module's layer
LAYERS = [
    ("codegen.target", 0), ("codegen.options", 0), ("codegen.cache", 0),
    ("models", 1),
    ("codegen.symbolic", 2),
    ("codegen.design", 3),
    ("codegen.spec", 4), ("codegen.observers", 4), ("codegen.controllers", 4),
    ("codegen.discretize", 4), ("codegen.stability", 4), ("codegen.sampling", 4),
    ("codegen", 5),                     # the pipeline: discretize, emit, build, runtime, harness, ...
    ("codegen.reference", 5),
    ("codegen.check", 6),
    ("codegen.sim", 7), ("codegen.bench", 7), ("codegen.compare", 7), ("codegen.embedded", 7),
    ("codegen.sweep", 7), ("codegen.cli", 7),
    ("codegen.jobs", 7),                # targets through design, emit, compile, run or check
    ("codegen.__main__", 7),
]
REFERENCE_MAY_IMPORT = ("codegen.target", "codegen.options", "codegen.reference")


def _modules():
    mods = {}
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = f
    return mods


def _resolve(module, is_package, node, mods):
    """Modules of ours imported by an Import/ImportFrom node of ``module``."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name in mods]
    if node.level:
        base = module.split(".")
        base = base if is_package else base[:-1]
        base = base[:len(base) - (node.level - 1)]
        prefix = ".".join(base + ([node.module] if node.module else []))
    else:
        prefix = node.module
    # "from pkg import name" imports the module pkg.name when there is one, else pkg
    out = [f"{prefix}.{a.name}" if f"{prefix}.{a.name}" in mods else prefix for a in node.names]
    return [m for m in out if m in mods]


def _graph():
    mods = _modules()
    edges = {}
    for name, f in mods.items():
        tree = ast.parse(f.read_text(), filename=str(f))
        out = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                out.update(t for t in _resolve(name, f.name == "__init__.py", node, mods) if t != name)
        edges[name] = out
    return edges


def rank(module):
    best = max((p for p, _ in LAYERS if module == p or module.startswith(p + ".")), key=len)
    return dict(LAYERS)[best]


def test_every_import_points_down():
    bad = []
    for src, targets in _graph().items():
        for dst in targets:
            if rank(dst) > rank(src):
                bad.append(f"{src} (layer {rank(src)}) imports {dst} (layer {rank(dst)})")
            if src.startswith("codegen.reference") and not dst.startswith(REFERENCE_MAY_IMPORT):
                bad.append(f"{src} (the independent reference) imports {dst}")
    assert not bad, "imports pointing up the layers:\n" + "\n".join(sorted(bad))


def test_no_import_cycles():
    graph = _graph()
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == 1:
                cycles.append(" -> ".join(stack[stack.index(t):] + [t]))
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


@pytest.mark.parametrize("module,expected", [("codegen.reference.reduced_order", 5),
                                             ("codegen.observers.ii_speed", 4),
                                             ("models.urdf", 1), ("codegen.emit", 5),
                                             ("codegen.sim.engine", 7), ("codegen.target", 0)])
def test_layer_table(module, expected):
    assert rank(module) == expected
