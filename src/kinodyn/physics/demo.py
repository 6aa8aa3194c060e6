"""Demo part "physics": a walking character hit by a ball, and a punch that lands.

1. The built-in walk plays kinematically; a 4 kg ball thrown from the side arrives at the chest at
   t = 1 s. On contact the character turns dynamic, its servos go soft for 0.3 s (stiffness 0.2), then
   stiffen again toward the walk; the simulated motion is written as ``walk_hit.bvh`` next to the clip
   it started from (``walk_kinematic.bvh``).
2. Two characters 0.95 m apart: one plays the built-in punch, the other idles; when the fist lands both
   turn dynamic (the paper's "human opponent" in place of the ball), the attacker's servos keep
   tracking the punch and the defender's go soft for 0.25 s (``fight_attacker.bvh``,
   ``fight_defender.bvh``).

Also written: ``body.xml`` (the humanoid's MJCF, which MuJoCo loads) and ``impacts.json`` (every
impact: time, body, world point, impulse). Everything is written atomically.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["demo"]


def _walk_hit(walk, body):
    from kinodyn.physics.world import World

    w = World()
    c = w.add_character(body, name="walker")
    c.play(walk, loop=True)
    ball = w.throw(c, "chest", mass=4.0, radius=0.11, speed=9.0, direction=np.pi / 2, height=1.5, at=1.0)
    p_ball = None
    while c.mode == "kinematic" and w.time < 2.0:
        p_ball = ball.momentum
        w.step()
    hit = w.time
    c.set_gains(0.2)
    w.run(0.3)
    c.set_gains(1.0)
    w.run(max(0.0, 3.0 - w.time))
    return w, c, ball, hit, p_ball


def _fight(body):
    from kinodyn.data import library
    from kinodyn.physics.world import World

    w = World()
    a = w.add_character(body, name="attacker", at=(0.0, 0.0, 0.0))
    b = w.add_character(body, name="defender", at=(0.95, 0.0, np.pi))
    a.play(library.load("punch"), at=(0.0, 0.0, 0.0))
    b.play(library.load("idle"), at=(0.95, 0.0, np.pi), loop=True)
    while b.mode == "kinematic" and w.time < 1.2:
        w.step()
    hit = w.time
    if b.mode == "dynamic":
        b.set_gains(0.3)
        w.run(0.25)
        b.set_gains(1.0)
    w.run(max(0.0, 2.0 - w.time))
    return w, a, b, hit


def demo(out: Path) -> list[str]:
    from kinodyn.data import library
    from kinodyn.data.skeleton import humanoid
    from kinodyn.io import save
    from kinodyn.io.atomic import atomic_write_bytes
    from kinodyn.physics.body import build_body

    out = Path(out) / "physics"
    out.mkdir(parents=True, exist_ok=True)
    lines = []
    body = build_body(humanoid())
    atomic_write_bytes(out / "body.xml", body.to_xml().encode())
    lines.append(f"body.xml: {body.map.num_bodies} bodies, {body.map.nu} servo controls, {body.total_mass:.0f} kg")

    walk = library.load("walk")
    w, c, _ball, hit, p_ball = _walk_hit(walk, body)
    sim = c.trajectory()
    save(out / "walk_hit.bvh", sim)
    save(out / "walk_kinematic.bvh", walk.resample(w.config.fps))
    imps = [i for i in w.impacts if i.character == "walker"]
    total = np.sum([i.impulse for i in imps], axis=0) if imps else np.zeros(3)
    hit = imps[0].time if imps else hit
    lines.append(f"walk_hit.bvh: {sim.num_frames} frames; ball hit at t={hit:.3f} s on "
                 f"{', '.join(sorted({i.body for i in imps}))}; impulse {np.linalg.norm(total):.1f} N s "
                 f"(ball momentum {np.linalg.norm(p_ball) if p_ball is not None else 0:.1f} kg m/s)")

    wf, a, b, _fhit = _fight(body)
    save(out / "fight_attacker.bvh", a.trajectory())
    save(out / "fight_defender.bvh", b.trajectory())
    fimps = [i for i in wf.impacts if i.character == "defender"]
    if fimps:
        first = fimps[0]
        lines.append(f"fight_*.bvh: the punch landed at t={first.time:.3f} s on the defender's {first.body} "
                     f"({np.linalg.norm(first.impulse):.1f} N s); the defender turned {b.mode}")
    else:
        lines.append("fight_*.bvh: the punch did not land")
    log = {"walk_hit": [i.to_json() for i in w.impacts], "fight": [i.to_json() for i in wf.impacts]}
    atomic_write_bytes(out / "impacts.json", (json.dumps(log, indent=2) + "\n").encode())
    lines.append(f"impacts.json: {len(log['walk_hit'])} + {len(log['fight'])} impacts")
    return lines
