"""The file commands of the CLI: ``info``, ``convert``, ``library`` and ``bench io``.

Good input exits 0; bad input prints one line on stderr and exits 2, never a traceback.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from kinodyn.io.bench import synthetic_amc_text, synthetic_asf_text
from kinodyn.cli import main
from kinodyn.io.bvh import read_bvh


@pytest.fixture
def cmu_like(tmp_path):
    """A synthetic CMU-shaped ASF/AMC pair (200 frames) and its BVH conversion."""
    (tmp_path / "synth_01.asf").write_text(synthetic_asf_text())
    (tmp_path / "synth_01_01.amc").write_text(synthetic_amc_text(200))
    bvh = tmp_path / "synth.bvh"
    assert main(["convert", str(tmp_path / "synth_01_01.amc"), str(bvh)]) == 0
    return tmp_path / "synth_01_01.amc", bvh


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().split("\n")
    assert len(lines) == 1 and lines[0].startswith("kinodyn: error: "), err
    assert "Traceback" not in err
    return lines[0]


# --------------------------------------------------------------------------- info


def test_info_good(cmu_like, capsys):
    amc, bvh = cmu_like
    capsys.readouterr()
    assert main(["info", str(bvh)]) == 0
    out = capsys.readouterr().out
    assert "31 joints" in out and "200 frames at 120 fps" in out
    assert main(["info", str(amc), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["joints"] == 31 and info["frames"] == 200 and info["fps"] == 120
    assert main(["info", str(bvh), "--scale", "cm", "--up", "y", "-v"]) == 0


@pytest.mark.parametrize("content,fragment", [
    (b"", "empty"),
    (b"HIERARCHY", "no MOTION"),
    (b"\x00\x01\x02garbage", "not a BVH"),
    ((b"HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n}\nMOTION\nFrames: 2\n"
      b"Frame Time: 0.1\n0 0 nan\n"), ":10: expected a number"),
])
def test_info_bad_bvh(tmp_path, capsys, content, fragment):
    path = tmp_path / "bad.bvh"
    path.write_bytes(content)
    assert main(["info", str(path)]) == 2
    line = _one_error_line(capsys)
    assert str(path) in line and fragment in line


def test_info_bad_inputs(tmp_path, cmu_like, capsys):
    amc, bvh = cmu_like
    assert main(["info", str(tmp_path / "missing.bvh")]) == 2
    assert "missing.bvh" in _one_error_line(capsys)
    (tmp_path / "x.txt").write_text("hello")
    assert main(["info", str(tmp_path / "x.txt")]) == 2
    assert "unknown motion file type" in _one_error_line(capsys)
    assert main(["info", str(bvh), "--scale", "furlong"]) == 2
    assert "--scale" in _one_error_line(capsys)
    lonely = tmp_path / "lonely"
    lonely.mkdir()
    (lonely / "walk_01.amc").write_text(amc.read_text())
    assert main(["info", str(lonely / "walk_01.amc")]) == 2
    assert "no ASF skeleton" in _one_error_line(capsys)
    (lonely / "walk_01.amc").write_text(amc.read_text().replace("lfemur", "lfemurx", 1))
    assert main(["info", str(lonely / "walk_01.amc"), "--asf", str(amc.with_name("synth_01.asf"))]) == 2
    assert "walk_01.amc:" in _one_error_line(capsys)


# --------------------------------------------------------------------------- convert


def test_convert_round_trips(cmu_like, tmp_path, capsys):
    _, bvh = cmu_like
    m = read_bvh(bvh)
    out = tmp_path / "out.bvh"
    assert main(["convert", str(bvh), str(out), "--out-unit", "m", "--order", "xyz", "--out-up", "z"]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {out}: 200 frames at 120 fps, 31 joints")
    back = read_bvh(out, scale="m", up="z")
    assert np.abs(back.global_positions() - m.global_positions()).max() < 1e-6
    npz = tmp_path / "out.npz"
    assert main(["convert", str(bvh), str(npz), "--drop-first", "1"]) == 0
    from kinodyn.io import load

    assert load(npz).num_frames == 199
    assert main(["convert", str(bvh), str(tmp_path / "half.bvh"), "--fps", "60"]) == 0
    assert read_bvh(tmp_path / "half.bvh").fps == pytest.approx(60.0)


def test_convert_output_opens_in_third_party_reader(cmu_like, tmp_path):
    """`kinodyn convert` writes a standard BVH: the PyPI `bvh` package reads the same joints, frames,
    frame time and channel values (root translation and a joint's Euler angles)."""
    bvh_pkg = pytest.importorskip("bvh")
    from scipy.spatial.transform import Rotation

    amc, _ = cmu_like
    out = tmp_path / "third.bvh"
    assert main(["convert", str(amc), str(out)]) == 0
    ours = read_bvh(out)
    doc = bvh_pkg.Bvh(out.read_text())
    assert tuple(doc.get_joints_names()) == ours.skeleton.names
    assert doc.nframes == ours.num_frames == 200
    assert doc.frame_time == pytest.approx(1 / 120, rel=1e-8)
    root = np.array(doc.frames_joint_channels("root", ["Xposition", "Yposition", "Zposition"]), dtype=float)
    np.testing.assert_allclose(root[:, [2, 0, 1]] * 0.01, ours.root_pos, atol=1e-7)
    ang = np.array(doc.frames_joint_channels("lfemur", ["Zrotation", "Yrotation", "Xrotation"]), dtype=float)
    # the femur's rotation, turned from the file's Y-up axes to kinodyn's Z-up axes
    r = Rotation.from_euler("ZYX", ang, degrees=True).as_matrix()
    turn = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], dtype=float)  # (x, y, z) -> (z, x, y)
    want = turn @ r @ turn.T
    from kinodyn.math import quat

    got = quat.to_matrix(ours.local_rot[:, ours.skeleton.index("lfemur")])
    np.testing.assert_allclose(got, want, atol=1e-7)


@pytest.mark.parametrize("args,fragment", [
    (["--order", "abc"], "order"),
    (["--out-unit", "furlong"], "--out-unit"),
    (["--fps", "-5"], "fps"),
])
def test_convert_bad_options(cmu_like, tmp_path, capsys, args, fragment):
    _, bvh = cmu_like
    assert main(["convert", str(bvh), str(tmp_path / "o.bvh"), *args]) == 2
    assert fragment in _one_error_line(capsys)
    assert not (tmp_path / "o.bvh").exists()


def test_convert_bad_input_and_output(cmu_like, tmp_path, capsys):
    _, bvh = cmu_like
    assert main(["convert", str(bvh), str(tmp_path / "o.txt")]) == 2
    assert "cannot write" in _one_error_line(capsys)
    bad = tmp_path / "bad.bvh"
    bad.write_bytes(bvh.read_bytes()[:-300])  # truncated
    assert main(["convert", str(bad), str(tmp_path / "o.bvh")]) == 2
    assert "bad.bvh:" in _one_error_line(capsys)


def test_argparse_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as ei:
        main(["convert", "only-one-arg"])
    assert ei.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.strip().count("\n") <= 2  # usage line + error line


def test_subprocess_has_no_traceback(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_bytes(b"HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 3000000000\n}\nMOTION\nFrames: 1\n")
    r = subprocess.run([sys.executable, "-m", "kinodyn.cli", "info", str(bad)], capture_output=True, text=True,
                       timeout=120, check=False)
    assert r.returncode == 2
    assert r.stdout == ""
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert f"{bad}:5:" in r.stderr


# --------------------------------------------------------------------------- library

def test_library_commands(tmp_path, capsys):
    assert main(["library", "list"]) == 0
    out = capsys.readouterr().out
    names = [ln.split()[0] for ln in out.strip().split("\n")]
    assert "walk" in names
    path = tmp_path / "walk.bvh"
    assert main(["library", "export", "walk", str(path)]) == 0
    m = read_bvh(path)
    assert m.num_frames > 1 and np.isfinite(m.global_positions()).all()
    assert main(["library", "export", "no_such_clip", str(tmp_path / "x.bvh")]) == 2
    _one_error_line(capsys)
    assert main(["library", "export"]) == 2
    _one_error_line(capsys)


# --------------------------------------------------------------------------- bench


def test_bench_files_without_mocap(tmp_path, monkeypatch):
    """Without ../shared/mocap the benchmark makes its own CMU-shaped files."""
    import kinodyn.io.bench as bench_io
    from kinodyn.io.amc import read_amc

    monkeypatch.setenv("KINODYN_MOCAP", str(tmp_path / "absent"))
    assert bench_io.find_mocap() is None
    path, src = bench_io.make_bvh_file(tmp_path, frames=300)
    assert src.startswith("synthetic")
    m = read_bvh(path)
    assert m.num_frames == 300 and m.num_joints == 31 and m.fps == pytest.approx(120.0)
    assert 700 < path.stat().st_size / 300 < 800  # bytes per frame, as in the CMU files
    amc, asf, src = bench_io.make_amc_files(tmp_path, frames=50)
    assert read_amc(amc, asf=asf).num_frames == 50


@pytest.mark.slow
def test_bench_io_quick(tmp_path, capsys):
    out = tmp_path / "bench.json"
    assert main(["bench", "io", "--quick", "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    for key in ("bvh_frames_per_s", "fk_joint_frames_per_s", "amc_parse_s", "cold_info_s", "cold_info_mb",
                "library_generate_s", "bvh_huge_header_reject_s"):
        assert res["metrics"][key] > 0, key
    # a whole process of python + numpy at least, and no 300 MB of the benchmark's own process counted
    assert 0.02 < res["metrics"]["cold_info_s"] < 60 and 15 < res["metrics"]["cold_info_mb"] < 150
    if "cold_bvh_pypi_s" in res["metrics"]:
        ratio = res["metrics"]["cold_info_s"] / res["metrics"]["cold_bvh_pypi_s"]
        assert res["metrics"]["cold_ratio_vs_bvh_pypi"] == pytest.approx(ratio)
    assert res["units"]["amc_parse_s"] == "s"
    assert "10000 frames x 31 joints" in res["notes"]["bvh_file"]
    assert "bvh_frames_per_s" in capsys.readouterr().out
