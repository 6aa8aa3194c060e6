"""Blend scripts (YAML) and the ``kinodyn blend`` command."""

from __future__ import annotations

from pathlib import Path

import pytest

from kinodyn.blend.script import ScriptError, load_script, parse_script
from kinodyn.cli import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "blend_fig12.yaml"


def test_example_script_is_the_demo_script():
    from kinodyn.blend.demo import transition_script

    ex = load_script(EXAMPLE)
    demo = transition_script()
    assert ex.actions == demo.actions
    assert (ex.fps, ex.nk, ex.ramp_in, ex.ramp_out, ex.synchronize) == (demo.fps, demo.nk, demo.ramp_in,
                                                                          demo.ramp_out, demo.synchronize)


@pytest.mark.parametrize("data, message", [
    ([1, 2], "the script must be a mapping"),
    ({"actions": []}, "'actions' must be a non-empty list"),
    ({"actions": [{"start": 0}]}, "actions[0]: missing 'clip'"),
    ({"actions": [{"clip": "walk"}]}, "actions[0]: missing 'start' (seconds)"),
    ({"actions": [{"clip": "walk", "start": 2, "stop": 1}]}, "actions[0]: stop (1 s) is before start (2 s)"),
    ({"actions": [{"clip": "walk", "start": 0, "speed": 0}]}, "actions[0]: speed must be positive, got 0"),
    ({"actions": [{"clip": "walk", "start": 0, "prio": 1}]}, "actions[0]: unknown key 'prio'; allowed:"),
    ({"actions": [{"clip": "walk", "start": "soon"}]}, "actions[0]: start must be a number, got 'soon'"),
    ({"tempo": 3, "actions": [{"clip": "walk", "start": 0}]}, "script: unknown key 'tempo'"),
    ({"synchronize": "yes", "actions": [{"clip": "walk", "start": 0}]}, "synchronize must be true or false"),
    ({"actions": [{"clip": "walk", "start": 0, "key": "a"}, {"clip": "run", "start": 1, "key": "a"}]},
     "actions[1]: key 'a' is used twice"),
])
def test_script_errors_name_the_entry(data, message):
    with pytest.raises(ScriptError) as e:
        parse_script(data)
    assert message in str(e.value)


def test_yaml_syntax_error_gives_the_line(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("actions:\n  - clip: walk\n    start: [0\n")
    with pytest.raises(ScriptError) as e:
        load_script(p)
    assert str(p) in str(e.value) and "not valid YAML" in str(e.value)


def test_unknown_clip_lists_the_known_ones():
    from kinodyn.blend.script import build_library

    with pytest.raises(ScriptError, match="unknown clip 'moonwalk'; known clips: .*walk"):
        build_library(parse_script({"actions": [{"clip": "moonwalk", "start": 0}]}))


def test_cli_writes_the_blend_plots_and_viewer(tmp_path, capsys):
    script = tmp_path / "s.yaml"
    script.write_text("fps: 30\nactions:\n  - {clip: walk, start: 0, stop: 1.5, priority: 1}\n"
                      "  - {clip: run, start: 1.2, stop: 2.5, priority: 1}\n")
    out = tmp_path / "out.bvh"
    rc = main(["blend", str(script), "-o", str(out), "--compare", "--plots", str(tmp_path / "plots")])
    assert rc == 0
    text = capsys.readouterr().out
    assert out.exists() and "synchronized" in text and "not synchronized" in text
    assert (tmp_path / "plots" / "out_phases.png").stat().st_size > 10_000
    assert (tmp_path / "plots" / "out_timewarp.png").stat().st_size > 10_000
    from kinodyn.io import load

    m = load(out)
    assert m.num_frames == pytest.approx(30 * (2.5 + 0.4 + 0.5) + 1, abs=2)


def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    script = tmp_path / "s.yaml"
    script.write_text("actions:\n  - {clip: walk}\n")
    assert main(["blend", str(script), "-o", str(tmp_path / "o.bvh")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "missing 'start'" in err[0]
    assert main(["blend", str(tmp_path / "none.yaml"), "-o", str(tmp_path / "o.bvh")]) == 2
