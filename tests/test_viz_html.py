"""kinodyn.viz.html and kinodyn.viz.world: the self-contained viewer page, its data encoding, overlays.

The page is checked as a document here (self-contained, data complete, decodable); tests that open it
in a browser are in test_viz_browser.py.
"""

from __future__ import annotations

import base64
import itertools
import json
import re
import zlib

import numpy as np
import pytest
from numpy.testing import assert_allclose

from kinodyn.data import library
from kinodyn.errors import ParameterError
from kinodyn.plotting import style
from kinodyn.viz import html, world
from kinodyn.viz.world import Actor, Contacts, Impact, Phases, Trajectory

_TOL = 1e-9

pytestmark = pytest.mark.skipif(not html.bundle_available(), reason="viewer bundle not built (run make)")


def page_data(text: str) -> dict:
    m = re.search(r'<script type="application/json" id="kinodyn-data">(.*?)</script>', text, re.DOTALL)
    assert m, "no data block in the page"
    return json.loads(m.group(1).replace("<\\/", "</"))


@pytest.fixture(scope="module")
def walk():
    return library.load("walk")


@pytest.fixture(scope="module")
def run_clip():
    return library.load("run")


# --------------------------------------------------------------------------- encoding


def test_positions_round_trip_within_half_a_step(rng):
    pos = rng.normal(scale=3.0, size=(50, 7, 3)) + np.array([10.0, -4.0, 1.0])
    for compress in (True, False):
        block = html.encode_positions(pos, compress)
        back = html.decode_positions(block, 50, 7)
        assert_allclose(back, pos, atol=0.5 * max(block["scale"]) + _TOL)


def test_positions_wrap_around_large_jumps(rng):
    """Regression: deltas between frames that overflow int16 must wrap and decode exactly (teleports)."""
    pos = np.zeros((6, 2, 3))
    pos[::2] = 100.0  # jumps across the whole box every frame
    pos[:, 1] = rng.uniform(0, 100, size=(6, 3))
    block = html.encode_positions(pos)
    assert_allclose(html.decode_positions(block, 6, 2), pos, atol=0.5 * max(block["scale"]) + _TOL)


def test_positions_bytes_are_planes_of_int16_deltas():
    """The layout the page decodes: int16 deltas along frames (wrapping), low bytes then high bytes."""
    pos = np.zeros((3, 1, 3))
    pos[:, 0, 0] = [0.0, 1.0, 2.0]  # x steps by half the box each frame: q = -32768, 0, 32767
    block = html.encode_positions(pos, compress=False)
    raw = np.frombuffer(base64.b64decode(block["data"]), dtype=np.uint8)
    n = 9
    d = (raw[:n].astype(np.uint16) | (raw[n:].astype(np.uint16) << 8)).view(np.int16)
    # frame 0 absolute; frame 1: 0 - (-32768) = 32768 wraps to -32768; frame 2: 32767 - 0.
    assert d.tolist() == [-32768, -32768, -32768, -32768, 0, 0, 32767, 0, 0]
    assert block["enc"] == "i16d"
    assert zlib.decompress(base64.b64decode(html.encode_positions(pos)["data"])) == raw.tobytes()


def test_encode_rejects_bad_positions():
    with pytest.raises(ParameterError, match=r"shape \(F, P, 3\)"):
        html.encode_positions(np.zeros((3, 4)))
    with pytest.raises(ParameterError, match="finite"):
        html.encode_positions(np.full((2, 1, 3), np.nan))


# --------------------------------------------------------------------------- world


def test_body_points_are_joints_then_end_sites(walk):
    pos, parents, names = world.body_points(walk)
    sk = walk.skeleton
    assert pos.shape == (walk.num_frames, sk.num_joints + len(sk.end_parents), 3)
    assert names[:sk.num_joints] == list(sk.names)
    assert all(n.endswith("_end") for n in names[sk.num_joints:])
    assert_allclose(pos[:, :sk.num_joints], walk.global_positions(), atol=1e-12)
    assert parents[0] == -1 and np.all(parents[1:] < np.arange(1, len(parents)))


def test_bone_radii_make_a_head_thicker_than_a_hand(walk):
    _, parents, names = world.body_points(walk)
    r = world.bone_radii(names, parents, walk.skeleton.height())
    assert r[0] == 0 and np.all(r[1:] > 0)
    assert r[names.index("Head_end")] > 2 * r[names.index("LeftHand")]
    assert r[names.index("Spine")] > r[names.index("LeftForeArm")]


def test_support_phases_labels_and_spans():
    lab = np.array([[1, 1], [1, 0], [1, 0], [0, 0], [0, 1], [1, 1]], dtype=bool)
    spans = world.support_phases(lab, fps=10.0, start=1.0)
    assert spans == [(1.0, 1.1, "DS"), (1.1, 1.3, "LS"), (1.3, 1.4, "FLIGHT"), (1.4, 1.5, "RS"), (1.5, 1.6, "DS")]
    with pytest.raises(ParameterError, match=r"shape \(F, 2\)"):
        world.support_phases(np.zeros(4, dtype=bool), 10.0)


def test_build_world_names_colours_and_clock(walk, run_clip):
    w = world.build_world({"a": walk, "b": Actor(run_clip, color="#112233", start=0.5)}, None)
    assert [c.name for c in w.characters] == ["a", "b"]
    assert w.characters[1].color == "#112233"
    assert w.fps == 60.0
    assert w.duration == pytest.approx(max(walk.duration, 0.5 + run_clip.duration))
    assert w.characters[1].frame_at(0.0) == 0 and w.characters[1].frame_at(100.0) == run_clip.num_frames - 1


def test_row_layout_keeps_characters_apart(walk, run_clip):
    w = world.build_world([walk, run_clip, walk], None, layout="row")
    ranges = [(c.positions[..., 0].min(), c.positions[..., 0].max()) for c in w.characters]
    for (lo0, hi0), (lo1, hi1) in itertools.pairwise(ranges):
        assert hi0 < lo1, "characters of a row overlap"
    grid = world.build_world([walk] * 4, None, layout="grid")
    starts = np.array([c.positions[0, 0, :2] for c in grid.characters])
    assert len({tuple(np.round(s, 3)) for s in starts}) == 4


@pytest.mark.parametrize("bad, message", [
    ({"overlays": ["nope"]}, "unknown overlay 'nope'"),
    ({"layout": "circle"}, "layout must be one of"),
    ({"names": ["only one"], "motions": 2}, "one entry per character"),
    ({"overlays": [Impact(0.0, (0, 0), (1, 0, 0))]}, r"finite \(3,\) vectors"),
    ({"overlays": [Phases([(0, 1, "DS")], character=5)]}, "character index must be in 0..0"),
    ({"overlays": [Trajectory(np.zeros((4, 2)))]}, r"shape \(N, 3\)"),
])
def test_build_world_errors_name_the_problem(walk, bad, message):
    kw = dict(bad)
    motions = [walk] * kw.pop("motions", 1)
    with pytest.raises(ParameterError, match=message):
        world.build_world(motions, **kw)


def test_build_world_rejects_empty_and_wrong_types(walk):
    with pytest.raises(ParameterError, match="empty"):
        world.build_world([])
    with pytest.raises(ParameterError, match="motions must be a Motion"):
        world.build_world("walk.bvh")
    with pytest.raises(ParameterError, match=r"contacts of character 0 must have shape"):
        world.build_world(walk, [Contacts(0, np.zeros((3, 2), dtype=bool))])


# --------------------------------------------------------------------------- page


def test_page_is_self_contained(tmp_path, walk):
    page = html.write(tmp_path / "walk.html", walk)
    text = page.path.read_text()
    assert page.bytes == len(text.encode())
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=|@import|url\(\s*['\"]?https?:", text), \
        "the page loads something from outside"
    assert "//cdn" not in text and "unpkg.com" not in text
    assert text.count("<script") == 2  # the data block and the inlined bundle
    assert "WebGLRenderer" in text or "webgl" in text.lower()


def test_page_data_holds_every_frame(tmp_path, walk, run_clip):
    overlays = ["contacts", "phases", "trajectories",
                Impact(0.5, (0.3, 0.0, 1.4), (-30.0, 0.0, 0.0), character=1, label="punch"),
                Trajectory(np.zeros((5, 3)), color="C2", label="plan")]
    text = html.to_html([walk, run_clip], overlays, names=["walker", "runner"], colors=["#ff0000", None],
                        title="a <test>")
    assert "<title>a &lt;test&gt;</title>" in text
    data = page_data(text)
    assert data["version"] == html.FORMAT_VERSION
    (scene,) = data["scenes"]
    chars = scene["characters"]
    assert [c["name"] for c in chars] == ["walker", "runner"]
    assert chars[0]["color"] == "#ff0000" and chars[1]["color"] != "#ff0000"
    for c, m in zip(chars, [walk, run_clip]):
        pos, _, _ = world.body_points(m)
        back = html.decode_positions(c["pos"], c["frames"], len(c["parents"]))
        assert_allclose(back, pos, atol=0.5 * max(c["pos"]["scale"]) + _TOL)
        assert c["contacts"] is not None and set(c["feet"]) == {"left", "right"}
    assert scene["impacts"][0]["impulse"] == [-30.0, 0.0, 0.0] and scene["impacts"][0]["char"] == 1
    assert [p["label"] for p in scene["phases"]] == ["walker support", "runner support"]
    assert scene["trajectories"][0]["color"] == style.PALETTE[2]
    assert data["options"]["trajectories"] and data["options"]["contacts"] and data["options"]["phases"]


def test_explicit_phases_do_not_add_support_bars(walk):
    data = page_data(html.to_html([walk, walk], [Phases([(0.0, 1.0, "blend")], "weights", 0)]))
    assert [p["label"] for p in data["scenes"][0]["phases"]] == ["weights"]
    assert data["scenes"][0]["characters"][0]["contacts"] is None


def test_scenes_in_one_page(tmp_path, walk, run_clip):
    scenes = [html.Scene([walk], name="#1 score 0.9"), html.Scene({"r": run_clip, "w": walk}, None, "#2")]
    page = html.write(tmp_path / "ranked.html", scenes=scenes)
    assert [s[:2] for s in page.scenes] == [("#1 score 0.9", 1), ("#2", 2)]
    data = page_data(page.path.read_text())
    assert [s["name"] for s in data["scenes"]] == ["#1 score 0.9", "#2"]


def test_names_cannot_break_out_of_the_data_block(walk):
    text = html.to_html({"</script><script>alert(1)</script>": walk})
    assert text.count("</script>") == 2
    assert page_data(text)["scenes"][0]["characters"][0]["name"].startswith("</script>")


def test_page_argument_errors(walk):
    with pytest.raises(ParameterError, match="body must be one of"):
        html.to_html(walk, body="mesh")
    with pytest.raises(ParameterError, match="camera must be one of"):
        html.to_html(walk, camera="top")
    with pytest.raises(ParameterError, match="not both"):
        html.to_html(walk, scenes=[html.Scene(walk)])
    with pytest.raises(ParameterError, match="give motions or scenes"):
        html.to_html()


def test_missing_bundle_message(monkeypatch):
    monkeypatch.setattr(html, "_BUNDLE", "no-such-bundle.js")
    with pytest.raises(html.AssetMissingError, match="not built|missing"):
        html._asset("no-such-bundle.js")
    assert "npm" in html.MSG_BUNDLE_MISSING and "make" in html.MSG_BUNDLE_MISSING


def test_write_is_atomic_on_error(tmp_path, walk):
    target = tmp_path / "page.html"
    target.write_text("previous")
    with pytest.raises(ParameterError):
        html.write(target, walk, overlays=["nope"])
    assert target.read_text() == "previous"
    assert [p.name for p in tmp_path.iterdir()] == ["page.html"]


def _bytes(block) -> np.ndarray:
    raw = base64.b64decode(block["data"])
    return np.frombuffer(zlib.decompress(raw) if block["enc"].endswith("z") else raw, dtype=np.uint8)


def test_a_highlighted_joint_marks_the_bones_of_its_segment(walk):
    """A joint's segment runs from it to its children and end sites: those bones, and only those,
    are marked in the frames given."""
    sk = walk.skeleton
    hot = np.zeros((walk.num_frames, sk.num_joints), dtype=bool)
    arm = sk.index("LeftForeArm")
    hot[10:20, arm] = True
    data = page_data(html.to_html(Actor(walk, highlight=hot), None))
    (c,) = data["scenes"][0]["characters"]
    marks = _bytes(c["hot"]).reshape(c["frames"], len(c["parents"]))
    parents = np.array(c["parents"])
    assert np.array_equal(np.nonzero(marks.any(axis=0))[0], np.nonzero(parents == arm)[0])
    assert np.array_equal(np.nonzero(marks.any(axis=1))[0], np.arange(10, 20))
    assert page_data(html.to_html(walk, None))["scenes"][0]["characters"][0]["hot"] is None
    with pytest.raises(ParameterError, match=r"highlight of character 0 must be a bool array of shape"):
        world.build_world(Actor(walk, highlight=hot[:5]), None)


def test_prop_opacity_reaches_the_page_and_is_checked(walk):
    from kinodyn.viz.objects import Prop

    data = page_data(html.to_html(walk, [Prop("box", (0, 0, 1), (1, 1, 1), opacity=0.35)]))
    assert data["scenes"][0]["props"][0]["opacity"] == 0.35
    with pytest.raises(ParameterError, match=r"opacity must be in \(0, 1\]"):
        html.to_html(walk, [Prop("box", (0, 0, 1), (1, 1, 1), opacity=0.0)])


def test_lanes_overlay_a_reference_on_the_first_lane(walk, run_clip):
    """Solid characters get lanes side by side; a ghost shares the first one's lane (a comparison)."""
    w = world.build_world([walk, run_clip, Actor(walk, "ref", ghost=True)], None, layout="lanes")
    roots = [c.positions[0, 0] for c in w.characters]
    assert abs(roots[0][1] - roots[1][1]) > 0.5  # walking along X: lanes apart in Y
    assert_allclose(roots[2], roots[0], atol=1e-9)  # the reference on the walk's lane, where it starts
    alone = world.build_world([walk, run_clip], None, layout="lanes")
    assert_allclose([c.positions[0, 0] for c in alone.characters], roots[:2], atol=1e-9)
