"""Demo part "crowd": a pushed crowd of keyframe characters and the impact experiment.

1. 80 characters (idle, wandering, walking to places, following each other) for 10 s, with 16 pushes
   and 4 balls thrown into the crowd: ``crowd/crowd.npz``, ``crowd/crowd.html`` (viewer page),
   ``crowd/crowd.png`` (a snapshot).
2. The 54 reactions of the paper's section 6 and the automatic observer trained on 3 other seeds:
   ``crowd/impacts/reactions.npz``, one BVH per reaction, ``observer.json``, ``impacts.png``.
"""

from __future__ import annotations

from argparse import Namespace
from pathlib import Path

__all__ = ["demo"]


def demo(out: Path) -> list[str]:
    from kinodyn.crowd import command

    base = Path(out) / "crowd"
    base.mkdir(parents=True, exist_ok=True)
    args = Namespace(action="run", out=str(base), n=80, seconds=10.0, push=16, balls=4, behaviour="mix",
                     format="npz", keyframes=None, viewer_fps=30.0, seed=0, train_seeds=3, test_seeds=1)
    crowd = command.simulate(args.n, args.seconds, args.push, args.balls, args.behaviour, args.seed)
    lines = command.write_run(crowd, args, base)
    lines.append(command.viewer_page(crowd, base, args.viewer_fps))
    imp = Namespace(**{**vars(args), "action": "impacts", "out": str(base / "impacts")})
    (base / "impacts").mkdir(exist_ok=True)
    lines += command.impacts_experiment(imp, base / "impacts")
    return lines
