"""Small files never import numba: the numpy paths for parsing, Euler angles and forward kinematics give
the compiled kernels' results (to 1e-12), and ``import kinodyn`` / ``kinodyn info`` stay light.

The speed itself is measured by ``kinodyn bench io`` (``cold_info_s``), not here.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from conftest import mocap_files
from kinodyn import kinematics
from kinodyn.data import library
from kinodyn.io import _numparse
from kinodyn.io.bvh import read_bvh
from kinodyn.math import quat

_TOL = 1e-12
_HEAVY = ("numba", "scipy", "yaml", "matplotlib", "mujoco", "numpy.ma")


def _random_motion_arrays(rng, f=40, j=12):
    parents = np.array([-1] + [int(rng.integers(0, k)) for k in range(1, j)])
    offsets = rng.normal(size=(j, 3))
    q = quat.normalize(rng.normal(size=(f, j, 4)))
    return rng.normal(size=(f, 3)), q, offsets, parents, rng.normal(size=(f, j, 3))


@pytest.mark.parametrize("animated", [False, True])
def test_numpy_fk_equals_the_compiled_kernel(rng, monkeypatch, animated):
    rp, q, off, par, tr = _random_motion_arrays(rng)
    tr = tr if animated else None
    small = kinematics.fk_arrays(rp, q, off, par, tr)
    monkeypatch.setattr(kinematics, "SMALL_JOINT_FRAMES", -1)
    big = kinematics.fk_arrays(rp, q, off, par, tr)
    for a, b in zip(small, big):
        np.testing.assert_allclose(a, b, rtol=0, atol=_TOL)


def test_numpy_fk_equals_the_quaternion_reference(rng):
    rp, q, off, par, _ = _random_motion_arrays(rng)
    gr, gp = kinematics.fk_arrays(rp, q, off, par)
    lp = np.broadcast_to(off, q.shape[:2] + (3,)).copy()
    lp[:, 0] = rp
    ref_r, ref_p = quat.fk(q, lp, par)
    np.testing.assert_allclose(gp, ref_p, atol=_TOL)
    np.testing.assert_allclose(gr, ref_r, atol=_TOL)  # the same products: the same sign too


_TEXTS = {
    "plain": b"1 2 3\n4 5 6\n",
    "signs-points-exponents": b"+1 -2.5 .5\n5. -0.0 1e3\n1.25E-2 -7e+1 0\n",
    "crlf-tabs-blank-lines": b"1\t2 3\r\n\r\n\n4 5 6 \r\n",
    "no-final-newline": b"1 2 3\n4 5 6",
    "many-digits": b"0.12345678901234567890123 1234567890123456789012 3\n",
}


@pytest.mark.parametrize("name", sorted(_TEXTS))
def test_numpy_parse_equals_the_compiled_parser(name, monkeypatch):
    text = _TEXTS[name]
    small = _numparse.parse(text, 3, 10, 1e9)
    monkeypatch.setattr(_numparse, "SMALL_TEXT_BYTES", -1)
    big = _numparse.parse(text, 3, 10, 1e9)
    assert small[1:] == big[1:]  # status, rows, line, position, count
    np.testing.assert_allclose(small[0], big[0], rtol=_TOL, atol=0)


@pytest.mark.parametrize("text", [b"1 2 nan\n", b"1 2\n", b"1 2 3 4\n", b"1 2,5 3\n", b"1 2 3\n" * 11,
                                  b"1 2 1e10\n", b"1 2 e5\n", b"1 2 1.2.3\n", b"1 2 3\x0b\n", b"1 2 inf\n"])
def test_bad_text_gets_the_compiled_parsers_report(text, monkeypatch):
    small = _numparse.parse(text, 3, 10, 1e9)
    monkeypatch.setattr(_numparse, "SMALL_TEXT_BYTES", -1)
    big = _numparse.parse(text, 3, 10, 1e9)
    assert small[1] != _numparse.OK
    assert small[1:] == big[1:]


def test_numpy_euler_equals_the_compiled_kernel(rng, monkeypatch):
    values = rng.uniform(-720, 720, size=(30, 9))
    cols = np.array([[0, 1, 2], [3, 4, 5], [-1, -1, -1], [6, 7, 8]])
    axes = np.array([[2, 0, 1], [0, 1, 2], [0, 0, 0], [1, 1, 0]])
    a = np.empty((30, 4, 4))
    b = np.empty((30, 4, 4))
    _numparse.euler_columns_to_quat(values, cols, axes, a)
    monkeypatch.setattr(_numparse, "SMALL_JOINT_FRAMES", -1)
    _numparse.euler_columns_to_quat(values, cols, axes, b)
    np.testing.assert_allclose(a, b, rtol=0, atol=_TOL)
    np.testing.assert_array_equal(a[:, 2], [[1, 0, 0, 0]] * 30)


_SMALL_FILES = [p for p in mocap_files("**/*.bvh") if p.stat().st_size < 1 << 20][:6]


@pytest.mark.mocap
@pytest.mark.parametrize("path", _SMALL_FILES or [None], ids=[p.name for p in _SMALL_FILES] or ["no-mocap"])
def test_real_files_read_the_same_on_both_paths(path, monkeypatch):
    if path is None:
        pytest.skip("shared motion-capture folder not found")
    small = read_bvh(path)
    gp_small = small.global_positions()
    monkeypatch.setattr(kinematics, "SMALL_JOINT_FRAMES", -1)
    monkeypatch.setattr(_numparse, "SMALL_JOINT_FRAMES", -1)
    monkeypatch.setattr(_numparse, "SMALL_TEXT_BYTES", -1)
    big = read_bvh(path)
    np.testing.assert_allclose(small.local_rot, big.local_rot, rtol=0, atol=_TOL)
    np.testing.assert_allclose(small.root_pos, big.root_pos, rtol=0, atol=_TOL)
    np.testing.assert_allclose(gp_small, big.global_positions(), rtol=0, atol=_TOL)


def _modules_after(code: str) -> set[str]:
    """The modules a fresh interpreter holds after running ``code``."""
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys\nprint(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True, timeout=120).stdout
    return set(out.strip().split("\n")[-1].split())


def _heavy(mods: set[str]) -> list[str]:
    return sorted(m for m in mods if any(m == h or m.startswith(h + ".") for h in _HEAVY))


def test_import_kinodyn_is_light():
    assert _heavy(_modules_after("import kinodyn")) == []


def test_info_on_a_small_file_is_light(tmp_path):
    path = tmp_path / "walk.bvh"
    from kinodyn.io import save

    save(path, library.load("walk"))
    mods = _modules_after(f"from kinodyn.cli import main\nmain(['info', {str(path)!r}])")
    assert _heavy(mods) == []


def test_large_motions_still_use_the_compiled_kernel():
    code = ("import numpy as np\nfrom kinodyn import kinematics\n"
            "n = kinematics.SMALL_JOINT_FRAMES // 3 + 1\n"
            "kinematics.fk_arrays(np.zeros((n, 3)), np.tile([1.0, 0, 0, 0], (n, 3, 1)), np.ones((3, 3)), "
            "np.array([-1, 0, 1]))")
    assert "numba" in _modules_after(code)
