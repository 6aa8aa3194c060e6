"""Training data for the reaction classifier (dynamic response, section 7.2).

Balls are thrown at the character while it plays a base motion, varying the angle, speed, starting height,
arrival time and target landmark. Each case is simulated through the classification window and the
lookahead (:func:`kinodyn.response.pipeline.observe`) and labelled by the exhaustive search (clip and
timing), with every clip's error D as the exhaustive search and as the fast alignment find it; its large
and small feature vectors (:mod:`kinodyn.response.features`) are kept. Generation
runs through :func:`kinodyn.parallel.run` (all local cores by default, or Ray), deterministic per seed:
case ``i`` of seed ``s`` draws its ball from ``numpy.random.default_rng([s, i])``. Saved as ``.npz``
arrays plus a JSON description (no pickles).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from kinodyn.errors import FileFormatError, KinodynError, ParameterError
from kinodyn.io.atomic import atomic_path
from kinodyn.response.features import features
from kinodyn.response.pipeline import Ball, fast_errors, label_search, observe
from kinodyn.version import __version__

__all__ = ["TARGETS", "Dataset", "ball_for", "flip_chunk", "generate", "label_chunk", "label_flips",
           "load_base", "setup"]

FORMAT = "kinodyn.response-dataset/2"
#: Earlier formats :meth:`Dataset.load` still reads (``/1`` has no ``fast_per_clip``: read as NaN).
_READS = ("kinodyn.response-dataset/1", FORMAT)
#: Landmarks the balls aim at.
TARGETS = ("chest", "stomach", "pelvis", "head")


def ball_for(seed: int, i: int) -> Ball:
    """The ball of case ``i`` of a dataset with ``seed``: speed 6-11 m/s, any horizontal direction,
    launch height 1.0-1.8 m, arrival 0.8-1.4 s, one of :data:`TARGETS`."""
    rng = np.random.default_rng([int(seed), int(i)])
    return Ball(speed=float(rng.uniform(6.0, 11.0)), direction=float(rng.uniform(-np.pi, np.pi)),
                height=float(rng.uniform(1.0, 1.8)), target=TARGETS[int(rng.integers(len(TARGETS)))],
                time=float(rng.uniform(0.8, 1.4)))


def load_base(base: str, fps: float):
    """The base motion ``base``: a BVH (or other motion) file when that path exists, resampled to ``fps``
    (a T-pose frame a converter added before the capture left out), else a built-in clip by name."""
    if Path(base).exists():
        from kinodyn.io import drop_added_tpose, load

        return drop_added_tpose(load(Path(base)))[0].resample(fps)
    from kinodyn.data import library as data

    return data.load(base)


def _files_state(base: str, library: str | None) -> tuple:
    """Size and modification time of the files a setup reads (the folder's clips, a base motion file):
    a setup is built again when one of them changed."""
    files = sorted(Path(library).glob("*.bvh")) if library is not None else []
    if Path(base).exists():
        files.append(Path(base))
    return tuple((str(f), f.stat().st_size, f.stat().st_mtime_ns) for f in files)


@lru_cache(maxsize=4)
def _build(base: str, library: str | None, fps: float | None, state: tuple):
    from kinodyn.response.library import builtin, from_folder
    from kinodyn.response.pipeline import check_inputs

    lib = builtin() if library is None else from_folder(library, fps=fps)
    motion = load_base(base, lib.fps)
    check_inputs(motion, lib)
    return motion, lib


def _setup(base: str, library: str | None = None, fps: float | None = None):
    """``(base motion, reaction library)`` of one job: the built-in library, or the BVH clips of folder
    ``library`` (resampled to ``fps``, default the first clip's rate); built once per process while the
    files stay as they are (a clip edited, added or removed builds it again)."""
    return _build(base, library, fps, _files_state(base, library))


def _folder_and_rate(library, fps) -> tuple:
    """The job arguments of :func:`_setup` for a library folder and a rate (checked), as plain values."""
    if fps is not None and (library is None or not (np.isfinite(fps) and fps > 0)):
        alone = " without a folder (the built-in library is at 60 fps)" if library is None else ""
        raise ParameterError(f"fps resamples the clips of a library folder to a positive rate, got "
                             f"fps={fps}{alone}")
    return (None if library is None else str(Path(library).resolve())), (None if fps is None else float(fps))


def setup(base: str, library=None, fps: float | None = None):
    """``(base motion, reaction library)``: ``base`` a built-in clip name or a motion file, against the
    built-in library or the BVH clips of folder ``library`` (both resampled to ``fps``, default the first
    clip's rate), checked to play together (:func:`kinodyn.response.pipeline.check_inputs`). Built once
    per process and arguments (the library's search windows included)."""
    return _setup(base, *_folder_and_rate(library, fps))


def label_chunk(tasks: list) -> dict:
    """Simulate and label cases ``[(seed, i, base), ...]``, or ``[(seed, i, base, library folder, fps), ...]``
    for a library of BVH clips (one worker job; the library is built once per process). Cases whose
    simulation fails get label -1."""
    rows = {"large": [], "small": [], "clip": [], "sim_frame": [], "clip_frame": [], "error": [], "per_clip": [],
            "fast_per_clip": [], "ball": []}
    for seed, i, base, *library in tasks:
        motion, lib = _setup(base, *library)
        ball = ball_for(seed, i)
        rows["ball"].append([ball.speed, ball.direction, ball.height, ball.time, TARGETS.index(ball.target)])
        try:
            obs = observe(motion, ball)
            r = label_search(obs, lib)
            k, fs, fm, err, per_clip = r.clip, r.sim_frame, r.clip_frame, r.error, r.per_clip
            fast = fast_errors(obs, lib)
            big, small = features(obs.states, "large"), features(obs.states, "small")
        except KinodynError:
            k, fs, fm, err, big, small = -1, -1, -1, np.inf, np.full(198, np.nan), np.full(20, np.nan)
            per_clip, fast = np.full(len(lib), np.inf), np.full(len(lib), np.inf)
        for key, v in (("large", big), ("small", small), ("clip", k), ("sim_frame", fs), ("clip_frame", fm),
                       ("error", err), ("per_clip", per_clip), ("fast_per_clip", fast)):
            rows[key].append(v)
    return {k: np.asarray(v) for k, v in rows.items()}


def flip_chunk(tasks: list) -> dict:
    """One worker job of :func:`label_flips`: for cases ``[(seed, i, base, relative), ...]``, whether the
    exhaustive label changes with a ball ``relative`` faster (``flip``) and whether both throws simulated
    (``ok``)."""
    from dataclasses import replace

    flip, ok = [], []
    for seed, i, base, relative in tasks:
        motion, lib = _setup(base)
        ball = ball_for(seed, i)
        try:
            a = label_search(observe(motion, ball), lib).clip
            b = label_search(observe(motion, replace(ball, speed=ball.speed * (1.0 + relative))), lib).clip
        except KinodynError:
            a = b = -1
        flip.append(a != b)
        ok.append(a >= 0 and b >= 0)
    return {"flip": np.asarray(flip, dtype=bool), "ok": np.asarray(ok, dtype=bool)}


def label_flips(seed: int, cases, base: str = "walk", relative: float = 1e-3, *, workers: int | None = None,
                show_progress=None) -> np.ndarray:
    """How stable the exhaustive labels are: for each case ``i`` of ``cases`` (of a dataset with ``seed``),
    whether its label changes when the ball is thrown ``relative`` faster (a 0.1 % change by default: under a
    centimetre a second, far below what the features resolve). ``(N,)`` booleans; cases whose simulation
    fails in either throw are left out. Runs on all local cores by default (:func:`kinodyn.parallel.run`).

    A classifier that gives two such near-identical throws the same answer is wrong on at least one of each
    pair that flips, so ``1 - flips.mean() / 2`` bounds the accuracy such a classifier can reach against
    these labels.
    """
    from kinodyn import parallel

    if not relative > 0:
        raise ParameterError(f"relative must be > 0, got {relative}")
    tasks = [(int(seed), int(i), base, float(relative)) for i in cases]
    if not tasks:
        return np.zeros(0, dtype=bool)
    out = parallel.run(flip_chunk, tasks, chunk_size=10, workers=workers, desc="label stability",
                       show_progress=show_progress)
    return out["flip"][out["ok"]]


@dataclass(frozen=True)
class Dataset:
    """Labelled cases.

    Attributes:
        large, small: ``(N, 198)`` and ``(N, 20)`` feature vectors.
        clip: ``(N,)`` exhaustive label (clip index; -1 where the case failed).
        sim_frame, clip_frame, error: ``(N,)`` the exhaustive timing and its error D.
        per_clip: ``(N, K)`` every clip's best error D (the label is its argmin; inf where a case failed).
        fast_per_clip: ``(N, K)`` every clip's error D at the timing the fast alignment finds (what a
            choice among the classifier's candidates compares; NaN in datasets of format ``/1``).
        ball: ``(N, 5)`` speed, direction, height, time, target index of each case.
        meta: JSON-able description (seed, base, clip names, library signature).
    """

    large: np.ndarray
    small: np.ndarray
    clip: np.ndarray
    sim_frame: np.ndarray
    clip_frame: np.ndarray
    error: np.ndarray
    per_clip: np.ndarray
    ball: np.ndarray
    meta: dict
    fast_per_clip: np.ndarray | None = None

    def __post_init__(self):
        if self.fast_per_clip is None:
            object.__setattr__(self, "fast_per_clip", np.full(np.shape(self.per_clip), np.nan))

    def __len__(self) -> int:
        return len(self.clip)

    def valid(self) -> np.ndarray:
        return self.clip >= 0

    def save(self, path) -> None:
        with atomic_path(path, suffix=".npz") as tmp:
            np.savez_compressed(tmp, meta=np.array(json.dumps(self.meta)), large=self.large, small=self.small,
                                clip=self.clip, sim_frame=self.sim_frame, clip_frame=self.clip_frame,
                                error=self.error, per_clip=self.per_clip, ball=self.ball,
                                fast_per_clip=self.fast_per_clip)

    @classmethod
    def load(cls, path) -> "Dataset":
        try:
            with np.load(Path(path), allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta.get("format") not in _READS:
                    raise FileFormatError(f"not a kinodyn response dataset (format {meta.get('format')!r})", path)
                fast = z["fast_per_clip"] if "fast_per_clip" in z.files else None
                return cls(z["large"], z["small"], z["clip"], z["sim_frame"], z["clip_frame"], z["error"],
                           z["per_clip"], z["ball"], meta, fast)
        except (KeyError, ValueError, OSError, json.JSONDecodeError) as e:
            if isinstance(e, FileFormatError):
                raise
            raise FileFormatError(f"cannot read response dataset: {e}", path) from None


def generate(cases: int, seed: int = 0, base: str = "walk", *, library=None, fps: float | None = None,
             workers: int | None = None, backend: str = "local", address: str | None = None, resume_dir=None,
             chunk_size: int = 20, show_progress=None) -> Dataset:
    """``cases`` labelled throws (see :func:`ball_for`) at a character playing ``base``, labelled against
    the built-in reaction library, or against the BVH clips of folder ``library``.

    Args:
        cases, seed: how many throws, and the seed they are drawn from (case ``i`` of seed ``s`` is always
            the same throw).
        base: a built-in clip name (``walk``, ``idle``, ``fighting_stance``) or a motion file, on the
            library's skeleton.
        library: a folder of BVH reaction clips (default: the built-in library); on a Ray cluster, a path
            every node can read.
        fps: the rate the folder's clips and the base motion are resampled to (default: the first clip's).
        workers, backend, address, resume_dir, chunk_size, show_progress: as :func:`kinodyn.parallel.run`;
            the chunks kept in ``resume_dir`` are read back only by a run on the same clips (their content,
            not only their names), the same base motion and the same kinodyn version.

    Raises:
        ParameterError, MotionError: a base motion or library that cannot be used (checked before any
            throw is simulated).
    """
    from kinodyn import parallel

    if int(cases) < 1:
        raise ParameterError(f"cases must be >= 1, got {cases}")
    folder, rate = _folder_and_rate(library, fps)
    motion, lib = _setup(base, folder, rate)  # bad input is reported here, not as failed cases
    tasks = [(int(seed), i, base) + (() if folder is None else (folder, rate)) for i in range(int(cases))]
    # chunks kept in resume_dir are read back only for the same clips, base motion, kinodyn version and format
    context = f"kinodyn {__version__}, {FORMAT}, library {lib.fingerprint()}, base {motion.digest()}"
    out = parallel.run(label_chunk, tasks, chunk_size=chunk_size, workers=workers, backend=backend,
                       address=address, resume_dir=resume_dir, context=context, desc=f"throws at {base}",
                       show_progress=show_progress)
    meta = {"format": FORMAT, "seed": int(seed), "base": base, "cases": int(cases), "clips": list(lib.names),
            "library": lib.signature(), "targets": list(TARGETS)}
    return Dataset(out["large"], out["small"], out["clip"].astype(np.int64), out["sim_frame"].astype(np.int64),
                   out["clip_frame"].astype(np.int64), out["error"], out["per_clip"], out["ball"], meta,
                   out["fast_per_clip"])
