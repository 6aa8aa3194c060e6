"""``kinodyn crowd run|impacts``: simulate a crowd of keyframe characters, or the impact experiment.

* ``kinodyn crowd run --n 200 --seconds 20 [--push K] [--balls K] [--behaviour mix] -o out/`` writes
  ``crowd.npz`` (every character's posed motion, controller states and body states) or one BVH per
  character (``--format bvh``), a viewer page ``crowd.html`` (kinodyn.viz.html) and a snapshot PNG.
* ``kinodyn crowd impacts -o out/`` generates the 54 reactions of section 6 (``reactions.npz`` and a
  BVH each), trains the automatic observer on other seeds and writes its table beside the paper's
  human subjects (``observer.json``) and a contact sheet (``impacts.png``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from kinodyn.errors import KinodynError

HELP = "simulate a crowd of keyframe characters (run) or the 54-reaction impact experiment (impacts)"
DESCRIPTION = ("Single-rigid-body characters balanced by an inverted-pendulum controller and posed from "
               "a multidimensional keyframe set (Mitake et al.). 'run' simulates a pushed crowd; 'impacts' "
               "runs the impact experiment with an automatic observer.")
_BEHAVIOURS = ("mix", "idle", "wander", "goto", "follow", "flee")


def add_arguments(p) -> None:
    p.add_argument("action", choices=["run", "impacts"], help="what to do")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--n", type=int, default=200, help="characters (run; default 200)")
    p.add_argument("--seconds", type=float, default=20.0, help="seconds to simulate (run; default 20)")
    p.add_argument("--push", type=int, default=30, help="random pushes during the run (default 30)")
    p.add_argument("--balls", type=int, default=6, help="balls thrown into the crowd (default 6)")
    p.add_argument("--behaviour", choices=_BEHAVIOURS, default="mix", help="what the characters do")
    p.add_argument("--format", choices=["npz", "bvh"], default="npz", help="motion output (run)")
    p.add_argument("--keyframes", help="a keyframe-set file (.json, .yaml) instead of the built-in one")
    p.add_argument("--viewer-fps", type=float, default=30.0, help="frame rate of the viewer page (default 30)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--train-seeds", type=int, default=8, help="observer training seeds (impacts; default 8)")
    p.add_argument("--test-seeds", type=int, default=3, help="observer test seeds (impacts; default 3)")


def _check(args) -> None:
    if args.n < 1 or args.n > 20000:
        raise KinodynError(f"--n must be between 1 and 20000, got {args.n}")
    if not (0 < args.seconds <= 600):
        raise KinodynError(f"--seconds must be in (0, 600], got {args.seconds}")
    if args.push < 0 or args.balls < 0:
        raise KinodynError(f"--push and --balls must be >= 0, got {args.push} and {args.balls}")
    if not (1 <= args.viewer_fps <= 60):
        raise KinodynError(f"--viewer-fps must be in [1, 60], got {args.viewer_fps}")
    if args.train_seeds < 1 or args.test_seeds < 1:
        raise KinodynError("--train-seeds and --test-seeds must be >= 1")


def _assign(crowd, kind: str, rng) -> None:
    from kinodyn.crowd import behaviours as b

    n = crowd.n
    ai = crowd.ai
    if kind == "mix":
        ai.kind[:] = rng.choice([b.IDLE, b.WANDER, b.GOTO, b.FOLLOW], n, p=[0.35, 0.35, 0.15, 0.15])
    else:
        ai.kind[:] = b.BEHAVIOURS.index(kind)
    ai.target[:] = rng.uniform(-0.6, 0.6, (n, 2)) * np.sqrt(n) * 1.3
    ai.leader[:] = rng.integers(0, n, n)
    if kind == "flee":
        ai.target[:] = 0.0


def simulate(n: int, seconds: float, pushes: int, balls: int, behaviour: str = "mix", seed: int = 0,
             keyframes=None):
    """A crowd of ``n`` characters run for ``seconds`` with random pushes and balls; recorded."""
    from kinodyn.crowd.crowd import Crowd, CrowdConfig, grid

    rng = np.random.default_rng(seed)
    crowd = Crowd(grid(n, spacing=1.3, seed=seed), rng.uniform(-np.pi, np.pi, n), keyframes=keyframes,
                  config=CrowdConfig(balls=max(1, min(balls, 8))), seed=seed)
    _assign(crowd, behaviour, rng)
    frames = round(seconds * crowd.config.fps)
    push_at = np.sort(rng.integers(30, max(31, frames - 60), pushes))
    ball_at = np.sort(rng.integers(30, max(31, frames - 60), balls))
    crowd.start_recording()
    for f in range(frames):
        for _ in range(int(np.sum(push_at == f))):
            i = int(rng.integers(n))
            a = rng.uniform(-np.pi, np.pi)
            strength = rng.choice([500.0, 1500.0])
            crowd.push(i, strength * np.array([np.cos(a), np.sin(a), 0.0]),
                       point=crowd.state.r[i] + [0.0, 0.0, rng.uniform(-0.3, 0.3)], duration=0.1)
        for _ in range(int(np.sum(ball_at == f))):
            i = int(rng.integers(n))
            a = rng.uniform(-np.pi, np.pi)
            start = crowd.state.r[i] + np.array([4 * np.cos(a), 4 * np.sin(a), 0.6])
            aim = crowd.state.r[i] + [0.0, 0.0, 0.2]
            crowd.throw(start, (aim - start) / 0.3 + [0.0, 0.0, 0.5 * 9.81 * 0.3])
        crowd.step()
    return crowd


def write_run(crowd, args, out: Path) -> list[str]:
    from kinodyn.crowd.controller import FALLING
    from kinodyn.crowd.figures import crowd_snapshot
    from kinodyn.io.atomic import atomic_path

    rec = crowd.recording()
    sk = crowd.keyframes.skeleton
    lines = []
    if args.format == "npz":
        with atomic_path(out / "crowd.npz", suffix=".npz") as tmp:
            np.savez_compressed(tmp, root_pos=rec["root_pos"], local_rot=rec["local_rot"], mode=rec["mode"],
                                body=rec["body"], parents=sk.parents, offsets=sk.offsets,
                                names=np.array(sk.names), fps=crowd.config.fps, behaviour=crowd.ai.kind)
        lines.append(f"wrote {out / 'crowd.npz'}: {crowd.n} characters x {len(rec['mode'])} frames")
    else:
        from kinodyn.io.bvh import write_bvh

        for m in crowd.motions():
            write_bvh(out / "bvh" / f"{m.name}.bvh", m)
        lines.append(f"wrote {crowd.n} BVH files in {out / 'bvh'}")
    falls = int(np.sum(np.any(rec["mode"] == FALLING, axis=0)))
    frame = min(len(rec["mode"]) - 1, int(0.6 * len(rec["mode"])))
    crowd_snapshot(out / "crowd.png", sk, rec["root_pos"][frame].astype(float), rec["local_rot"][frame],
                   title=f"{crowd.n} characters at t = {frame / crowd.config.fps:.1f} s")
    lines.append(f"{falls} of {crowd.n} characters fell; snapshot {out / 'crowd.png'}")
    return lines


def viewer_page(crowd, out: Path, fps: float) -> str:
    from kinodyn.viz import html

    motions = [m.resample(fps) if abs(m.fps - fps) > 1e-9 else m for m in crowd.motions()]
    page = html.write(out / "crowd.html", motions, overlays=None, body="bones", camera="free",
                      title=f"kinodyn crowd: {crowd.n} characters")
    return f"wrote {page.path} ({page.bytes / 1e6:.1f} MB)"


def impacts_experiment(args, out: Path) -> list[str]:
    from kinodyn.crowd import impacts as ex
    from kinodyn.crowd.figures import contact_sheet
    from kinodyn.io.atomic import atomic_path, atomic_write_bytes
    from kinodyn.io.bvh import write_bvh
    from kinodyn.motion import Motion

    ks = _keyframes(args)
    labels = ex.experiment()
    shown = ex.run_impacts(labels, args.seed, keyframes=ks)
    train = [ex.run_impacts(labels, args.seed + 1 + s, keyframes=ks) for s in range(args.train_seeds)]
    test = [ex.run_impacts(labels, args.seed + 1000 + s, keyframes=ks) for s in range(args.test_seeds)]
    sk = ks.skeleton if ks is not None else _builtin().skeleton
    table = ex.evaluate_observer(train, test, sk)
    with atomic_path(out / "reactions.npz", suffix=".npz") as tmp:
        np.savez_compressed(tmp, labels=labels, root_pos=shown.root_pos, local_rot=shown.local_rot,
                            mode=shown.modes, fps=shown.fps, parents=sk.parents, offsets=sk.offsets)
    for i, lab in enumerate(labels):
        name = (f"reaction_{i:02d}_pos{ex.ANGLES[lab[0]]:+.0f}_dir{ex.ANGLES[lab[1]]:+.0f}"
                f"_h{ex.HEIGHTS[lab[2]]:.1f}_{ex.STRENGTHS[lab[3]]}")
        write_bvh(out / "reactions" / f"{name}.bvh",
                  Motion(sk, shown.root_pos[i].astype(float), shown.local_rot[i].astype(float), shown.fps, name=name))
    meta = {"train_seeds": args.train_seeds, "test_seeds": args.test_seeds, "reactions_per_seed": 54,
            "observer": table}
    atomic_write_bytes(out / "observer.json", (json.dumps(meta, indent=2) + "\n").encode())
    contact_sheet(out / "impacts.png", shown, sk, title=f"54 reactions (seed {args.seed}): pos, dir, height, strength")
    lines = [f"wrote 54 reactions: {out / 'reactions.npz'} and {out / 'reactions'}/*.bvh; {out / 'impacts.png'}",
             "observer (trained on other seeds) vs the paper's subjects:"]
    for k, row in table.items():
        lines.append(f"  {k:<8} accuracy {row['accuracy']:.2f} (paper {row['paper_accuracy']:.2f})  "
                     f"mu {row['mu']:+.3f} sigma {row['sigma']:.3f} (paper {row['paper_mu']:+.3f}, "
                     f"{row['paper_sigma']:.3f})")
    return lines


def _builtin():
    from kinodyn.crowd.keyframes import builtin_keyframes

    return builtin_keyframes()


def _keyframes(args):
    if not args.keyframes:
        return None
    from kinodyn.crowd.keyframes import load_keyframes

    return load_keyframes(args.keyframes)


def run(args) -> int:
    _check(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.action == "impacts":
        lines = impacts_experiment(args, out)
    else:
        crowd = simulate(args.n, args.seconds, args.push, args.balls, args.behaviour, args.seed, _keyframes(args))
        lines = write_run(crowd, args, out)
        lines.append(viewer_page(crowd, out, args.viewer_fps))
    for line in lines:
        print(line)
    return 0
