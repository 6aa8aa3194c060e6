"""The transitions of the paper's figures 12 and 13: walk, run, walk at another speed, a fighting move,
another walk, a jump, blended with and without synchronization.

Foot sliding is the horizontal speed of a foot's lowest point (the measure of :mod:`kinodyn.contacts`)
over the frames where the actions' support phases put that foot down; see
:func:`kinodyn.blend.script.sliding_report`.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.blend.demo import sliding_figures, transition_script
from kinodyn.phases import ERR, LS, RS


@pytest.fixture(scope="module")
def builtin():
    results = {}
    figs = sliding_figures(transition_script(), results=results)
    return figs, results


def _no_foot_under_two_constraints(result):
    """At no frame do two contributing actions put different single feet down (RS with LS)."""
    from kinodyn.blend.plots import action_phase_track

    keys = list(result.actions)
    tracks = [action_phase_track(result, k) for k in keys]
    rs = np.zeros(result.motion.num_frames, bool)
    ls = np.zeros_like(rs)
    for codes, on in tracks:
        rs |= on & (codes == RS)
        ls |= on & (codes == LS)
    return ~(rs & ls)


def test_builtin_clips_slide_5x_less_with_synchronization(builtin):
    figs, _ = builtin
    _report("built-in figure 12/13 script", figs)
    s, u = figs["synced"], figs["unsynced"]
    assert s["planted_frames"] > 800 and u["planted_frames"] > 800
    assert figs["sliding_ratio"] >= 5.0, figs["sliding_ratio"]
    assert figs["sliding_ratio_transitions"] >= 5.0, figs["sliding_ratio_transitions"]
    assert s["sliding_cm_s"] < 4.0
    # the foundation's measure on contacts detected on the result agrees. It only sees feet slower than
    # the detector's 0.35 m/s, so it misses most of the unsynchronized sliding (its ratio is lower), and
    # what remains synchronized is mostly the clips' own landings: less than the built-in walk's 0.7 cm/s.
    assert figs["sliding_ratio_detected"] >= 4.0, figs["sliding_ratio_detected"]
    assert s["detected_sliding_cm_s"] < 0.7


def test_planted_feet_do_not_sink_into_the_floor(builtin):
    """Blending poses of different root heights pushes feet through the floor (the plain blend by up to
    about 4 cm); held feet stay at least at the height the actions' planted feet have (2.5 cm here, the
    sole), and synchronized feet never go below it by more than a few millimetres."""
    from kinodyn.contacts import foot_points

    _, results = builtin
    lows = {}
    for name in ("synced", "unsynced"):
        p = foot_points(results[name].motion)
        lows[name] = min(float(p[s][..., 2].min()) for s in p)
    assert lows["unsynced"] < -0.02
    assert lows["synced"] > 0.02


def test_builtin_no_foot_is_under_two_support_constraints(builtin):
    figs, results = builtin
    assert figs["synced"]["err_frames"] == 0
    assert figs["unsynced"]["err_frames"] > 10   # without synchronization right and left supports meet
    assert _no_foot_under_two_constraints(results["synced"]).all()
    assert not _no_foot_under_two_constraints(results["unsynced"]).all()
    assert (results["synced"].frame_phases() != ERR).all()


def test_builtin_every_action_starts_and_waits_at_most_a_few_elements(builtin):
    _, results = builtin
    for key, (asked, started) in results["synced"].starts.items():
        assert started is not None and 0.0 <= started - asked < 0.6, (key, asked, started)


def test_builtin_synchronization_is_what_keeps_feet_planted(builtin):
    """Ablations: synchronization alone already halves the plain blend's sliding; the support
    constraints need synchronization to be at their best."""
    figs, _ = builtin
    assert figs["synced_plain"]["sliding_cm_s"] < 0.7 * figs["unsynced"]["sliding_cm_s"]
    assert figs["synced"]["sliding_cm_s"] < figs["unsynced_constrained"]["sliding_cm_s"]


def _cmu_script(mocap, fight=("cmu_135_06-martialArts.amc", 8.9, 11.1)):
    """Figures 12/13 with real CMU clips of four subjects, retargeted to the walker's skeleton: one
    cycle of a slow walk and of a run (heel strike to heel strike), a fighting move, a forward jump.
    The default fighting move is a karate kata stretch that steps into a stance and blocks (subject
    135)."""
    from kinodyn.blend.script import parse_script

    loco = mocap / "locomotion"
    name, a, b = fight
    return parse_script({
        "name": "cmu_fig12", "fps": 60, "ramp_in": 0.5, "ramp_out": 0.5,
        "clips": {
            "walk": {"file": str(loco / "cmu_07_05-walk.amc"), "fps": 60, "start": 0.3167, "stop": 1.9167,
                     "cyclic": True},
            "run": {"file": str(loco / "cmu_09_06-run.amc"), "fps": 60, "start": 0.2833, "stop": 1.0167,
                    "cyclic": True},
            "fight": {"file": str(mocap / "fighting" / name), "fps": 60, "start": a, "stop": b},
            "jump": {"file": str(loco / "cmu_01_01.amc"), "fps": 60, "start": 1.0, "stop": 3.2}},
        "actions": [
            {"clip": "walk", "start": 0.0, "stop": 3.0, "priority": 1},
            {"clip": "run", "start": 2.8, "stop": 6.0, "priority": 1},
            {"clip": "walk", "start": 5.8, "stop": 8.5, "priority": 1, "speed": 1.3, "key": "fast_walk"},
            {"clip": "fight", "start": 8.2, "priority": 2},
            {"clip": "walk", "start": 9.6, "stop": 12.0, "priority": 1, "key": "walk_again"},
            {"clip": "jump", "start": 11.8, "priority": 2}]})


def _report(label, figs):
    s, u = figs["synced"], figs["unsynced"]
    print(f"{label}: sliding {s['sliding_cm_s']:.2f} vs {u['sliding_cm_s']:.2f} cm/s (x{figs['sliding_ratio']:.1f}), "
          f"transitions x{figs['sliding_ratio_transitions']:.1f}, detected contacts "
          f"{s['detected_sliding_cm_s']:.2f} vs {u['detected_sliding_cm_s']:.2f} cm/s "
          f"(x{figs['sliding_ratio_detected']:.1f}); RS+LS frames {s['err_frames']} vs {u['err_frames']}")


def _need(mocap_dir, files):
    for f in files:
        if not (mocap_dir / f).exists():
            pytest.skip(f"{f} not in the mocap folder")


_CMU_FILES = ("locomotion/cmu_07_05-walk.amc", "locomotion/cmu_09_06-run.amc", "locomotion/cmu_01_01.amc")


@pytest.mark.mocap
@pytest.mark.slow
def test_cmu_clips_transitions(mocap_dir):
    """Real CMU clips: synchronization removes every frame where a right and a left single support
    meet and cuts sliding at least 5x, on the planted frames the actions intend and on the contacts
    detected on the result (the foundation's measure)."""
    _need(mocap_dir, _CMU_FILES + ("fighting/cmu_135_06-martialArts.amc",))
    results = {}
    figs = sliding_figures(_cmu_script(mocap_dir), results=results)
    _report("CMU figure 12/13 script, kata stepping block", figs)
    assert figs["synced"]["err_frames"] == 0 and figs["unsynced"]["err_frames"] > 0
    assert _no_foot_under_two_constraints(results["synced"]).all()
    assert figs["sliding_ratio"] >= 5.0, figs["sliding_ratio"]
    assert figs["sliding_ratio_transitions"] >= 5.0, figs["sliding_ratio_transitions"]
    assert figs["sliding_ratio_detected"] >= 5.0, figs["sliding_ratio_detected"]
    assert figs["synced"]["sliding_cm_s"] < figs["synced_plain"]["sliding_cm_s"]


@pytest.mark.mocap
@pytest.mark.slow
@pytest.mark.parametrize("fight", [("cmu_135_06-martialArts.amc", 3.75, 5.65), ("cmu_135_06-martialArts.amc", 6.4, 8.95),
                                   ("cmu_11_01.amc", 1.6, 4.3)], ids=["kata-3.75s", "kata-6.4s", "soccer-kick"])
def test_cmu_other_fighting_moves_that_step(mocap_dir, fight):
    """Other stretches of the kata, and a kick with a run-up: moves that step into their stance."""
    _need(mocap_dir, _CMU_FILES + ("fighting/" + fight[0],))
    figs = sliding_figures(_cmu_script(mocap_dir, fight))
    _report(f"CMU script with {fight[0]} {fight[1]:g}-{fight[2]:g} s", figs)
    assert figs["synced"]["err_frames"] == 0
    assert figs["sliding_ratio"] >= 5.0, figs["sliding_ratio"]
    assert figs["sliding_ratio_detected"] >= 5.0, figs["sliding_ratio_detected"]


@pytest.mark.mocap
@pytest.mark.slow
def test_cmu_punch_without_a_step_still_slides_where_the_stance_changes(mocap_dir):
    """The limit of blending: a punch thrown from a fixed stance (subject 02) never lifts a foot, so the
    change from the walk's stance to the fighter's happens with both feet down and the feet must slide
    (or stretch the legs) whatever the synchronization does. The gain is smaller, about 4x."""
    _need(mocap_dir, _CMU_FILES + ("fighting/cmu_02_05.amc",))
    figs = sliding_figures(_cmu_script(mocap_dir, ("cmu_02_05.amc", 2.0, 4.5)))
    _report("CMU script with the 02_05 punch (no step)", figs)
    assert figs["synced"]["err_frames"] == 0
    assert figs["sliding_ratio"] >= 3.0, figs["sliding_ratio"]
    assert figs["sliding_ratio_detected"] >= 4.0, figs["sliding_ratio_detected"]


@pytest.mark.slow
def test_demo_part_writes_bvh_plots_and_figures(tmp_path):
    import json

    from kinodyn.blend.demo import demo
    from kinodyn.io import load

    lines = demo(tmp_path)
    d = tmp_path / "blend"
    for name in ("fig12_synced.bvh", "fig12_unsynced.bvh"):
        assert load(d / name).num_frames > 800
    for name in ("fig12_phases.png", "fig12_timewarp.png", "fig12_feet.png"):
        assert (d / name).stat().st_size > 20_000
    figs = json.loads((d / "sliding.json").read_text())
    assert figs["sliding_ratio"] >= 5.0 and figs["synced"]["err_frames"] == 0
    assert any("foot sliding" in line for line in lines)
