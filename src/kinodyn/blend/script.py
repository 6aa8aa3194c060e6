"""Blend scripts: a YAML list of actions with start/stop times and priorities, and the runner.

A script (``kinodyn blend SCRIPT.yaml -o out.bvh``)::

    fps: 60                    # output frame rate (default 60)
    duration: 12.0             # seconds (default: until the last action has faded out, + 0.5 s)
    synchronize: true          # support-phase synchronization (false: the plain blend baseline)
    nk: 5                      # elements synchronized ahead (section 5.1)
    ramp_in: 0.4               # default activation / deactivation durations (s)
    ramp_out: 0.4
    neutral: idle              # the neutral double-support pose: a clip name (default: idle if known)
    clips:                     # clips from files, in addition to the built-in library
      mywalk: {file: walk.bvh, cyclic: true, drop_first: 1, start: 0.5, stop: 1.63, fps: 60}
      brisk: {mix: {walk: 0.5, mywalk: 0.5}}   # a cycle between cycles (kinodyn.blend.parametric)
    actions:
      - clip: walk             # built-in clip or a name from `clips`
        start: 0.0             # seconds
        stop: 4.0              # optional (non-cyclic clips stop by themselves at their end)
        priority: 1            # higher overrides lower (default 0)
        speed: 1.0             # time scaling (default 1)
        ramp_in: 0.4           # optional, per action
        ramp_out: 0.4
        key: walk1             # optional identifier

A ``cyclic`` clip should cover one cycle (heel strike to the same heel strike); a captured cycle never
closes exactly, so the small mismatch between its last and first frames is spread over the clip.
Relative file paths are relative to the script. Errors name the script, the entry and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from kinodyn.errors import FileFormatError, KinodynError
from kinodyn.motion import Motion

__all__ = [
    "ActionEntry",
    "BlendResult",
    "ClipEntry",
    "MAX_FPS",
    "MAX_FRAMES",
    "MAX_NK",
    "MAX_SECONDS",
    "MixEntry",
    "Script",
    "ScriptError",
    "build_library",
    "intended_contacts",
    "load_script",
    "parse_script",
    "run_script",
    "sliding_report",
]

#: Upper bounds of a script's numbers, so a typo (``fps: 1e9``) is an error, not a 15 GiB allocation.
MAX_FPS = 1000.0
MAX_SECONDS = 3600.0
MAX_NK = 100
#: the most frames a script may produce (duration x fps)
MAX_FRAMES = 1_000_000
_LIMITS = {"fps": MAX_FPS, "duration": MAX_SECONDS, "start": MAX_SECONDS, "stop": MAX_SECONDS,
           "ramp_in": MAX_SECONDS, "ramp_out": MAX_SECONDS, "nk": MAX_NK}

_TOP_KEYS = {"fps", "duration", "synchronize", "nk", "ramp_in", "ramp_out", "neutral", "clips", "actions",
             "name", "skeleton"}
_ACTION_KEYS = {"clip", "start", "stop", "priority", "speed", "ramp_in", "ramp_out", "key", "auto_stop"}
_CLIP_KEYS = {"file", "cyclic", "drop_first", "start", "stop", "fps", "scale", "up", "mirror"}


class ScriptError(FileFormatError):
    """A blend script is malformed."""


@dataclass(frozen=True)
class MixEntry:
    """A cycle blended from other cyclic clips: ``weights`` is ``((clip, weight), ...)``."""

    name: str
    weights: tuple


@dataclass(frozen=True)
class ClipEntry:
    """A clip read from a file: ``file`` (BVH/AMC/NPZ), ``cyclic``, frames to drop, time range (s),
    resampling fps, unit scale, up axis, mirror."""

    name: str
    file: Path
    cyclic: bool = False
    drop_first: int = 0
    start: float | None = None
    stop: float | None = None
    fps: float | None = None
    scale: object = None
    up: str | None = None
    mirror: bool = False

    def load(self) -> Motion:
        from kinodyn.io import load

        kw = {}
        if self.scale is not None:
            kw["scale"] = self.scale
        if self.up is not None and self.file.suffix.lower() != ".npz":
            kw["up"] = self.up
        m = load(self.file, **kw)
        if self.drop_first:
            m = m[self.drop_first:]
        if self.start is not None or self.stop is not None:
            m = m.trim(self.start or 0.0, self.stop)
        if self.fps:
            m = m.resample(self.fps)
        if self.mirror:
            m = m.mirrored()
        return m.replace(name=self.name)


@dataclass(frozen=True)
class ActionEntry:
    """One scripted action (see the module docstring)."""

    clip: str
    start: float
    stop: float | None = None
    priority: float = 0.0
    speed: float = 1.0
    ramp_in: float | None = None
    ramp_out: float | None = None
    key: str | None = None
    auto_stop: bool = True


@dataclass(frozen=True)
class Script:
    """A parsed blend script."""

    actions: tuple[ActionEntry, ...]
    clips: tuple[ClipEntry, ...] = ()
    fps: float = 60.0
    duration: float | None = None
    synchronize: bool = True
    nk: int = 5
    ramp_in: float = 0.4
    ramp_out: float = 0.4
    neutral: str | None = None
    name: str = ""
    path: Path | None = None
    mixes: tuple[MixEntry, ...] = ()


def _num(where: str, key: str, v, positive=False, nonneg=False, integer=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ScriptError(f"{where}: {key} must be a number, got {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise ScriptError(f"{where}: {key} must be finite, got {v!r}")
    if positive and v <= 0:
        raise ScriptError(f"{where}: {key} must be positive, got {v:g}")
    if nonneg and v < 0:
        raise ScriptError(f"{where}: {key} must be >= 0, got {v:g}")
    limit = _LIMITS.get(key)
    if limit is not None and v > limit:
        raise ScriptError(f"{where}: {key} must be at most {limit:g}, got {v:g}")
    if integer:
        if v != int(v):
            raise ScriptError(f"{where}: {key} must be an integer, got {v:g}")
        return int(v)
    return v


def _unknown(where: str, got, allowed) -> None:
    bad = sorted(set(got) - set(allowed))
    if bad:
        raise ScriptError(f"{where}: unknown key {bad[0]!r}; allowed: {', '.join(sorted(allowed))}")


def parse_script(data, path=None) -> Script:
    """Validate a script given as the YAML document's data (a mapping)."""
    src = str(path) if path is not None else "script"
    if not isinstance(data, dict):
        raise ScriptError(f"{src}: the script must be a mapping with an 'actions' list, got {type(data).__name__}")
    _unknown(src, data, _TOP_KEYS)
    base = Path(path).resolve().parent if path is not None else Path.cwd()
    clips, mixes = [], []
    raw_clips = data.get("clips") or {}
    if not isinstance(raw_clips, dict):
        raise ScriptError(f"{src}: clips must be a mapping name -> {{file: ...}}, got {type(raw_clips).__name__}")
    for name, c in raw_clips.items():
        where = f"{src}: clips.{name}"
        if isinstance(c, str):
            c = {"file": c}
        if isinstance(c, dict) and "mix" in c:
            _unknown(where, c, {"mix"})
            mix = c["mix"]
            if not isinstance(mix, dict) or not mix:
                raise ScriptError(f"{where}: mix must map clip names to weights, got {mix!r}")
            weights = tuple((str(k), _num(f"{where}.mix", str(k), v, nonneg=True)) for k, v in mix.items())
            if sum(v for _, v in weights) <= 0:
                raise ScriptError(f"{where}: mix weights must not all be zero")
            mixes.append(MixEntry(str(name), weights))
            continue
        if not isinstance(c, dict) or "file" not in c:
            raise ScriptError(f"{where}: needs a 'file' (or a 'mix' of cyclic clips)")
        _unknown(where, c, _CLIP_KEYS)
        f = Path(str(c["file"]))
        f = f if f.is_absolute() else base / f
        clips.append(ClipEntry(
            str(name), f, bool(c.get("cyclic", False)),
            _num(where, "drop_first", c.get("drop_first", 0), nonneg=True, integer=True),
            None if c.get("start") is None else _num(where, "start", c["start"], nonneg=True),
            None if c.get("stop") is None else _num(where, "stop", c["stop"], positive=True),
            None if c.get("fps") is None else _num(where, "fps", c["fps"], positive=True),
            c.get("scale"), c.get("up"), bool(c.get("mirror", False))))
    acts = data.get("actions")
    if not isinstance(acts, list) or not acts:
        raise ScriptError(f"{src}: 'actions' must be a non-empty list")
    out = []
    keys = set()
    for i, a in enumerate(acts):
        where = f"{src}: actions[{i}]"
        if not isinstance(a, dict):
            raise ScriptError(f"{where}: must be a mapping with clip and start, got {a!r}")
        _unknown(where, a, _ACTION_KEYS)
        if "clip" not in a:
            raise ScriptError(f"{where}: missing 'clip'")
        if "start" not in a:
            raise ScriptError(f"{where}: missing 'start' (seconds)")
        start = _num(where, "start", a["start"], nonneg=True)
        stop = None if a.get("stop") is None else _num(where, "stop", a["stop"], nonneg=True)
        if stop is not None and stop < start:
            raise ScriptError(f"{where}: stop ({stop:g} s) is before start ({start:g} s)")
        key = None if a.get("key") is None else str(a["key"])
        if key is not None:
            if key in keys:
                raise ScriptError(f"{where}: key {key!r} is used twice")
            keys.add(key)
        out.append(ActionEntry(
            str(a["clip"]), start, stop, _num(where, "priority", a.get("priority", 0.0)),
            _num(where, "speed", a.get("speed", 1.0), positive=True),
            None if a.get("ramp_in") is None else _num(where, "ramp_in", a["ramp_in"], nonneg=True),
            None if a.get("ramp_out") is None else _num(where, "ramp_out", a["ramp_out"], nonneg=True),
            key, bool(a.get("auto_stop", True))))
    sync = data.get("synchronize", True)
    if not isinstance(sync, bool):
        raise ScriptError(f"{src}: synchronize must be true or false, got {sync!r}")
    return Script(
        tuple(out), tuple(clips), _num(src, "fps", data.get("fps", 60.0), positive=True),
        None if data.get("duration") is None else _num(src, "duration", data["duration"], positive=True),
        sync, _num(src, "nk", data.get("nk", 5), positive=True, integer=True),
        _num(src, "ramp_in", data.get("ramp_in", 0.4), nonneg=True),
        _num(src, "ramp_out", data.get("ramp_out", 0.4), nonneg=True),
        None if data.get("neutral") is None else str(data["neutral"]), str(data.get("name", "")),
        None if path is None else Path(path), tuple(mixes))


def load_script(path) -> Script:
    """Read and validate a YAML blend script."""
    import yaml

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except yaml.YAMLError as e:
        line = getattr(getattr(e, "problem_mark", None), "line", None)
        raise ScriptError(f"not valid YAML: {getattr(e, 'problem', e)}", p, None if line is None else line + 1) from None
    except UnicodeDecodeError:
        raise ScriptError("not a text file", p) from None
    return parse_script(data, p)


def build_library(script: Script, extra: dict | None = None):
    """The :class:`~kinodyn.clips.ClipStore` (with support) holding the clips the script uses.

    Built-in clips are loaded by name from :mod:`kinodyn.data.library`; ``clips`` entries from files;
    ``extra`` maps names to ``(Motion, cyclic)`` pairs given in code (they win over both).
    """
    from kinodyn.blend.library import add_blend, add_clip
    from kinodyn.clips import ClipStore

    extra = dict(extra or {})
    files = {c.name: c for c in script.clips}
    mixes = {m.name: m for m in script.mixes if m.name not in extra}
    wanted = [a.clip for a in script.actions]
    if script.neutral is not None:
        wanted.append(script.neutral)
    builtin_names: list[str] = []
    try:
        from kinodyn.data import library as data_lib

        builtin_names = data_lib.names()
    except ImportError:  # pragma: no cover - the library ships with the package
        data_lib = None
    where = f"{script.path}" if script.path else "script"
    # the clips mixes are made of come first, mixes after their parts (in the order they are written)
    order: list[str] = []

    def need(n, chain=()):
        if n in order:
            return
        if n in chain:
            raise ScriptError(f"{where}: clips.{n}: a mix cannot contain itself (through {' -> '.join(chain)})")
        if n in mixes:
            for part, _ in mixes[n].weights:
                need(part, chain + (n,))
        order.append(n)

    for n in dict.fromkeys(wanted):
        need(n)
    motions: dict[str, tuple[Motion, bool]] = {}
    for n in order:
        if n in mixes:
            continue
        if n in extra:
            motions[n] = extra[n]
        elif n in files:
            motions[n] = (files[n].load(), files[n].cyclic)
        elif n in builtin_names:
            motions[n] = (data_lib.load(n), data_lib.info(n).cyclic)
        else:
            known = sorted(set(builtin_names) | set(files) | set(extra) | set(mixes))
            raise ScriptError(f"{where}: unknown clip {n!r}; known clips: {', '.join(known)}")
    first = next(iter(motions.values()))[0]
    lib = ClipStore.empty(first.skeleton)
    for n, (m, cyc) in motions.items():
        lib = add_clip(lib, n, m, cyc)
    for n in order:
        if n in mixes:
            try:
                lib = add_blend(lib, n, dict(mixes[n].weights))
            except KinodynError as e:
                raise ScriptError(f"{where}: clips.{n}: {e}") from None
    if script.neutral is None and "idle" not in lib.names and "idle" in builtin_names:
        idle = data_lib.load("idle")
        if idle.skeleton.same_topology(lib.skeleton):  # the built-in standing pose as the neutral pose
            lib = add_clip(lib, "idle", idle, True)
    return lib


@dataclass
class BlendResult:
    """A script played through the mixer: plain arrays and records, no live mixer.

    Attributes:
        motion: the blended clip.
        recording: per-frame action times and weights (:class:`~kinodyn.blend.actions.Recording`).
        actions: ``{key: ActionRecord}`` every action started, in start order
            (:class:`~kinodyn.blend.actions.ActionRecord`: its adapted sequence, start and stop times).
        synchronized: whether the mixer synchronized the support phases.
        timing: ``{key: timing}`` each action's time-warp segments (the warp planner's history), or
            ``None`` without synchronization.
        sync_events: the synchronizer's events (:class:`~kinodyn.blend.sync.SyncEvent`), empty without.
        library: the clips used (:class:`~kinodyn.clips.ClipStore`).
        script: the script.
        starts: ``{key: (requested, actual)}`` start times (actual differs when synchronization delayed it).
    """

    motion: Motion
    recording: object
    actions: dict
    synchronized: bool
    timing: dict | None
    sync_events: tuple
    library: object
    script: Script
    starts: dict = field(default_factory=dict)

    def transition_mask(self, threshold: float = 1e-3) -> np.ndarray:
        """``(F,)`` frames where two or more actions have weight above ``threshold`` (the blends)."""
        rec = self.recording.arrays()
        ws = [rec[k][1] for k in rec if k not in ("t", "neutral")]
        if not ws:
            return np.zeros(self.motion.num_frames, dtype=bool)
        return (np.stack(ws) > threshold).sum(axis=0) >= 2

    def frame_phases(self, threshold: float = 1e-3) -> np.ndarray:
        """``(F,)`` combination of the support phases of the actions with weight above ``threshold``."""

        rec = self.recording.arrays()
        out = np.zeros(self.motion.num_frames, dtype=np.int8)
        for k, act in self.actions.items():
            if k not in rec:
                continue
            h, w = rec[k]
            on = (w > threshold) & np.isfinite(h)
            ph = np.zeros_like(out)
            ph[on] = act.seq.phase_at(h[on])
            out |= ph
        return out


def intended_contacts(result, threshold: float = 0.5) -> dict:
    """``{side: (F,) bool}``: frames where a foot *should* be planted according to the actions.

    A foot should be down when the weights of the actions whose current support phase puts it down (RS:
    right, LS: left, DS: both, the neutral pose: both) add up to at least ``threshold``. The same rule
    judges synchronized and unsynchronized blends, unlike contacts detected on the result (which can
    never see a foot that slides faster than the detector's speed threshold).
    """
    from kinodyn import phases as P

    rec = result.recording.arrays()
    n = result.motion.num_frames
    left = np.array(rec["neutral"][:n], dtype=np.float64)
    right = left.copy()
    for k, act in result.actions.items():
        if k not in rec:
            continue
        h, w = rec[k]
        on = np.isfinite(h) & (w > 0)
        ph = np.full(n, int(P.FLIGHT), dtype=np.int8)
        ph[on] = act.seq.phase_at(h[on])
        left += np.where((ph == P.LS) | (ph == P.DS), w, 0.0)
        right += np.where((ph == P.RS) | (ph == P.DS), w, 0.0)
    return {"left": left >= threshold, "right": right >= threshold}


def sliding_report(result, labels: dict | None = None, frames=None):
    """Foot sliding of a blend (:func:`kinodyn.contacts.sliding`) over the frames where the feet should
    be planted (:func:`intended_contacts`), optionally restricted to ``frames (F,) bool``."""
    from kinodyn import contacts

    m = result.motion
    c = contacts.detect(m, contacts.ContactConfig(floor=0.0))
    lab = intended_contacts(result) if labels is None else labels
    if frames is not None:
        lab = {s: lab[s] & frames for s in lab}
    return contacts.sliding(m, contacts.FootContacts(lab, c.lowest, c.lowest_velocity, c.floor, c.fps))


def _default_duration(script: Script, lib) -> float:
    end = 0.0
    for a in script.actions:
        ro = script.ramp_out if a.ramp_out is None else a.ramp_out
        if a.stop is not None:
            e = a.stop + ro
        elif lib.cyclic(a.clip):
            e = a.start + 4.0
        else:
            e = a.start + lib.duration(a.clip) / a.speed + 1.0
        end = max(end, e)
    return end + 0.5


def run_script(script: Script, synchronize: bool | None = None, library=None, extra=None,
               config=None) -> BlendResult:
    """Play a script through a one-character :class:`~kinodyn.blend.mixer.Mixer`.

    Args:
        script: a :class:`Script` (:func:`load_script`).
        synchronize: override the script's ``synchronize``.
        library: a ready :class:`~kinodyn.clips.ClipStore` with support (default: :func:`build_library`).
        extra: clips given in code for :func:`build_library`.
        config: a :class:`~kinodyn.blend.mixer.BlendConfig` overriding the script's settings.
    """
    from kinodyn.blend.mixer import BlendConfig, Mixer
    from kinodyn.blend.sync import SyncConfig

    lib = build_library(script, extra) if library is None else library
    sync = script.synchronize if synchronize is None else bool(synchronize)
    cfg = config or BlendConfig(synchronize=sync, sync=SyncConfig(nk=script.nk), ramp_in=script.ramp_in,
                                ramp_out=script.ramp_out)
    if config is not None and synchronize is not None:
        cfg = replace(cfg, synchronize=sync)
    neutral = script.neutral if script.neutral is not None else ("idle" if "idle" in lib.names else None)
    mixer = Mixer(lib, 1, cfg, neutral=neutral, record=True)
    fps = script.fps
    dt = 1.0 / fps
    duration = script.duration if script.duration is not None else _default_duration(script, lib)
    n = int(round(duration * fps)) + 1
    if n > MAX_FRAMES:
        where = script.path if script.path is not None else "script"
        raise ScriptError(f"{where}: {duration:g} s at {fps:g} fps is {n:,} frames, more than {MAX_FRAMES:,}; "
                          "shorten the script or lower its fps")
    cmds = []
    for i, a in enumerate(script.actions):
        key = a.key or f"{a.clip}@{a.start:g}"
        cmds.append((a.start, 0, i, "start", key, a))
        if a.stop is not None:
            cmds.append((a.stop, 1, i, "stop", key, a))
    cmds.sort(key=lambda c: (c[0], c[1], c[2]))
    mixer.time = -dt
    root = np.zeros((n, 3))
    rot = np.zeros((n, lib.skeleton.num_joints, 4))
    ci = 0
    history = {}
    starts = {}
    for f in range(n):
        t = f * dt
        while ci < len(cmds) and cmds[ci][0] <= t + 1e-9:
            _, _, _, kind, key, a = cmds[ci]
            ci += 1
            try:
                if kind == "start":
                    mixer.start(a.clip, priority=a.priority, ramp_in=a.ramp_in, ramp_out=a.ramp_out, speed=a.speed,
                                key=key, auto_stop=a.auto_stop, at=cmds[ci - 1][0])
                    history[key] = mixer.actions(0)[key]
                elif key in mixer.actions(0):
                    mixer.stop(key, at=cmds[ci - 1][0])
            except KinodynError as e:
                raise KinodynError(f"at {t:.3f} s, {kind} {key!r}: {e}") from None
        pose = mixer.step(dt)
        root[f] = pose.root_pos[0]
        rot[f] = pose.local_rot[0]
    for key, a in history.items():
        starts[key] = (a.requested, a.t_on)
    name = script.name or (script.path.stem if script.path else "blend")
    motion = Motion(lib.skeleton, root, rot, fps, name=name)
    ch = mixer.chars[0]
    timing = None if ch.planner is None else dict(ch.planner.timing_history)
    events = () if ch.sync is None else tuple(ch.sync.events)
    return BlendResult(motion, mixer.recordings[0], {k: a.record() for k, a in ch.history.items()},
                       cfg.synchronize, timing, events, lib, script, starts)
