"""``kinodyn response train|play``: train the reaction classifier, or play one response and explain it.

    kinodyn response train [--cases N] [--base walk|FILE] [--library DIR [--fps F]] [--backend local|ray]
                           [--address ADDR] [--workers N] -o MODEL_DIR
    kinodyn response play --base walk --ball SPEED,DIRECTION,HEIGHT,TARGET | --seed N [--model DIR]
                          [--candidates K [--align-stride N]] [--exhaustive] [--library DIR [--fps F]]
                          -o out.bvh [--html out.html] [--explain DIR]

``DIRECTION`` is the ball's heading of travel in degrees (180 flies at a walker's face, 0 at its back).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from kinodyn.errors import ParameterError

HELP = "dynamic response: kinodyn response train -o MODEL_DIR | kinodyn response play --ball ... -o out.bvh"
DESCRIPTION = ("Train the SVM that picks a reaction clip from the simulated state after an impact (labels "
               "from the exhaustive search), or play one impact on a character and write the response.")

#: Where the shipped default models live, inside the package (``large`` and ``small`` feature sets).
DEFAULT_MODEL = Path(__file__).resolve().parent / "model"
#: The feature set of the shipped model that chooses by default (``play``, the demo, the benchmark's fast
#: path): trained on the same throws, the small set's model is within a point of the large one's
#: accuracy, and its choice streams a tenth of the support-vector memory, which is what a choice costs.
DEFAULT_KIND = "small"


_FPS_HELP = "frame rate to resample the --library clips and the base motion to (default: the first clip's)"


def add_arguments(p) -> None:
    sub = p.add_subparsers(dest="action", required=True)
    t = sub.add_parser("train", help="generate labelled throws and train the classifier")
    t.add_argument("-o", "--output", required=True, help="model folder to write")
    t.add_argument("--cases", type=int, default=5500, help="number of throws (default 5500)")
    t.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    t.add_argument("--base", default="walk",
                   help="base motion: a built-in clip (walk, idle, fighting_stance) or a BVH file "
                   "(default walk)")
    t.add_argument("--library", help="folder of BVH reaction clips to label against (default: the built-in "
                   "library); the base motion must be on their skeleton")
    t.add_argument("--fps", type=float, help=_FPS_HELP)
    t.add_argument("--kind", choices=["large", "small"], default="large", help="feature set (default large)")
    t.add_argument("--backend", choices=["local", "ray"], default="local")
    t.add_argument("--address", help="Ray cluster address (default: start Ray here)")
    t.add_argument("--workers", type=int, help="worker processes (default every core)")
    t.add_argument("--resume", help="folder keeping finished chunks, read back by a rerun on the same throws, "
                   "clips and base motion (default OUTPUT/chunks)")
    t.add_argument("--chunk-size", type=int, default=20, help="throws per job (default 20)")
    t.add_argument("--dataset", help="also write the labelled dataset (.npz) here")
    q = sub.add_parser("play", help="one impact: write the response motion and its explanation")
    q.add_argument("--base", default="walk", help="base motion: a built-in clip name or a BVH file")
    q.add_argument("--ball", help="SPEED,DIRECTION,HEIGHT,TARGET (m/s, degrees, m, landmark)")
    q.add_argument("--seed", type=int, help="a random ball (as in training) instead of --ball")
    q.add_argument("--model", help="model folder (default: the shipped small-feature model, or exhaustive "
                   "search with --library)")
    q.add_argument("--candidates", type=int, default=1,
                   help="time the model's K most probable clips and keep the one of lowest error D "
                   "(default 1: the model's clip; each further one costs an alignment, about 0.3 ms)")
    q.add_argument("--align-stride", type=int, default=10,
                   help="frames between the fast alignment's samples on both axes (default 10, the paper's); "
                   "5 finds D precisely enough to tell near-tied candidates apart, at about the same cost")
    q.add_argument("--exhaustive", action="store_true", help="choose by exhaustive search, no model")
    q.add_argument("--library", help="folder of BVH reaction clips instead of the built-in library")
    q.add_argument("--fps", type=float, help=_FPS_HELP)
    q.add_argument("-o", "--output", required=True, help="motion file to write (.bvh or .npz)")
    q.add_argument("--html", help="also write a viewer page")
    q.add_argument("--explain", help="folder for explain.json and the plots")


def _ball(args):
    from kinodyn.response.dataset import ball_for
    from kinodyn.response.pipeline import Ball

    if (args.ball is None) == (args.seed is None):
        raise ParameterError("give exactly one of --ball SPEED,DIRECTION,HEIGHT,TARGET and --seed N")
    if args.seed is not None:
        return ball_for(args.seed, 0)
    parts = args.ball.split(",")
    if len(parts) != 4:
        raise ParameterError(f"--ball must be SPEED,DIRECTION,HEIGHT,TARGET, got {args.ball!r}")
    try:
        speed, direction, height = (float(x) for x in parts[:3])
    except ValueError:
        raise ParameterError(f"--ball SPEED, DIRECTION and HEIGHT must be numbers, got {args.ball!r}") from None
    return Ball(speed=speed, direction=float(np.deg2rad(direction)), height=height, target=parts[3].strip())


def _train(args) -> int:
    from kinodyn.response.classifier import train
    from kinodyn.response.dataset import generate, setup

    if args.cases < 10:
        raise ParameterError(f"--cases must be at least 10, got {args.cases}")
    out = Path(args.output)
    ds = generate(args.cases, args.seed, args.base, library=args.library, fps=args.fps, workers=args.workers,
                  backend=args.backend, address=args.address, resume_dir=args.resume or out / "chunks",
                  chunk_size=args.chunk_size)
    ok = ds.valid()
    lib = setup(args.base, args.library, args.fps)[1]  # the library generate built, from its cache
    model = train(getattr(ds, args.kind)[ok], ds.clip[ok], args.kind, lib, errors=ds.per_clip[ok])
    # the command names files and folders as their last part (the rest is where they were on this machine)
    library = "" if args.library is None else f" --library {Path(args.library).name}"
    library += "" if args.fps is None else f" --fps {args.fps:g}"
    base = Path(args.base).name if Path(args.base).exists() else args.base
    model.info.update({"seed": args.seed, "base": base,
                       "command": f"kinodyn response train --cases {args.cases} --seed {args.seed} "
                                  f"--base {base}{library} --kind {args.kind} -o {out.name}"})
    model.save(out)
    if args.dataset:
        ds.save(args.dataset)
    print(f"wrote {out}: {args.kind} features, {int(ok.sum())} of {len(ds)} cases, "
          f"cross-validated accuracy {model.info['cv_accuracy']:.1%}")
    return 0


def _explain(folder: Path, r, lib, model_used: bool) -> None:
    from kinodyn.response import plots
    from kinodyn.response.pipeline import ResponseConfig
    from kinodyn.response.search import Windows, body_tracks, exhaustive, windows

    folder.mkdir(parents=True, exist_ok=True)
    skip = max(1, int(round(ResponseConfig().min_transition_s * r.motion.fps)))
    pos, rot = body_tracks(r.lookahead)
    win = windows(pos, rot, lib.window)
    full = exhaustive(win, lib, keep_surfaces=True)  # surfaces from the choice frame on
    best = exhaustive(Windows(win.pos[skip:], win.rot[skip:], win.ground[skip:]), lib)
    facts = {"clip": r.clip, "sim_frame": r.sim_frame, "clip_frame": r.clip_frame, "error": r.error,
             "impact_time": r.impact_time, "impulse": r.impulse.tolist(),
             "stages": {k: list(v) for k, v in r.stages.__dict__.items()},
             "chosen_by": "classifier + fast alignment" if model_used else "exhaustive search",
             "exhaustive": {"clip": lib.names[best.clip], "sim_frame": best.sim_frame + skip,
                            "clip_frame": best.clip_frame, "error": best.error}}
    if r.candidates:
        facts["candidates"] = [{"clip": lib.names[c], "error": e} for c, e in r.candidates]
    if r.probabilities is not None:
        facts["probabilities"] = {n: round(float(p), 4) for n, p in zip(lib.names, r.probabilities) if p > 0.005}
    (folder / "explain.json").write_text(json.dumps(facts, indent=2) + "\n", encoding="utf-8")
    mark = (best.sim_frame + skip, best.clip_frame) if best.clip == r.clip_index else None
    plots.error_surface(full.surfaces[r.clip_index], folder / "error_surface.png", f"error D: {r.clip}",
                        fast=(r.sim_frame, r.clip_frame), best=mark, searched_from=skip)
    plots.timeline(r.stages, r.motion.fps, folder / "timeline.png", r.motion.name, r.impact_time)


#: The output's stages in order, as named in :data:`kinodyn.plotting.style.STAGE_COLORS`.
STAGE_NAMES = ("motion data", "simulation", "transition", "clip")


def _blows(hits) -> list:
    """The hits grouped by what delivered them (a ball touching chest and arm is one blow): per source,
    ``(first time, impulse-weighted point (3,), total impulse (3,), kind, bodies)``."""
    out = []
    for src in dict.fromkeys(h.source for h in hits):
        group = [h for h in hits if h.source == src]
        j = np.array([h.impulse for h in group], dtype=np.float64)
        w = np.linalg.norm(j, axis=1) + 1e-12
        point = (w[:, None] * np.array([h.point for h in group])).sum(axis=0) / w.sum()
        bodies = sorted({h.body for h in group}, key=lambda b: -sum(
            np.linalg.norm(h.impulse) for h in group if h.body == b))
        out.append((min(h.time for h in group), point, j.sum(axis=0), group[0].kind, bodies))
    return out


def viewer_overlays(r, character: int = 0) -> list:
    """What the viewer draws for response ``r`` of character ``character``: the timeline bar coloured by
    stage (motion data, simulation, transition, clip), the body tinted by the stage it is in, a marker
    where each reacting stage begins, and one impact arrow per blow (where it landed, which way it
    pushed), labelled with what hit which bodies and how hard.
    """
    from kinodyn.plotting import style
    from kinodyn.viz.html import Impact, Marker, Stages

    fps = r.motion.fps
    frames = (r.stages.motion, r.stages.simulation, r.stages.transition, r.stages.clip)
    spans = [(a / fps, b / fps, n) for n, (a, b) in zip(STAGE_NAMES, frames) if b > a]
    out = [Stages(spans, character, label=f"{r.clip} stages" if r.clip else "stages", tint=True)]
    out += [Marker(a, "", style.STAGE_COLORS[n]) for a, _, n in spans if n != STAGE_NAMES[0]]
    for t, point, j, kind, bodies in _blows(r.hits):
        out.append(Impact(float(t), point, j, character, f"{kind} on {', '.join(bodies)}: {np.linalg.norm(j):.0f} N s"))
    return out


def _play(args) -> int:
    from kinodyn.io import save
    from kinodyn.response.classifier import ReactionModel
    from kinodyn.response.dataset import setup
    from kinodyn.response.align import AlignConfig
    from kinodyn.response.pipeline import ResponseConfig, respond

    ball = _ball(args)
    config = ResponseConfig(candidates=args.candidates, align=AlignConfig(stride=args.align_stride))
    base, lib = setup(args.base, args.library, args.fps)
    select = None
    if not args.exhaustive and args.model is None and args.library is not None:
        print("kinodyn: note: the shipped model chooses among the built-in clips; the clips of --library are "
              "chosen by exhaustive search (--model DIR for a model trained on them)", file=sys.stderr)
    elif not args.exhaustive:
        select = ReactionModel.load(args.model or DEFAULT_MODEL / DEFAULT_KIND, lib)
    if select is None and (args.candidates != 1 or args.align_stride != 10):
        raise ParameterError("--candidates and --align-stride shape the model's fast path; the exhaustive search "
                             "(--exhaustive, or --library without --model) already times every clip at every frame")
    r = respond(base, lib, ball, select, config)
    save(args.output, r.motion)
    if args.html:
        from kinodyn.viz.html import write

        write(args.html, {"response": r.motion}, ["contacts", *viewer_overlays(r)], title=f"{r.motion.name}")
    if args.explain:
        _explain(Path(args.explain), r, lib, select is not None)
    print(f"wrote {args.output}: {r.motion.num_frames} frames; hit at {r.impact_time:.2f} s "
          f"({np.linalg.norm(r.impulse):.1f} N s), clip {r.clip} from frame {r.clip_frame}, D = {r.error:.3f}")
    return 0


def run(args) -> int:
    return _train(args) if args.action == "train" else _play(args)
