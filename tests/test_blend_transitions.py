"""The transitions of the paper's figures 12 and 13 (walk, run, walk at another speed, a fighting move,
another walk, a jump) and real-clip scripts, blended four ways and measured like with like
(:mod:`kinodyn.blend.evaluate`): synchronization and the foot lock each on and off, sliding on contacts
labelled on the source clips.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.blend import realclips
from kinodyn.blend.evaluate import ARMS, evaluate, lock_events, source_contacts, table
from kinodyn.phases import ERR, LS, RS
from kinodyn.blend.transitions import transition_script


@pytest.fixture(scope="module")
def builtin():
    results = {}
    figs = evaluate(transition_script(), results=results)
    print(table(figs, "built-in figure 12/13 script"))
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




def test_the_four_arms_differ_only_in_synchronization_and_the_lock(builtin):
    """Each arm is the same script with synchronization and the foot lock on or off, nothing else."""
    figs, results = builtin
    assert set(figs["arms"]) == {a for a, _, _ in ARMS}
    for name, sync, lock in ARMS:
        r = results[name]
        assert r.synchronized == sync
        held = np.isfinite(r.recording.lock_offsets())
        assert held.any() == lock, name   # the lock's displacement is recorded exactly when it runs
        assert figs["arms"][name]["frames"] == figs["arms"]["plain"]["frames"]


def test_headline_ratios_compare_arms_that_differ_only_in_synchronization(builtin):
    figs, _ = builtin
    a = figs["arms"]
    assert figs["sliding_ratio"] == pytest.approx(a["lock"]["sliding_cm_s"] / a["sync_lock"]["sliding_cm_s"])
    assert figs["sliding_ratio_sync_only"] == pytest.approx(a["plain"]["sliding_cm_s"] / a["sync"]["sliding_cm_s"])
    assert figs["lock_p95_ratio"] == pytest.approx(a["lock"]["lock_p95_cm"] / a["sync_lock"]["lock_p95_cm"])
    assert figs["pelvis_acc_ratio"] == pytest.approx(a["sync_lock"]["pelvis_acc"] / a["sync_lock"]["pelvis_acc_source"])
    assert figs["sliding_cm_s_synced"] == a["sync_lock"]["sliding_cm_s"]


def test_sliding_is_measured_on_the_source_clips_contacts_not_on_the_locks_vote(builtin):
    """The same frames are judged in every arm that plays the same actions at the same times: the
    source contacts of the plain and lock arms agree exactly (the lock changes the pose, not the
    frames that count)."""
    _, results = builtin
    a, b = source_contacts(results["plain"]), source_contacts(results["lock"])
    for s in ("left", "right"):
        assert np.array_equal(a[s], b[s]) and a[s].sum() > 300


def test_builtin_no_foot_is_under_two_support_constraints(builtin):
    figs, results = builtin
    assert figs["arms"]["sync_lock"]["err_frames"] == 0 and figs["arms"]["sync"]["err_frames"] == 0
    assert figs["arms"]["plain"]["err_frames"] > 10   # without synchronization right and left supports meet
    assert _no_foot_under_two_constraints(results["sync_lock"]).all()
    assert not _no_foot_under_two_constraints(results["plain"]).all()
    assert (results["sync_lock"].frame_phases() != ERR).all()


def test_builtin_every_action_starts_and_waits_at_most_a_few_elements(builtin):
    _, results = builtin
    for key, (asked, started) in results["sync_lock"].starts.items():
        assert started is not None and 0.0 <= started - asked < 0.6, (key, asked, started)


def test_synchronization_lets_the_lock_hold_feet_without_distorting_the_pose(builtin):
    """With the same foot lock, synchronization cuts sliding on the source clips' contacts at least 3x
    and the lock's displacement of held feet (p95) about 3x: the actions agree on the support, so the
    blended pose already puts the planted feet where they are held."""
    figs, _ = builtin
    s, l = figs["arms"]["sync_lock"], figs["arms"]["lock"]
    assert s["planted_frames"] > 800
    assert figs["sliding_ratio"] >= 3.0, figs["sliding_ratio"]
    assert s["sliding_cm_s"] < 1.5
    assert figs["lock_p95_ratio"] >= 2.5, figs["lock_p95_ratio"]
    assert s["lock_p95_cm"] < 6.0 and l["lock_p95_cm"] > 12.0
    assert s["lowest_foot_cm"] > -1.0


def test_max_foot_offset_bounds_the_displacement_the_evaluation_reports():
    """``max_foot_offset`` bounds all the lock does to a held foot, as measured: its root follow, the
    IK's offset and the height correction (up to 5.3 cm here). The height correction itself is never
    given up: without synchronization the blend puts feet up to 8 cm under the floor, and the lock
    lifts them that far whatever the bound."""
    figs = evaluate(transition_script(), max_foot_offset=0.06)
    s = figs["arms"]["sync_lock"]
    assert s["lock_max_cm"] <= 6.0 + 1e-6, s["lock_max_cm"]
    assert s["lowest_foot_cm"] > -1.0


def test_lock_events_find_where_the_lock_displaces_feet(builtin):
    """The events cover exactly the frames where a held foot is displaced beyond the threshold, worst
    first; the worst is the evaluation's maximum and names the foot and the actions playing there."""
    figs, results = builtin
    r = results["sync_lock"]
    off = np.nan_to_num(r.recording.lock_offsets()[:r.motion.num_frames] * 100.0, nan=0.0)
    events = lock_events(r, above_cm=3.0)
    assert sum(e["frames"] for e in events) == int((off.max(axis=1) > 3.0).sum()) > 0
    assert [e["peak_cm"] for e in events] == sorted((e["peak_cm"] for e in events), reverse=True)
    top = events[0]
    assert top["peak_cm"] == pytest.approx(figs["arms"]["sync_lock"]["lock_max_cm"], abs=1e-9)
    assert top["t0"] <= top["t_peak"] <= top["t1"]
    assert top[f"{top['foot']}_cm"] == pytest.approx(top["peak_cm"])
    assert top["weights"] and sum(top["weights"].values()) + top["neutral"] == pytest.approx(1.0, abs=0.05)
    spans = sorted((e["t0"], e["t1"]) for e in events)
    assert all(a[1] < b[0] for a, b in zip(spans, spans[1:]))


def test_builtin_time_warp_stays_within_a_fifth_to_two_and_a_half_times_the_clips_speed(builtin):
    """Equation 6 alone warped the run to 0.08x of its speed; the bounded step durations keep every
    visible action (5 % of the weight or more) within 0.23x-2.47x here (0.5x-2x where the spans of
    one step allow it)."""
    figs, _ = builtin
    s = figs["arms"]["sync_lock"]
    assert s["warp_rate_min"] >= 0.2 and s["warp_rate_max"] <= 2.5, (s["warp_rate_min"], s["warp_rate_max"])


_CMU = realclips.default_folder()


@pytest.mark.mocap
@pytest.mark.slow
def test_cmu_walk_run_walk_synchronized_holds_feet_within_3_cm():
    """Real CMU walk and run cycles: with the lock, synchronization keeps the held feet within 3 cm (p95)
    of the blended pose, over 2x closer than the lock without it, and sliding under 1.5 cm/s. The script
    starts and ends in the walk's own double support (no standing start: the lock holds the standing
    feet while the walk fades in, a separate cause measured by the standing script in the benchmark)."""
    script = realclips.walk_run_walk(_CMU, neutral=None)
    if script is None:
        pytest.skip("CMU walk and run clips not in the mocap folder")
    figs = evaluate(script)
    print(table(figs, script.name))
    s = figs["arms"]["sync_lock"]
    assert s["err_frames"] == 0 and figs["arms"]["plain"]["err_frames"] > 0
    assert s["lock_p95_cm"] < 3.0 and figs["lock_p95_ratio"] >= 2.0
    assert s["sliding_cm_s"] < 1.5


@pytest.mark.mocap
@pytest.mark.slow
@pytest.mark.parametrize("name", ["cmu_fig12", "cmu_walk_stumble", "cmu_walk_fall_getup"])
def test_cmu_scripts_synchronized_never_mix_a_right_and_a_left_support(name):
    scripts = realclips.scripts(_CMU)
    if name not in scripts:
        pytest.skip(f"clips of {name} not in the mocap folder")
    figs = evaluate(scripts[name])
    print(table(figs, name))
    assert figs["arms"]["sync_lock"]["err_frames"] == 0 and figs["arms"]["sync"]["err_frames"] == 0
    assert figs["arms"]["sync_lock"]["sliding_cm_s"] < figs["arms"]["sync"]["sliding_cm_s"]


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
    assert set(figs["arms"]) == {"plain", "sync", "lock", "sync_lock"}
    assert figs["arms"]["sync_lock"]["err_frames"] == 0
    assert any("foot sliding" in line for line in lines)


@pytest.mark.mocap
@pytest.mark.slow
def test_cmu_walk_to_run_neither_pops_nor_warps_a_clip_beyond_half_to_twice_its_speed():
    """Finding 2: the walk's single support (0.73 s) and the run's (0.13 s) shared one step, so the run
    played at 0.26x and then its flight at 1.84x (an 83 m/s^2 pelvis pop, 2.5x the sources' peak). With
    the walk's support held over the run's support and flight, every clip plays within 0.5x-2x of its
    speed and the pelvis accelerates no more than 1.2x the sources' peak."""
    script = realclips.walk_run_walk(_CMU)
    if script is None:
        pytest.skip("CMU walk and run clips not in the mocap folder")
    figs = evaluate(script)
    print(table(figs, script.name))
    s = figs["arms"]["sync_lock"]
    assert 0.5 <= s["warp_rate_min"] and s["warp_rate_max"] <= 2.0, (s["warp_rate_min"], s["warp_rate_max"])
    assert figs["pelvis_acc_ratio"] <= 1.2, figs["pelvis_acc_ratio"]
    assert s["err_frames"] == 0


@pytest.mark.mocap
@pytest.mark.slow
def test_cmu_walk_into_the_jump_slows_over_a_step_and_keeps_the_crouch():
    """Finding 6: walking into the jump, neither the walk nor the jump's crouch is warped beyond 0.5x-2x;
    the root brakes no harder than 1.2x the sources' peak deceleration (the old overlay: 15.9 m/s^2 in
    0.1 s, 1.8x), and the pelvis drops into the crouch by at least 10 cm before take-off (5 cm when the
    crouch was played at 3x; the jump clip's own crouch is 18 cm)."""
    from kinodyn.blend.evaluate import DECEL_WINDOW, WARP_WEIGHT, source_peaks
    from kinodyn.blend.mixer import BlendConfig
    from kinodyn.blend.script import run_script
    from kinodyn.blend.sync import SyncConfig

    script = realclips.scripts(_CMU).get("cmu_fig12")
    if script is None:
        pytest.skip("clips of cmu_fig12 not in the mocap folder")
    cfg = BlendConfig(sync=SyncConfig(nk=script.nk), constraints="on", ramp_in=script.ramp_in,
                      ramp_out=script.ramp_out)
    r = run_script(script, config=cfg)
    rec = r.recording.arrays()
    fps = r.motion.fps
    for key in ("walk_again", "jump@11.8"):
        h, w = rec[key]
        near = np.arange(len(h) - 1) / fps >= 11.5
        ok = near & np.isfinite(np.diff(h)) & (w[1:] >= WARP_WEIGHT) & (w[:-1] >= WARP_WEIGHT)
        rate = np.diff(h)[ok] * fps
        assert rate.min() >= 0.5 and rate.max() <= 2.0, (key, rate.min(), rate.max())
    seg = r.motion.root_pos[int(11.5 * fps):int(13.0 * fps)]  # from the walk's last steps to the landing
    speed = np.linalg.norm(np.diff(seg[:, :2], axis=0), axis=1) * fps
    w = int(round(DECEL_WINDOW * fps))
    braking = -np.diff(np.convolve(speed, np.ones(w) / w, mode="valid")).min() * fps  # as the evaluation does
    assert braking <= 1.2 * source_peaks(r)["root_decel"], (braking, source_peaks(r)["root_decel"])
    crouch = r.motion.root_pos[int(11.8 * fps), 2] - seg[:, 2].min()
    assert crouch >= 0.10, crouch
