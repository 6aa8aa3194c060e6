"""kinodyn.viz.objects and kinodyn.viz.recording: props, forces, stages, markers, lanes, sides, centre of mass,
and the balls of a physics world recorded for the viewer. Checked as data here; test_viz_features.py opens
the pages in a browser."""

from __future__ import annotations

import itertools
import json
import re

import numpy as np
import pytest
from numpy.testing import assert_allclose

from kinodyn.data import library
from kinodyn.errors import ParameterError
from kinodyn.plotting import style
from kinodyn.viz import html, world
from kinodyn.viz.objects import (
    Forces,
    Marker,
    Prop,
    Stages,
    centre_of_mass,
    face_points,
    lane_offsets,
    point_sides,
)

_TOL = 1e-9


def page_data(text: str) -> dict:
    m = re.search(r'<script type="application/json" id="kinodyn-data">(.*?)</script>', text, re.DOTALL)
    return json.loads(m.group(1).replace("<\\/", "</"))


@pytest.fixture(scope="module")
def walk():
    return library.load("walk")


def test_centre_of_mass_matches_a_loop_over_capsules(rng):
    pos = rng.normal(size=(4, 5, 3))
    parents = np.array([-1, 0, 1, 1, 3])
    radii = np.array([0.0, 0.1, 0.05, 0.08, 0.02])
    want = np.zeros((4, 3))
    for f in range(4):
        num, den = np.zeros(3), 0.0
        for p in range(1, 5):
            a, b = pos[f, parents[p]], pos[f, p]
            w = np.pi * radii[p] ** 2 * np.linalg.norm(b - a) + 4 / 3 * np.pi * radii[p] ** 3
            num += w * (a + b) / 2
            den += w
        want[f] = num / den
    assert_allclose(centre_of_mass(pos, parents, radii), want, atol=_TOL)


def test_centre_of_mass_of_a_standing_body_is_over_its_feet(walk):
    pos, parents, names = world.body_points(walk)
    radii = world.bone_radii(names, parents, walk.skeleton.height())
    com = centre_of_mass(pos, parents, radii)
    assert np.all((com[:, 2] > 0.7) & (com[:, 2] < 1.2)), "a walker's centre of mass is near the hips"
    assert np.all(np.linalg.norm(com[:, :2] - pos[:, 0, :2], axis=1) < 0.15)


def test_point_sides_from_names():
    names = ["Hips", "LeftUpLeg", "RightUpLeg", "LeftHand_end", "lfemur", "rhumerus", "Spine", "l_wrist", "hand_r"]
    assert point_sides(names).tolist() == [0, -1, 1, -1, -1, 1, 0, -1, 1]


def test_face_points_say_where_the_walker_faces(walk):
    pos, _, names = world.body_points(walk)
    sides = point_sides(names)
    face = face_points(names, sides, pos)
    assert names[face["head"]] == "Head"
    assert (names[face["left"]], names[face["right"]]) == ("LeftShoulder", "RightShoulder")
    lat = pos[:, face["right"], :2] - pos[:, face["left"], :2]
    facing = np.stack([-lat[:, 1], lat[:, 0]], axis=1)
    facing /= np.linalg.norm(facing, axis=1, keepdims=True)
    travel = pos[-1, 0, :2] - pos[0, 0, :2]
    assert np.mean(facing @ (travel / np.linalg.norm(travel))) > 0.9, "up x (right - left) is the way it walks"


def test_lanes_go_across_the_direction_of_travel(walk):
    """Regression: the row layout lined walkers up along their walking direction, into each other's lane."""
    moved = walk.transformed(np.array([0.4, 0.3, 0.0]))  # the same walk, a little ahead and aside
    pos = [world.body_points(m)[0] for m in (walk, moved, walk)]
    off = lane_offsets(pos)
    travel = pos[0][-1, 0, :2] - pos[0][0, 0, :2]
    d = travel / np.linalg.norm(travel)
    n = np.array([d[1], -d[0]])
    along = [o[:2] @ d for o in off]
    assert_allclose(along, 0.0, atol=1e-9, err_msg="lanes keep each character's place along its travel")
    spans = sorted((((p[..., :2].reshape(-1, 2) + o[:2]) @ n).min(), ((p[..., :2].reshape(-1, 2) + o[:2]) @ n).max())
                   for p, o in zip(pos, off))
    for (_, a1), (b0, _) in itertools.pairwise(spans):
        assert b0 > a1, "the lanes' sweeps across the direction of travel do not overlap"


def test_lanes_layout_in_a_page(walk):
    w = world.build_world({"a": walk, "b": walk}, None, layout="lanes")
    gap = np.linalg.norm(w.characters[0].positions[0, 0, :2] - w.characters[1].positions[0, 0, :2])
    assert gap > 0.5
    assert w.view is not None and w.view[2] > 0.3


def test_props_forces_markers_and_stages_reach_the_page(walk):
    t = np.arange(30) / 60
    ball = Prop("sphere", np.stack([t, 0 * t, 1 + t], axis=1), (0.11,), fps=60, start=0.5, label="ball")
    crate = Prop("box", (1.0, 0.0, 0.25), (0.3, 0.2, 0.25), quats=(1.0, 0.0, 0.0, 0.0))
    cap = Prop("capsule", (0.0, 1.0, 0.5), (0.1, 0.3))
    tri = Prop("mesh", (0.0, -1.0, 0.0), vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]])
    forces = Forces([0.2, 0.1], [(0, 0, 1), (0, 0, 1.1)], [(-100, 0, 0), (0, 50, 0)], character=0)
    stages = Stages([(0.0, 1.0, "motion data"), (1.0, 2.0, "simulation")], character=0)
    text = html.to_html(walk, ["contacts", "phases", ball, crate, cap, tri, forces, Marker(1.0, "hit"), stages])
    s = page_data(text)["scenes"][0]
    assert [p["shape"] for p in s["props"]] == ["sphere", "box", "capsule", "mesh"]
    back = html.decode_positions(s["props"][0]["pos"], 30, 1)[:, 0]
    assert_allclose(back, ball.positions, atol=0.5 * max(s["props"][0]["pos"]["scale"]) + 1e-9)
    assert s["props"][0]["start"] == 0.5 and s["props"][1]["quat"] == [1.0, 0.0, 0.0, 0.0]
    assert s["forces"][0]["t"] == [0.1, 0.2], "forces sorted by time"
    assert s["markers"] == [{"t": 1.0, "label": "hit", "color": "#333333"}]
    bars = {p["label"]: p for p in s["phases"]}
    assert set(bars) == {"walk support", "stages"}, "stages add a bar; the support bar stays"
    assert bars["stages"]["colors"]["simulation"] == style.STAGE_COLORS["simulation"]
    assert bars["stages"]["tint"] is False and bars["walk support"]["tint"] is False
    tinted = page_data(html.to_html(walk, [Stages(stages.spans, 0, tint=True)]))["scenes"][0]["phases"]
    assert [p["tint"] for p in tinted] == [True], "a tinted stage bar tells the page to colour the body"
    data = page_data(text)
    assert data["phaseColors"] == style.PHASE_COLORS and data["stageColors"] == style.STAGE_COLORS
    ch = s["characters"][0]
    assert ch["pointNames"][0] == "Hips" and ch["sides"][ch["pointNames"].index("LeftHand")] == -1


@pytest.mark.parametrize("prop, match", [
    (Prop("cone", (0, 0, 0)), "shape must be one of"),
    (Prop("box", (0, 0, 0), (1.0, 2.0)), "needs 3 positive size"),
    (Prop("sphere", np.zeros((4, 2))), r"shape \(F, 3\)"),
    (Prop("sphere", [np.nan, 0, 0]), "finite"),
    (Prop("mesh", (0, 0, 0), vertices=[[0, 0, 0]], faces=[[0, 1, 2]]), "face indices"),
    (Prop("sphere", np.zeros((3, 3)), quats=np.ones((2, 4))), r"quats must have shape \(3, 4\)"),
])
def test_bad_props_are_refused(walk, prop, match):
    with pytest.raises(ParameterError, match=match):
        world.build_world(walk, [prop])


def test_bad_forces_and_stages_are_refused(walk):
    with pytest.raises(ParameterError, match=r"shape \(2, 3\)"):
        world.build_world(walk, [Forces([0, 1], np.zeros((3, 3)), np.zeros((2, 3)))])
    with pytest.raises(ParameterError, match="kind must be"):
        world.build_world(walk, [Forces([0], [(0, 0, 0)], [(1, 0, 0)], kind="torque")])
    with pytest.raises(ParameterError, match="stop >= start"):
        world.build_world(walk, [Stages([(1.0, 0.5, "clip")])])
    with pytest.raises(ParameterError, match="character index"):
        world.build_world(walk, [Forces([0], [(0, 0, 0)], [(1, 0, 0)], character=3)])


def test_the_ball_of_a_hit_is_recorded_from_the_physics_world(walk):
    pytest.importorskip("mujoco")
    from kinodyn.data.skeleton import humanoid
    from kinodyn.physics.world import World
    from kinodyn.viz.recording import ObjectRecorder

    w = World()
    c = w.add_character(humanoid(), name="walker")
    c.play(walk, loop=True)
    ball = w.throw(c, "chest", mass=4.0, radius=0.11, speed=9.0, direction=np.pi / 2, height=1.5, at=0.5)
    rec = ObjectRecorder(w)
    seen = []
    for _ in range(50):
        rec.step()
        seen.append((w.time, ball.position if ball.active else None))
    overlays = rec.overlays(["walker"], forces=True)
    props = [o for o in overlays if isinstance(o, Prop)]
    assert len(props) == 1 and props[0].size == (0.11,) and props[0].hide_outside
    live = [(t, p) for t, p in seen if p is not None]
    assert props[0].start == pytest.approx(live[0][0])
    assert_allclose(props[0].positions[-1], live[-1][1], atol=_TOL)
    hits = [o for o in overlays if isinstance(o, world.Impact)]
    assert hits and all(h.character == 0 for h in hits)
    # the ball is where the impact is when it lands
    k = round((hits[0].time - props[0].start) * props[0].fps)
    assert np.linalg.norm(props[0].positions[k] - hits[0].point) < 0.11 + 0.05
    assert any(isinstance(o, Forces) for o in overlays)


def test_the_benchmark_scenes_are_what_their_keys_say():
    """``page_fps_500`` and ``page_fps_scene`` measure a 500-character page and a 20-object scene."""
    from kinodyn.viz.bench import crowd_scene, object_scene

    crowd = crowd_scene(500, 30)
    assert len(crowd) == 500 and all(m.num_frames == 30 for m in crowd)
    motions, overlays = object_scene()
    props = [o for o in overlays if isinstance(o, Prop)]
    assert len(props) == 20 and {p.shape for p in props} == {"sphere", "box", "capsule", "mesh"}
    assert any(isinstance(o, Forces) for o in overlays)
    w = world.build_world(motions, ["contacts", *overlays])
    assert len(w.props) == 20 and len(w.characters) == 2
