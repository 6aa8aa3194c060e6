"""Bad input to the CLI: exit 2, one line naming the user's path or option, existing output intact.

One test per case a new user met: an output folder that is a file, frame counts and rates out of range,
blend scripts whose numbers would allocate gigabytes, archives that are not motions, unwritable output,
messages naming the wrong option, and help pages without descriptions.
"""

from __future__ import annotations

import resource

import numpy as np
import pytest

from kinodyn.cli import main
from kinodyn.data import library
from kinodyn.io import load, save


@pytest.fixture
def walk_bvh(tmp_path):
    path = tmp_path / "walk.bvh"
    save(path, library.load("walk"))
    return path


@pytest.fixture
def existing(tmp_path):
    """An output that exists already: every failed command must leave it as it was."""
    out = tmp_path / "out.bvh"
    out.write_text("previous result\n")
    return out


def _one_error_line(capsys, *fragments) -> str:
    err = capsys.readouterr().err
    lines = err.strip().split("\n")
    assert len(lines) == 1 and lines[0].startswith("kinodyn: error: "), err
    assert "Traceback" not in err
    for f in fragments:
        assert f in lines[0], (f, lines[0])
    return lines[0]


@pytest.fixture(autouse=True)
def _memory_cap():
    """An address-space cap of 4 GiB: a command that tries to allocate 13-15 GiB fails loudly here
    (MemoryError, not exit 2) instead of slowing the machine down."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = 4 << 30
    if hard != resource.RLIM_INFINITY and hard < cap:
        cap = hard
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    yield
    resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


# --------------------------------------------------------------------------- output paths


def test_output_folder_that_is_a_file(walk_bvh, tmp_path, capsys):
    blocker = tmp_path / "notes.txt"
    blocker.write_text("keep me\n")
    out = blocker / "c.bvh"
    assert main(["convert", str(walk_bvh), str(out)]) == 2
    _one_error_line(capsys, str(out), "is a file, not a folder")
    assert blocker.read_text() == "keep me\n"


def test_output_folder_below_a_file(walk_bvh, tmp_path, capsys):
    blocker = tmp_path / "notes.txt"
    blocker.write_text("keep me\n")
    out = blocker / "sub" / "c.npz"
    assert main(["convert", str(walk_bvh), str(out)]) == 2
    _one_error_line(capsys, str(out), "is a file, not a folder")
    assert blocker.read_text() == "keep me\n"


def test_unwritable_output_names_the_users_path(walk_bvh, capsys):
    """/sys refuses new files even to root: the message names the user's path, not the temporary file."""
    out = "/sys/c.bvh"
    assert main(["convert", str(walk_bvh), out]) == 2
    line = _one_error_line(capsys, f"{out}: ")
    assert ".tmp" not in line and ".c.bvh." not in line


def test_output_that_is_a_folder_names_the_users_path(walk_bvh, tmp_path, capsys):
    out = tmp_path / "taken.bvh"
    out.mkdir()
    assert main(["convert", str(walk_bvh), str(out)]) == 2
    line = _one_error_line(capsys, str(out))
    assert ".tmp" not in line
    assert out.is_dir() and not list(tmp_path.glob(".taken.bvh.*"))


# --------------------------------------------------------------------------- frame counts and rates


def test_drop_first_all_frames(walk_bvh, existing, capsys):
    n = load(walk_bvh).num_frames
    assert main(["convert", str(walk_bvh), str(existing), "--drop-first", str(n)]) == 2
    _one_error_line(capsys, "--drop-first", str(walk_bvh), f"{n} frames")
    assert existing.read_text() == "previous result\n"


def test_drop_first_negative(walk_bvh, existing, capsys):
    assert main(["convert", str(walk_bvh), str(existing), "--drop-first", "-1"]) == 2
    _one_error_line(capsys, "--drop-first", "-1")
    assert existing.read_text() == "previous result\n"


def test_fps_zero(walk_bvh, existing, capsys):
    assert main(["convert", str(walk_bvh), str(existing), "--fps", "0"]) == 2
    _one_error_line(capsys, "--fps")
    assert existing.read_text() == "previous result\n"


def test_fps_huge(walk_bvh, existing, capsys):
    assert main(["convert", str(walk_bvh), str(existing), "--fps", "1e9"]) == 2
    _one_error_line(capsys, "--fps 1e+09", "frames")
    assert existing.read_text() == "previous result\n"


def test_out_unit_names_out_unit(walk_bvh, existing, capsys):
    assert main(["convert", str(walk_bvh), str(existing), "--out-unit", "furlong"]) == 2
    line = _one_error_line(capsys, "--out-unit", "furlong")
    assert "--scale" not in line
    assert existing.read_text() == "previous result\n"


# --------------------------------------------------------------------------- blend scripts


@pytest.mark.parametrize("top,action,fragment", [
    ("duration: 1.0e+7", "", "duration must be at most"),
    ("fps: 1.0e+9", "", "fps must be at most"),
    ("", ", start: 1.0e+9", "start must be at most"),
    ("nk: 1000000000", "", "nk must be at most"),
])
def test_blend_script_huge_numbers(tmp_path, existing, capsys, top, action, fragment):
    script = tmp_path / "s.yaml"
    script.write_text(f"{top}\nactions:\n  - {{clip: walk{action or ', start: 0'}}}\n")
    assert main(["blend", str(script), "-o", str(existing)]) == 2
    _one_error_line(capsys, str(script), fragment)
    assert existing.read_text() == "previous result\n"


def test_blend_fps_override_huge(tmp_path, existing, capsys):
    """``--fps`` bypasses the script's own limits: the frame count is bounded all the same."""
    script = tmp_path / "s.yaml"
    script.write_text("actions:\n  - {clip: walk, start: 0, stop: 2}\n")
    assert main(["blend", str(script), "-o", str(existing), "--fps", "1e9"]) == 2
    _one_error_line(capsys, "frames, more than")
    assert existing.read_text() == "previous result\n"


# --------------------------------------------------------------------------- archives


def test_info_on_a_zero_frame_archive(walk_bvh, tmp_path, capsys):
    empty = tmp_path / "none.npz"
    save(empty, load(walk_bvh)[:0])
    assert main(["info", str(empty)]) == 2
    _one_error_line(capsys, str(empty), "no frames")


def test_info_on_an_empty_file(tmp_path, capsys):
    path = tmp_path / "empty.npz"
    path.write_bytes(b"")
    assert main(["info", str(path)]) == 2
    _one_error_line(capsys, str(path), "empty")


def test_info_on_random_bytes(tmp_path, capsys):
    path = tmp_path / "noise.npz"
    path.write_bytes(np.random.default_rng(3).bytes(4096))
    assert main(["info", str(path)]) == 2
    line = _one_error_line(capsys, str(path), "not a kinodyn motion archive")
    assert "pickle" not in line


# --------------------------------------------------------------------------- messages and help


def test_amc_without_asf_names_the_option(tmp_path, capsys):
    from kinodyn.io.bench import synthetic_amc_text

    amc = tmp_path / "walk_01.amc"
    amc.write_text(synthetic_amc_text(5))
    assert main(["info", str(amc)]) == 2
    line = _one_error_line(capsys, str(amc), "--asf")
    assert "asf=" not in line


@pytest.mark.parametrize("command,args", [
    ("info", ["file", "--json", "--verbose", "--scale", "--up", "--asf"]),
    ("convert", ["input", "output", "--fps", "--mirror", "--drop-first", "--drop-tpose", "--out-unit",
                 "--out-up", "--order", "--scale"]),
])
def test_help_has_a_description_and_argument_help(command, args, capsys):
    with pytest.raises(SystemExit) as ei:
        main([command, "--help"])
    assert ei.value.code == 0
    out = capsys.readouterr().out
    description = out.split("\n\n")[1]
    assert len(description.split()) >= 15, out  # a paragraph, not the usage line again
    lines = out.split("\n")
    body = lines[next(i for i, ln in enumerate(lines) if ln.startswith("positional arguments")):]
    for a in args:
        row = next(ln for ln in body if ln.startswith("  ") and ln.split(",")[-1].strip().split()[0] == a
                   or ln.strip().startswith(a + " "))
        # the argument's own help text is on its row (or the row below when the name is long)
        following = body[body.index(row) + 1]
        text = row.strip().split(None, 1)[1:] if not row.strip().startswith("-") else \
            row.split(a, 1)[1].split(None, 1)[1:]
        if not text and following.startswith("      "):
            text = [following.strip()]
        assert text and len(" ".join(text).split()) >= 2, (a, row)


def test_view_drop_first_negative(walk_bvh, tmp_path, capsys):
    out = tmp_path / "v.html"
    assert main(["view", str(walk_bvh), "-o", str(out), "--drop-first", "-1"]) == 2
    _one_error_line(capsys, "--drop-first -1", str(walk_bvh))
    assert not out.exists()
