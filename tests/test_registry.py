"""Registration: each package's register.py, read without importing the package (kinodyn.registry)."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from kinodyn import bench, registry
from kinodyn.errors import FileFormatError

SRC = Path(__file__).resolve().parents[1] / "src"


def test_packages_register_their_commands_benchmarks_and_demo_parts():
    """The landed capabilities' parts are found (a new capability adds its own without editing this)."""
    assert {"blend": "kinodyn.blend.command", "body": "kinodyn.physics.command",
            "view": "kinodyn.commands.view", "render": "kinodyn.commands.render"}.items() <= registry.commands().items()
    assert {"blend": "kinodyn.blend.bench", "io": "kinodyn.io.bench", "physics": "kinodyn.physics.bench",
            "viz": "kinodyn.viz.bench"}.items() <= registry.benchmarks().items()
    parts = list(registry.demo_parts())
    landed = [p for p in parts if p in ("clips", "physics", "blend", "viewer")]
    assert landed == ["clips", "physics", "blend", "viewer"] and parts[-1] == "viewer"
    assert bench.names() == list(registry.benchmarks())


def test_registered_modules_have_the_interface():
    for modname in registry.commands().values():
        mod = importlib.import_module(modname)
        assert isinstance(mod.HELP, str) and callable(mod.add_arguments) and callable(mod.run), modname
    for modname in registry.benchmarks().values():
        assert callable(importlib.import_module(modname).run), modname
    for modname in registry.demo_parts().values():
        assert callable(importlib.import_module(modname).demo), modname


def test_help_text_read_from_source_is_the_modules_own():
    for modname in registry.commands().values():
        mod = importlib.import_module(modname)
        text = registry.module_constants(modname, ("HELP", "DESCRIPTION"))
        assert text["HELP"] == mod.HELP, modname
        assert text.get("DESCRIPTION", mod.HELP) == getattr(mod, "DESCRIPTION", mod.HELP), modname
    assert registry.module_file("kinodyn.no_such_module") is None
    assert registry.module_constants("kinodyn.no_such_module", ("HELP",)) is None


def _imported_after(code: str) -> set[str]:
    probe = f"import sys, json\n{code}\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"})
    return set(json.loads(out.stdout.splitlines()[-1]))


def test_help_imports_no_capability_and_a_command_only_its_own():
    heavy = {"kinodyn.physics", "kinodyn.blend", "kinodyn.viz", "kinodyn.commands.view", "mujoco", "matplotlib"}
    mods = _imported_after("from kinodyn.cli import build_parser\nbuild_parser(['--help']).format_help()")
    assert not heavy & mods
    mods = _imported_after("from kinodyn.cli import build_parser\nbuild_parser(['body', 'x.bvh'])")
    assert "kinodyn.physics.command" in mods and "kinodyn.blend" not in mods and "kinodyn.commands.view" not in mods


def _tree(tmp_path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = tmp_path / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return tmp_path


def test_discovery_reads_literals_and_orders_demo_parts(tmp_path):
    root = _tree(tmp_path, {
        "b/register.py": '"""doc"""\nCOMMANDS = {"zeta": "kinodyn.b.command"}\n'
                         'DEMO_PARTS = {"late": ("kinodyn.b.demo", 50), "early": ("kinodyn.b.demo2", 5)}\n',
        "a/register.py": 'from __future__ import annotations\nBENCHMARKS: dict = {"a": "kinodyn.a.bench"}\n'
                         'COMMANDS = {"alpha": "kinodyn.a.command"}\nDEMO_PARTS = {"mid": ("kinodyn.a.demo", 50)}\n',
        "c/not_registered.py": "COMMANDS = {'x': 'kinodyn.c.x'}\n",
    })
    regs = registry.registrations(root)
    assert [r.package for r in regs] == ["a", "b"]
    assert list(registry.commands(root)) == ["alpha", "zeta"]
    assert registry.benchmarks(root) == {"a": "kinodyn.a.bench"}
    assert list(registry.demo_parts(root)) == ["early", "late", "mid"]


@pytest.mark.parametrize("text, found", [
    ("COMMANDS = {'x': 'kinodyn.p.command'\n", "not valid Python"),
    ("import os\nCOMMANDS = {}\n", "only assignments"),
    ("COMMAND = {'x': 'kinodyn.p.command'}\n", "unknown name 'COMMAND'"),
    ("COMMANDS = dict(x='kinodyn.p.command')\n", "must be a literal dict"),
    ("COMMANDS = ['kinodyn.p.command']\n", "must be a dict"),
    ("COMMANDS = {'x': 'numpy.linalg'}\n", "must name a kinodyn module"),
    ("COMMANDS = {'Bad Name': 'kinodyn.p.command'}\n", "lower-case words"),
    ("DEMO_PARTS = {'x': 'kinodyn.p.demo'}\n", "(module, order) pair"),
    ("DEMO_PARTS = {'x': ('kinodyn.p.demo', 1.5)}\n", "(module, order) pair"),
])
def test_a_malformed_registration_names_the_file_and_the_problem(tmp_path, text, found):
    root = _tree(tmp_path, {"p/register.py": text})
    with pytest.raises(FileFormatError) as e:
        registry.registrations(root)
    assert found in str(e.value) and str(root / "p" / "register.py") in str(e.value)


def test_two_packages_registering_one_name_is_an_error(tmp_path):
    root = _tree(tmp_path, {"a/register.py": "BENCHMARKS = {'x': 'kinodyn.a.bench'}\n",
                            "b/register.py": "BENCHMARKS = {'x': 'kinodyn.b.bench'}\n"})
    with pytest.raises(FileFormatError, match="'x' is registered by .*a/register.py too"):
        registry.registrations(root)


def test_load_skips_a_missing_capability_but_not_a_missing_dependency(tmp_path, monkeypatch):
    _tree(tmp_path, {"probe_pkg/__init__.py": "", "probe_pkg/needs.py": "import no_such_dependency_xyz\n"})
    monkeypatch.syspath_prepend(str(tmp_path))
    assert registry.load("kinodyn.registry") is registry
    assert registry.load("probe_pkg.not_built") is None
    with pytest.raises(ModuleNotFoundError, match="no_such_dependency_xyz"):
        registry.load("probe_pkg.needs")
