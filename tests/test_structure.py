"""The project's structure, checked from the source text (ast): layers, cycles, sizes, private names.

These are the rules DESIGN.md states, as tests any reader can repeat:

- no import cycles between kinodyn modules (imports inside functions count too);
- no import from a lower layer to a higher one (the table :data:`LAYERS`; DESIGN.md draws it); a
  capability's interface modules (:data:`INTERFACE`) count as the top layer;
- no module over :data:`MAX_MODULE_LINES` lines;
- no function over :data:`MAX_FUNCTION_LINES` lines, except compiled kernels that say why with a
  ``# long kernel: <reason>`` comment on the line above their decorator;
- no module reads another module's private names: neither ``from kinodyn.x import _name`` nor
  ``obj._name`` where ``_name`` is not defined in the module doing the reading. A private module
  (``kinodyn.io._numparse``) may be imported only from inside its own package.
"""

from __future__ import annotations

import ast
import sys
from functools import cache
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PKG = SRC / "kinodyn"

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80
LONG_KERNEL_MARK = "# long kernel:"

#: layer of each top-level part of kinodyn; a module may import only from its own layer or below.
#: Parts in one layer may not import each other unless :data:`SIDEWAYS` allows it.
LAYERS: dict[str, int] = {
    "errors": 0, "_arrays": 0, "progress": 0, "version": 0,
    "math": 1,
    "skeleton": 2, "roles": 2,
    "motion": 3, "kinematics": 3, "limits": 3,
    "contacts": 4, "phases": 4, "ik": 4, "parallel": 4,
    "io": 5, "clips": 5,
    "data": 6, "plotting": 6,
    "physics": 7, "blend": 7,
    "response": 8, "contact": 8, "crowd": 8,
    "scene": 9,
    "viz": 10,
    "bench": 11, "commands": 11, "registry": 11, "interface": 11,
    "demo": 12, "cli": 12,
    "__init__": 12,
}

#: (importer, imported) pairs of one layer that may depend on each other, one way.
SIDEWAYS: set[tuple[str, str]] = {
    ("skeleton", "roles"), ("motion", "kinematics"), ("clips", "io"), ("io", "clips"),
    ("phases", "contacts"), ("ik", "contacts"),
    ("response", "contact"), ("crowd", "contact"),
    ("bench", "commands"), ("cli", "demo"), ("cli", "registry"), ("demo", "registry"),
    ("bench", "registry"), ("interface", "bench"), ("interface", "commands"), ("interface", "interface"),
}
#: a capability package's interface modules (its command, benchmark, demo part and registration) sit
#: at the top with the CLI: they may use the whole package, the shared CLI options and BenchResult.
INTERFACE = {"bench", "command", "demo", "register"}
#: the package's own __init__ is the public surface: it may import anything below it, and only it.
PUBLIC = "__init__"


def _modules() -> dict[str, Path]:
    mods = {}
    for p in sorted(PKG.rglob("*.py")):
        rel = p.relative_to(SRC).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = p
    return mods


MODULES = _modules()


@cache
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), filename=str(path))


def _is_package(mod: str) -> bool:
    return MODULES[mod].name == "__init__.py"


def _resolve(mod: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = mod.split(".") if _is_package(mod) else mod.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(mod: str) -> list[tuple[str, list[str], int]]:
    """(imported kinodyn module, names taken from it, line) for every import in ``mod``."""
    out = []
    for node in ast.walk(_tree(MODULES[mod])):
        if isinstance(node, ast.Import):
            out += [(a.name, [], node.lineno) for a in node.names if a.name.split(".")[0] == "kinodyn"]
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(mod, node)
            if target.split(".")[0] != "kinodyn":
                continue
            names = [a.name for a in node.names]
            subs = [n for n in names if f"{target}.{n}" in MODULES]
            for n in subs:
                out.append((f"{target}.{n}", [], node.lineno))
            rest = [n for n in names if n not in subs]
            if rest or not subs:
                out.append((target, rest, node.lineno))
    return [(t if t in MODULES else _nearest(t), names, line) for t, names, line in out]


def _nearest(name: str) -> str:
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name


def _part(mod: str) -> str:
    parts = mod.split(".")
    if len(parts) > 2 and parts[-1] in INTERFACE:
        return "interface"
    return PUBLIC if len(parts) == 1 else parts[1]


def _graph() -> dict[str, set[str]]:
    return {m: {t for t, _, _ in _imports(m) if t != m} for m in MODULES}


def test_every_part_has_a_layer():
    unknown = sorted({_part(m) for m in MODULES} - set(LAYERS))
    assert not unknown, f"parts of kinodyn missing from LAYERS (add them, and to DESIGN.md): {unknown}"


def test_no_import_cycles():
    graph = _graph()
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components, iterative over each node's edges
        work = [(v, iter(sorted(graph[v])))]
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        while work:
            node, edges = work[-1]
            for w in edges:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[node] = min(low[node], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    if len(comp) > 1:
                        cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_no_import_from_a_higher_layer():
    bad = []
    for mod in MODULES:
        src = _part(mod)
        for target, _, line in _imports(mod):
            dst = _part(target)
            if (src == dst and src != "interface") or src == PUBLIC:
                continue
            if dst == PUBLIC:
                bad.append(f"{mod}:{line} imports the package surface 'kinodyn' (import the module instead)")
            elif LAYERS[dst] > LAYERS[src] or (LAYERS[dst] == LAYERS[src] and (src, dst) not in SIDEWAYS):
                bad.append(f"{mod}:{line} ({src}, layer {LAYERS[src]}) imports {target} "
                           f"({dst}, layer {LAYERS[dst]})")
    assert not bad, "imports against the layers:\n" + "\n".join(bad)


def test_modules_are_small():
    big = {m: n for m, p in MODULES.items() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not big, f"modules over {MAX_MODULE_LINES} lines (split them along their seams): {big}"


def _is_long_kernel(node, lines: list[str]) -> bool:
    first = min([d.lineno for d in node.decorator_list] + [node.lineno])
    return first >= 2 and lines[first - 2].strip().startswith(LONG_KERNEL_MARK)


def test_functions_are_short():
    long = []
    for mod, path in MODULES.items():
        lines = path.read_text().splitlines()
        for node in ast.walk(_tree(path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES and not _is_long_kernel(node, lines):
                    long.append(f"{mod}.{node.name} ({n} lines, line {node.lineno})")
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(long)


def _defined_names(tree: ast.Module) -> set[str]:
    """Every name a module defines: functions, classes, assignments, attributes it sets, arguments."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, (ast.Store, ast.Del)):
            names.add(node.attr)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.alias):
            names.add(node.asname or node.name.split(".")[0])
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.startswith("_"):
            names.add(node.value)  # __slots__ entries and setattr/getattr names
    return names


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def test_no_private_names_across_modules():
    bad = []
    for mod, path in MODULES.items():
        tree = _tree(path)
        for target, names, line in _imports(mod):
            if target == mod:
                continue
            taken = [n for n in names if _private(n)]
            if taken:
                bad.append(f"{mod}:{line} imports private {taken} from {target}")
            private_mod = [p for p in target.split(".") if _private(p)]
            if private_mod:
                owner = target.rsplit(".", 1)[0]
                if not (mod == owner or mod.startswith(owner + ".")):
                    bad.append(f"{mod}:{line} imports the private module {target} from outside {owner}")
        own = _defined_names(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and _private(node.attr) and node.attr not in own:
                bad.append(f"{mod}:{node.lineno} reads {ast.unparse(node)} (defined elsewhere)")
    assert not bad, "private names used across modules:\n" + "\n".join(bad)


@pytest.mark.parametrize("rule", ["cycle", "layer", "private"])
def test_the_checks_catch_what_they_name(rule, tmp_path, monkeypatch):
    """Each structural check fails on a tiny tree that breaks its rule (so none of them is vacuous)."""
    pkg = tmp_path / "kinodyn"
    (pkg / "math").mkdir(parents=True)
    for f in ("__init__.py", "math/__init__.py"):
        (pkg / f).write_text("")
    if rule == "cycle":
        (pkg / "errors.py").write_text("from kinodyn import progress\n")
        (pkg / "progress.py").write_text("from kinodyn import errors\n")
        (pkg / "_arrays.py").write_text("")
        check = test_no_import_cycles
    elif rule == "layer":
        (pkg / "errors.py").write_text("from kinodyn.math import quat\n")
        (pkg / "math/quat.py").write_text("")
        check = test_no_import_from_a_higher_layer
    else:
        (pkg / "errors.py").write_text("def _hidden():\n    pass\n")
        (pkg / "progress.py").write_text("from kinodyn.errors import _hidden\n")
        check = test_no_private_names_across_modules
    here = sys.modules[__name__]
    monkeypatch.setattr(here, "SRC", tmp_path)
    monkeypatch.setattr(here, "PKG", pkg)
    monkeypatch.setattr(here, "MODULES", _modules())
    with pytest.raises(AssertionError):
        check()


def test_design_md_draws_these_layers():
    """DESIGN.md's layer diagram lists every part of :data:`LAYERS` at its layer, and nothing else."""
    text = (SRC.parent / "DESIGN.md").read_text()
    block = text.split("## Layers", 1)[1].split("```", 2)[1]
    drawn, layer = {}, None
    for line in block.splitlines()[2:]:  # after the header line
        if line[:6].strip():
            layer = int(line[:6])
        for part in line[7:23].split(","):
            if part.strip():
                drawn[part.strip().rstrip("/")] = layer
    assert drawn == LAYERS


#: test files about the project as a whole rather than one module.
PROJECT_TESTS = {"cold_start", "readme", "setup_system", "structure"}


def test_tests_mirror_the_package():
    """``tests/test_<package>_<module>.py`` (or ``test_<package>.py``) names the module it tests, so a
    module's tests are found by its name."""
    tests = Path(__file__).resolve().parent
    names = {m.removeprefix("kinodyn.").replace(".", "_") for m in MODULES if m != "kinodyn"}
    stray = [p.name for p in sorted(tests.glob("test_*.py"))
             if (n := p.stem[len("test_"):]) not in PROJECT_TESTS
             and not any(n == m or n.startswith(m + "_") for m in names)]
    assert not stray, f"test files that name no module of kinodyn (rename them after the module): {stray}"
