"""The import graph points one way: one layer per folder, no circle.

Every module of ``models`` and ``codegen`` is parsed (imports inside functions count too) and
each import must point down this table, or stay in its own folder:

    core        values: Target, options, ObserverSpec, symbolic helpers, recordings, cache
    models      what a robot is (CasADi expressions from closed forms, DH tables, URDF)
    discrete    a spec's discrete step, its stability check, the working points they draw
    reference   numpy + pinocchio, independent of all the above but core's plain values
    families    observers, controllers, gain designs (which use the stability check)
    pipeline    targets file -> design -> emit -> compile -> load, as one sequence (stages)
    verify      cross-checks, sanitizers, C programs, Cortex-M runs
    logs        a recorded log as a measurement: recording, its clock, its noise, smoothing, the
                offline reference, identification (a log -> a model), tuning (a log -> gains)
    evaluate    baselines, metrics, plants, scenarios, compare, sweeps, benchmarks
    top         cli, jobs, __main__ and the package itself (imported by nothing of ours)
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("models", "codegen")

# (folder, rank): a module's rank is its folder's; each folder is one layer
LAYERS = [
    ("codegen.core", 0),
    ("models", 1),
    ("codegen.discrete", 2), ("codegen.reference", 2),
    ("codegen.families", 3),
    ("codegen.pipeline", 4),
    ("codegen.verify", 5),
    ("codegen.logs", 6),
    ("codegen.evaluate", 7),
    ("codegen.jobs", 8), ("codegen.cli", 8), ("codegen.__main__", 8),
]
TOP = 8                                  # the package ``codegen`` itself: a lazy facade for users
REFERENCE_MAY_IMPORT = ("codegen.core.target", "codegen.core.options", "codegen.core.arrays",
                        "codegen.reference")


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
    """The layer of ``module``; KeyError for a module in no folder of the table."""
    if module == "codegen":
        return TOP
    for prefix, r in LAYERS:
        if module == prefix or module.startswith(prefix + "."):
            return r
    raise KeyError(f"{module} is in no layer of tests/test_layers.py: put it in a folder of the table")


def test_every_module_has_a_layer():
    """No module sits at codegen's top level but the package, __main__, cli and jobs."""
    loose = []
    for m in _modules():
        try:
            rank(m)
        except KeyError as e:
            loose.append(str(e))
    assert not loose, "\n".join(loose)


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


@pytest.mark.parametrize("module,expected", [("codegen.reference.families.reduced_order", 2),
                                             ("codegen.families.observers.ii_speed", 3),
                                             ("models.urdf", 1), ("codegen.pipeline.emit", 4),
                                             ("codegen.evaluate.sim.engine", 7), ("codegen.logs.identify", 6), ("codegen.core.target", 0)])
def test_layer_table(module, expected):
    assert rank(module) == expected
