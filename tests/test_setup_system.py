"""scripts/setup-system.sh: installs the system packages as root, otherwise says so in one line and
changes nothing; a package apt cannot install is reported and the others are still installed.

The script runs against stub ``apt-get``, ``dpkg-query`` and ``id`` commands that record what they
are asked, so nothing is installed on the machine running the tests.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "setup-system.sh"
WANTED = {"chromium", "chromium-driver", "libosmesa6", "libegl1", "blender", "python3-numpy"}


def _stubs(tmp_path: Path, uid: int, installed: set[str], broken: set[str] = frozenset()) -> dict:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    log = tmp_path / "apt.log"
    stubs = {
        "id": f"#!/bin/sh\necho {uid}\n",
        "dpkg-query": "#!/bin/sh\nfor p; do :; done\ncase \" {} \" in *\" $p \"*) printf 'install ok installed';; "
                      "*) exit 1;; esac\n".format(" ".join(sorted(installed))),
        "apt-get": "#!/bin/sh\necho \"$@\" >> {log}\nfor p; do case \" {broken} \" in *\" $p \"*) exit 100;; esac; "
                   "done\nexit 0\n".format(log=log, broken=" ".join(sorted(broken))),
        "node": "#!/bin/sh\nexit 0\n", "npm": "#!/bin/sh\nexit 0\n",
    }
    for name, text in stubs.items():
        (bin_dir / name).write_text(text)
        (bin_dir / name).chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k != "KINODYN_SKIP_SYSTEM"}
    env["PATH"] = f"{bin_dir}:/usr/bin:/bin"
    return {"env": env, "log": log}


def _run(stub) -> subprocess.CompletedProcess:
    return subprocess.run(["sh", str(SCRIPT)], env=stub["env"], capture_output=True, text=True, timeout=60,
                          check=False)


def _apt_calls(stub) -> list[list[str]]:
    return [ln.split() for ln in stub["log"].read_text().splitlines()] if stub["log"].exists() else []


def test_not_root_is_one_line_and_changes_nothing(tmp_path):
    stub = _stubs(tmp_path, uid=1000, installed=set())
    r = _run(stub)
    assert r.returncode == 0 and r.stderr == ""
    assert r.stdout.count("\n") == 1 and "not root" in r.stdout and "blender" in r.stdout
    assert _apt_calls(stub) == []


def test_root_installs_what_is_missing_only(tmp_path):
    stub = _stubs(tmp_path, uid=0, installed=WANTED - {"blender", "libegl1"})
    r = _run(stub)
    assert r.returncode == 0
    calls = _apt_calls(stub)
    installs = [c for c in calls if "install" in c]
    assert len(installs) == 1
    assert {"blender", "libegl1"} <= set(installs[0]) and not (WANTED - {"blender", "libegl1"}) & set(installs[0])
    assert ["update", "-qq"] in calls


def test_everything_installed_does_nothing(tmp_path):
    stub = _stubs(tmp_path, uid=0, installed=WANTED)
    r = _run(stub)
    assert r.returncode == 0 and r.stdout == "" and _apt_calls(stub) == []


def test_a_package_apt_cannot_install_is_reported_and_the_rest_installed(tmp_path):
    stub = _stubs(tmp_path, uid=0, installed=set(), broken={"blender"})
    r = _run(stub)
    assert r.returncode == 0
    assert "could not install: blender" in r.stdout
    singles = [c[-1] for c in _apt_calls(stub) if "install" in c and len(set(c) & WANTED) == 1]
    assert set(singles) == WANTED  # each tried on its own after the batch failed


@pytest.mark.parametrize("how", ["skip", "no-apt"])
def test_skips_in_one_line(tmp_path, how):
    stub = _stubs(tmp_path, uid=0, installed=set())
    if how == "skip":
        stub["env"]["KINODYN_SKIP_SYSTEM"] = "1"
    else:
        (tmp_path / "bin" / "apt-get").unlink()
        stub["env"]["PATH"] = f"{tmp_path / 'bin'}"
    r = subprocess.run(["/bin/sh", str(SCRIPT)], env=stub["env"], capture_output=True, text=True, timeout=60,
                       check=False)
    assert r.returncode == 0 and r.stdout.count("\n") == 1 and r.stdout.startswith("setup-system: ")
    assert _apt_calls(stub) == []
