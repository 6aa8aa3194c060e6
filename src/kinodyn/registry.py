"""What each package adds to the ``kinodyn`` command, the benchmarks and the demo, read without importing it.

A package registers its parts in ``kinodyn/<pkg>/register.py``, a module of plain literal dicts::

    COMMANDS = {"crowd": "kinodyn.crowd.command"}       # CLI name -> module with HELP, DESCRIPTION,
                                                        #   add_arguments(parser), run(args) -> int
    BENCHMARKS = {"crowd": "kinodyn.crowd.bench"}       # name -> module with run(quick, progress)
    DEMO_PARTS = {"crowd": ("kinodyn.crowd.demo", 60)}  # name -> (module with demo(out), order)

Every name is optional. The files are parsed (:func:`ast.literal_eval` of each assignment), never
imported, so ``kinodyn --help`` does not load numpy, MuJoCo or matplotlib, and a new capability touches
only its own folder. A malformed file (a syntax error, a value that is not a literal, an unknown name,
a module outside kinodyn, a name two packages both register) raises
:class:`~kinodyn.errors.FileFormatError` naming the file, the line or entry and what was expected.

Order: commands and benchmarks follow the packages' names, then the order in each file; demo parts
run by their ``order`` number (ties by part name).
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from kinodyn.errors import FileFormatError

__all__ = [
    "REGISTER_FILE",
    "Registration",
    "benchmarks",
    "commands",
    "demo_parts",
    "load",
    "module_constants",
    "module_file",
    "read_registration",
    "registrations",
]

#: the file name a package registers its parts in.
REGISTER_FILE = "register.py"
#: the names a registration file may assign.
KINDS = ("COMMANDS", "BENCHMARKS", "DEMO_PARTS")

_NAME = re.compile(r"^[a-z][a-z0-9_-]*$")
_MODULE = re.compile(r"^kinodyn(\.[A-Za-z_][A-Za-z0-9_]*)+$")


@dataclass(frozen=True)
class Registration:
    """The parts one package registers.

    Attributes:
        package: the package's folder name (``"physics"``).
        path: its ``register.py``.
        commands: CLI name -> module path.
        benchmarks: benchmark name -> module path.
        demo_parts: part name -> ``(module path, order)``.
    """

    package: str
    path: Path
    commands: dict[str, str] = field(default_factory=dict)
    benchmarks: dict[str, str] = field(default_factory=dict)
    demo_parts: dict[str, tuple[str, int]] = field(default_factory=dict)


def _fail(path: Path, what: str, line: int | None = None) -> FileFormatError:
    return FileFormatError(what, path, line)


def _literal_assignments(path: Path) -> dict[str, object]:
    """``{NAME: value}`` of the module's top-level assignments, each value a Python literal."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    except SyntaxError as e:
        raise _fail(path, f"not valid Python ({e.msg})", e.lineno) from None
    out: dict[str, object] = {}
    for node in tree.body:
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            continue  # the docstring
        if isinstance(node, (ast.Import, ast.ImportFrom)) and all(a.name == "annotations" for a in node.names):
            continue  # from __future__ import annotations
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            name, value = node.targets[0].id, node.value
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
            name, value = node.target.id, node.value
        else:
            raise _fail(path, f"only assignments of literal dicts to {', '.join(KINDS)} are allowed, "
                              f"found {type(node).__name__}", node.lineno)
        if name not in KINDS:
            raise _fail(path, f"unknown name {name!r} (expected one of {', '.join(KINDS)})", node.lineno)
        try:
            out[name] = ast.literal_eval(value)
        except ValueError:
            raise _fail(path, f"{name} must be a literal dict, found {ast.unparse(value)!r}",
                        node.lineno) from None
    return out


def _entries(path: Path, kind: str, table: object) -> dict:
    if not isinstance(table, dict):
        raise _fail(path, f"{kind} must be a dict, found {type(table).__name__}")
    for name, value in table.items():
        if not (isinstance(name, str) and _NAME.match(name)):
            raise _fail(path, f"{kind}: names must be lower-case words, found {name!r}")
        module = value[0] if kind == "DEMO_PARTS" and isinstance(value, tuple) else value
        if kind == "DEMO_PARTS" and not (isinstance(value, tuple) and len(value) == 2
                                         and isinstance(value[1], int) and not isinstance(value[1], bool)):
            raise _fail(path, f"DEMO_PARTS[{name!r}] must be a (module, order) pair with an integer order, "
                              f"found {value!r}")
        if not (isinstance(module, str) and _MODULE.match(module)):
            raise _fail(path, f"{kind}[{name!r}] must name a kinodyn module ('kinodyn.pkg.module'), "
                              f"found {module!r}")
    return dict(table)


def read_registration(path: Path, package: str | None = None) -> Registration:
    """Parse one ``register.py`` (without importing it).

    Raises:
        FileFormatError: the file is not plain literal dicts of the expected shape.
    """
    path = Path(path)
    found = _literal_assignments(path)
    tables = {kind: _entries(path, kind, found.get(kind, {})) for kind in KINDS}
    return Registration(package or path.parent.name, path, tables["COMMANDS"], tables["BENCHMARKS"],
                        tables["DEMO_PARTS"])


def _discover(root: Path) -> tuple[Registration, ...]:
    regs = tuple(read_registration(p) for p in sorted(root.glob(f"*/{REGISTER_FILE}")))
    for kind, attr in zip(KINDS, ("commands", "benchmarks", "demo_parts")):
        owner: dict[str, Path] = {}
        for reg in regs:
            for name in getattr(reg, attr):
                if name in owner:
                    raise _fail(reg.path, f"{kind}: {name!r} is registered by {owner[name]} too")
                owner[name] = reg.path
    return regs


@cache
def _cached(root: Path) -> tuple[Registration, ...]:
    return _discover(root)


def registrations(root: Path | None = None) -> tuple[Registration, ...]:
    """Every package's registration under ``root`` (default: the installed kinodyn), by package name."""
    if root is None:
        return _cached(Path(__file__).resolve().parent)
    return _discover(Path(root))


def commands(root: Path | None = None) -> dict[str, str]:
    """CLI name -> module of every registered capability command."""
    return {k: v for reg in registrations(root) for k, v in reg.commands.items()}


def benchmarks(root: Path | None = None) -> dict[str, str]:
    """Benchmark name -> module of every registered benchmark."""
    return {k: v for reg in registrations(root) for k, v in reg.benchmarks.items()}


def demo_parts(root: Path | None = None) -> dict[str, str]:
    """Demo part name -> module, in the order the parts run."""
    parts = [(order, name, module) for reg in registrations(root)
             for name, (module, order) in reg.demo_parts.items()]
    return {name: module for _, name, module in sorted(parts)}


def module_file(module: str, root: Path | None = None) -> Path | None:
    """The source file of kinodyn module ``module`` (``kinodyn.physics.command``), found without importing
    anything; ``None`` when there is none."""
    root = Path(__file__).resolve().parent if root is None else Path(root)
    parts = module.split(".")[1:]
    for p in (root.joinpath(*parts).with_suffix(".py"), root.joinpath(*parts, "__init__.py")):
        if parts and p.is_file():
            return p
    return None


def module_constants(module: str, names, root: Path | None = None) -> dict[str, object] | None:
    """Top-level literal constants ``names`` of a module read from its source (those assigned a literal:
    a command's ``HELP`` and ``DESCRIPTION``); ``None`` when the module has no source file."""
    path = module_file(module, root)
    if path is None:
        return None
    out = {}
    for node in ast.parse(path.read_text(encoding="utf-8"), filename=str(path)).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and node.targets[0].id in names:
            try:
                out[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                pass  # not a literal: the caller imports the module instead
    return out


def load(module: str):
    """Import a registered module; ``None`` when the module itself is not part of this build (a
    capability not installed yet). A missing dependency inside it still raises ModuleNotFoundError."""
    import importlib

    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as e:
        if e.name and module.startswith(e.name):
            return None
        raise
