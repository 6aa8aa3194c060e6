"""The kinematic-to-dynamic switch swept over whole cycles, and clips played on a capture floor that is
not level (real motion capture: CMU 02_01)."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from conftest import mocap_files
from kinodyn.data import library
from kinodyn.data.skeleton import humanoid
from kinodyn.physics.assembly import lowest_point
from kinodyn.physics.body import build_body
from kinodyn.physics.state import character_state
from kinodyn.physics.tracking import PDConfig
from kinodyn.physics.world import World

_CMU_WALK = mocap_files("locomotion/cmu_02_01.bvh")

#: the issue's bounds one frame after a switch: position change (m), relative velocity change
_POS_TOL, _VEL_TOL = 0.005, 0.05


@pytest.fixture(scope="module")
def cmu_walk():
    if not _CMU_WALK:
        pytest.skip("../shared/mocap/locomotion/cmu_02_01.bvh not found")
    import kinodyn

    return kinodyn.load(_CMU_WALK[0])[1:].resample(60.0)  # frame 0 is the converter's T-pose


def switch_change(body, clip, t: float, loop: bool):
    """``(position change (m), body velocity change, com velocity change)`` one frame after switching
    ``clip`` to dynamic at ``t``, against the clip itself one frame on (relative velocity changes)."""
    w = World()
    c = w.add_character(body)
    c.play(clip, loop=loop)
    w.run(t)
    w.switch_to_dynamic(c)
    w.step()
    sim = character_state(w, c)
    r = World()
    rc = r.add_character(body)
    rc.play(clip, loop=loop)
    r.run(t + 1.0 / 60.0)
    ref = character_state(r, rc)
    return (np.abs(sim.pos - ref.pos).max(),
            np.linalg.norm(sim.linvel - ref.linvel) / np.linalg.norm(ref.linvel),
            np.linalg.norm(sim.com_vel - ref.com_vel) / np.linalg.norm(ref.com_vel))


def sweep(body, clip, times, loop):
    out = np.array([switch_change(body, clip, round(t * 60) / 60, loop) for t in times])
    print(f"switch sweep over {len(times)} times: position max {out[:, 0].max() * 100:.2f} cm, p95 "
          f"{np.percentile(out[:, 0], 95) * 100:.2f} cm; body velocity max {out[:, 1].max():.1%}, p95 "
          f"{np.percentile(out[:, 1], 95):.1%}; com velocity max {out[:, 2].max():.1%}, p95 "
          f"{np.percentile(out[:, 2], 95):.1%}")
    return out


@pytest.mark.mocap
def test_cmu_walk_stance_foot_stays_on_a_rising_capture_floor(cmu_walk):
    """CMU 02_01's capture floor rises about 4 cm over the walk; one median offset left the feet 4.7 cm
    inside the floor at the start and 1.9 cm above it at the end. Played with ``align_floor``, the body's
    lowest point touches the floor in every quarter second of the walk (a walk always has a foot down)."""
    body = build_body(cmu_walk.skeleton)
    w = World()
    c = w.add_character(body)
    c.play(cmu_walk)
    m, d = w.model, w.data
    lows = []
    for _ in range(cmu_walk.num_frames - 1):
        w.step()
        mujoco.mj_kinematics(m, d)
        lows.append(lowest_point(m, d, c.geom_ids))
    lows = np.array(lows)
    window = 15
    per_window = np.array([lows[i:i + window].min() for i in range(0, len(lows) - window + 1, window)])
    print(f"lowest point per 0.25 s: {np.round(per_window * 1000, 1)} mm")
    assert np.abs(per_window).max() < 0.005
    assert lows.min() > -0.005  # no foot sinks into the floor


@pytest.mark.xfail(strict=True, reason=(
    "open: one frame after a switch the body is 13.8 % (built-in walk), 11.7 % (run) and 22.6 % (CMU "
    "02_01) off the clip at worst, 0.74-1.39 cm. Measured causes: the built-in walk at 0.13 s asks for "
    "more horizontal force than friction allows (672 N against 538 N vertical, mu = 1); on its toes "
    "(0.38 s) the stance foot carries the body only through the ankle, whose servo carries nothing with "
    "the default 'static' feedforward (the ground gives 37 of 539 N) and with 'dynamics' at most its "
    "gain times a turn of its target (kp 42 N m/rad against up to 154 N m: 293 N); a pushing-off toe's "
    "servo (kp 2 N m/rad) buckles under the push-off; on CMU 02_01 nothing touches the ground at 8 of "
    "the 12 times (the stance foot's lowest point rises and sinks about 8 mm within each stance above "
    "the fitted floor, so the body falls for the frame); and with the clip's exact inverse-dynamics "
    "forces applied (no ground, no servos, no joint damping) the run's toes already end 0.58 cm from "
    "the clip one frame on (its finite-difference velocities integrated by the engine's steps)"))
@pytest.mark.parametrize("name", ["walk", "run", "cmu_02_01"])
def test_switch_is_continuous_at_any_time_of_a_cycle(name, request):
    if name == "cmu_02_01":
        clip = request.getfixturevalue("cmu_walk")
        body, loop = build_body(clip.skeleton), False
        times = np.linspace(0.2, clip.duration - 0.3, 12)
    else:
        clip = library.load(name)
        body, loop = build_body(humanoid()), True
        times = np.arange(12) * (min(clip.duration, 1.0) / 12) + 0.05
    out = sweep(body, clip, times, loop)
    assert out[:, 0].max() < _POS_TOL
    assert out[:, 1].max() < _VEL_TOL and out[:, 2].max() < _VEL_TOL



def test_dynamics_feedforward_follows_the_run_from_any_switch_time():
    """With ``feedforward="dynamics"`` the servos carry the clip's inverse dynamics (the ground's forces
    at the pose's own contacts, ankles included, no lookahead), so one frame after a switch at any of
    12 times of a cycle of the built-in run the body is within 0.85 cm and 9.0 % (body velocities), 5.3 %
    (centre of mass) of the clip. Measured before: 1.3 cm, 13.3 %, 8.1 % (the same mode with the weight
    split between the soles, ankles carrying nothing) and 1.14 cm, 11.7 %, 8.0 % (``"static"``)."""
    body = build_body(humanoid(), pd=PDConfig(feedforward="dynamics"))
    clip = library.load("run")
    out = sweep(body, clip, np.arange(12) * (min(clip.duration, 1.0) / 12) + 0.05, True)
    assert out[:, 0].max() < 0.01
    assert out[:, 1].max() < 0.10 and out[:, 2].max() < 0.06


def test_dynamics_feedforward_lets_the_ground_carry_a_body_on_its_toes():
    """At 23/60 s of the built-in walk the stance foot is on its toes (heel up): the ground can carry the
    body only as far as the ankle pushes. With ``"static"`` the ankles carry nothing and the ground gave
    37 of the 539 N the clip needs over the first frame after a switch (the centre of mass fell 0.12 m/s
    behind the clip); with ``"dynamics"`` the ankle carries its share up to a turn of its target, and the
    ground 293 N."""
    clip = library.load("walk")
    falls = {}
    for ff in ("static", "dynamics"):
        body = build_body(humanoid(), pd=PDConfig(feedforward=ff))
        w = World()
        c = w.add_character(body)
        c.play(clip, loop=True)
        w.step(23)
        w.switch_to_dynamic(c)
        w.step()
        r = World()
        rc = r.add_character(body)
        rc.play(clip, loop=True)
        r.step(24)
        falls[ff] = character_state(r, rc).com_vel[2] - character_state(w, c).com_vel[2]
    print(f"centre of mass behind the clip one frame after the switch (m/s): {falls}")
    assert falls["static"] > 0.1  # the case is what it says: without the ankle the ground carries little
    assert abs(falls["dynamics"]) < 0.07


def test_stance_sole_touches_the_ground_in_every_step_of_playback():
    """Regression: the built-in walk's stance sole was played exactly on the floor plane, so it touched
    the ground or not by the last bit of a float (no ground contact in about half the physics steps), and
    so did the ground's support in the first steps after a switch (clips 1e-12 m apart gave 4.1 % and
    6.8 % body velocity change one frame after a switch at 1 s). Played at the depth a standing body
    rests in, a walk (always a foot down) touches the ground in every step."""
    body = build_body(humanoid())
    w = World(fps=240, substeps=1)
    c = w.add_character(body)
    c.play(library.load("walk"), loop=True)
    ground = w.model.geom("ground").id
    touching = []
    for _ in range(240):
        w.step()
        g = w.data.contact.geom[:w.data.ncon]
        touching.append(bool(np.any(g == ground)))
    assert all(touching), f"no ground contact in {touching.count(False)} of 240 steps"
