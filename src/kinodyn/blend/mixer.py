"""The real-time motion mixer: actions with priorities and ramps, synchronized, blended per frame.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, sections 3 and 5 (after the
blending module of their reference [Lba]). An *action* plays a clip (or a clip adapted by a parametric
model, such as a time scaling) and is started and stopped at any time. Its weight ramps up from 0
over ``ramp_in`` seconds after it starts (``t1 -> t2`` of figure 2) and down to 0 over ``ramp_out``
seconds after it is stopped (``t3 -> t4``), with a smoothstep. *Priorities* resolve the weights:
actions of a higher priority take the legs and body first (their summed activation, capped at 1, is
their share), lower ones get what is left, and a neutral double-support pose of lowest priority takes
the remainder, so the character stands when nothing plays. Actions of the same priority share by
activation.

With ``synchronize=True`` every character runs a :class:`~kinodyn.blend.sync.Synchronizer` and a
:class:`~kinodyn.blend.timewarp.WarpPlanner`: actions start at a step boundary, their support phases
are organized so that no step mixes a left and a right single support, and each action's time is
warped to the common steps. An action stopped while another waits for its synchronized start hands
over: it plays on until the newcomer starts, then fades out. With ``synchronize=False`` (the baseline)
actions start when asked and play at their own speed.

Blending: local joint rotations are averaged with the weights (normalized weighted sum of
hemisphere-aligned quaternions, or Markley's eigenvector mean); the root is blended in each action's
*facing frame*: its height and its rotation without heading are averaged, and its motion over the
frame (floor displacement and heading change, expressed in the action's own facing frame) is averaged
and integrated in the character's frame, so a mix of straight walks goes straight. With
synchronization the support constraints are then enforced (:mod:`kinodyn.blend.footlock`): the
planted feet stay where they landed.

Per-frame evaluation is batched over characters: every array is ``(N, S, ...)`` for ``N`` characters
and ``S`` action slots (numpy, with the frame blend and the leg IK as compiled kernels looping over
characters); Python runs per character only when one of its steps ends or on a command.

The parts: :mod:`~kinodyn.blend.weights` (ramps and priorities), :mod:`~kinodyn.blend.pose` (pose
blending), :mod:`~kinodyn.blend.actions` (actions and the record), :mod:`~kinodyn.blend.character`
(each character's actions, synchronizer and slot arrays), :mod:`~kinodyn.blend.footlock` (the support
constraints); clips come from a :class:`~kinodyn.clips.ClipStore` with support
(:mod:`~kinodyn.blend.library`).

Shapes: ``J`` joints. Units: seconds, metres, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinodyn.blend import library as _library
from kinodyn.blend.actions import ActionState, Recording
from kinodyn.blend.character import Character, Slots
from kinodyn.blend.footlock import FootLock
from kinodyn.phases import PhaseSequence
from kinodyn.blend.pose import Pose, blend_frames_fast, blend_rotations
from kinodyn.blend.sync import SyncConfig
from kinodyn.blend.timewarp import WarpConfig
from kinodyn.blend.weights import mix_weights
from kinodyn.clips import ClipStore, unroll_loops
from kinodyn.errors import ParameterError
from kinodyn.math import quat, xform
from kinodyn.motion import Motion

__all__ = ["ActionState", "BlendConfig", "Mixer", "Pose", "Recording"]

_AVERAGES = ("nlerp", "markley")


@dataclass(frozen=True)
class BlendConfig:
    """Mixer parameters.

    Attributes:
        synchronize: run the support-phase synchronization (False: the unsynchronized baseline).
        sync: :class:`~kinodyn.blend.sync.SyncConfig` (``nk``).
        warp: :class:`~kinodyn.blend.timewarp.WarpConfig` (spline tension).
        ramp_in: default activation duration ``t2 - t1`` in seconds.
        ramp_out: default deactivation duration ``t4 - t3`` in seconds.
        max_actions: action slots per character (actions playing or fading at once).
        average: ``"nlerp"`` (normalized weighted sum, fast) or ``"markley"`` (eigenvector mean).
        constraints: enforce the support after blending (:mod:`kinodyn.blend.footlock`): planted feet
            stay where they landed (the root follows the held feet by the weight each carries,
            two-bone IK pins them). ``"auto"``: on with synchronization, off without (without synchronization the
            actions disagree on which foot carries the body, so there is no single constraint to
            enforce); ``"on"`` / ``"off"`` force it.
        root_halflife: seconds for the root to follow the held feet (IK pins the feet in
            the meantime; a short halflife keeps the legs natural, a non-zero one keeps the root
            smooth when the support changes foot).
        release_halflife: seconds over which a lifted foot's IK correction fades out.
        max_foot_offset: metres a planted foot may be held away from where the blended pose puts it,
            all the lock does to it counted (this frame's root follow, the IK's offset, the height
            correction: the displacement :mod:`~kinodyn.blend.evaluate` reports); beyond that, or beyond
            what the leg reaches, it follows the pose (it slides) instead of stretching the leg. The
            height correction is never given up (the foot would go through the floor).
        max_pelvis_drop: metres the pelvis may come down so that a planted foot stays within its leg's
            reach (a straight back leg at push-off); 0 never lowers it.
        root_motion: how the root moves over the floor. ``"clips"``: the weighted mix of the actions'
            root displacements. ``"support"`` (default): the same, then corrected so that the feet the
            actions' support phases plant stay in place (each by the share of the weight it carries).
            While weights ramp, the mix of displacements alone moves a planted foot by the weight change
            times the difference of where the clips put that foot; with synchronized supports there is
            one planted foot to follow, without them the actions disagree on it.
        closing_step: with synchronization, an action stopped while nothing else plays (fading into
            the neutral pose) plays on, up to :data:`~kinodyn.blend.character.CLOSING_DELAY` seconds,
            so that its weight passes one half when its feet stand where the neutral pose's do: the
            feet come down there instead of the lock holding them where the action left them. And an
            in-place action (a jump, a kick: non-cyclic, starting with a long double support) asked
            for over a locomotion cycle starts at the step where the cycle's feet best match its
            first frames; the cycle then leaves the synchronization and fades out at its own speed
            (it ends there), and the in-place action plays at its own speed.
    """

    synchronize: bool = True
    sync: SyncConfig = SyncConfig()
    warp: WarpConfig = WarpConfig()
    ramp_in: float = 0.4
    ramp_out: float = 0.4
    max_actions: int = 6
    average: str = "nlerp"
    constraints: str = "auto"
    root_halflife: float = 0.04
    release_halflife: float = 0.05
    max_foot_offset: float = 0.5
    max_pelvis_drop: float = 0.05
    root_motion: str = "support"
    closing_step: bool = True

    @property
    def enforce(self) -> bool:
        """Whether support constraints are enforced (see ``constraints``)."""
        return self.constraints == "on" or (self.constraints == "auto" and self.synchronize)

    def __post_init__(self):
        for name in ("ramp_in", "ramp_out"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"{name} must be a non-negative number of seconds, got {v}")
        if not isinstance(self.max_actions, int) or self.max_actions < 1:
            raise ParameterError(f"max_actions must be an integer >= 1, got {self.max_actions!r}")
        if self.constraints not in ("auto", "on", "off"):
            raise ParameterError(f"constraints must be 'auto', 'on' or 'off', got {self.constraints!r}")
        if not (np.isfinite(self.max_foot_offset) and self.max_foot_offset > 0):
            raise ParameterError(f"max_foot_offset must be a positive number of metres, got {self.max_foot_offset}")
        for name in ("root_halflife", "release_halflife", "max_pelvis_drop"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"{name} must be a non-negative number of seconds, got {v}")
        if self.root_motion not in ("clips", "support"):
            raise ParameterError(f"root_motion must be 'clips' or 'support', got {self.root_motion!r}")
        if self.average not in _AVERAGES:
            raise ParameterError(f"average must be one of {', '.join(_AVERAGES)}, got {self.average!r}")


class Mixer:
    """Mixes actions for ``N`` characters, one frame at a time (mutable real-time state).

    Args:
        library: the :class:`~kinodyn.clips.ClipStore` the actions play from, with each clip's support
            (built by :mod:`kinodyn.blend.library`).
        n_characters: number of characters mixed together.
        config: :class:`BlendConfig`.
        neutral: the neutral double-support pose: a clip name (its first frame), a
            :class:`~kinodyn.motion.Motion` (first frame), or ``None`` for the ``idle`` clip when the
            library has one, else the first double-support frame of the first clip.
        record: keep a per-frame :class:`Recording` of every character (for plots and checks).

    Attributes:
        slots: the :class:`~kinodyn.blend.character.Slots` arrays every frame is evaluated from.
        chars: one :class:`~kinodyn.blend.character.Character` per character (its actions and history).
        footlock: the :class:`~kinodyn.blend.footlock.FootLock` (support constraints and their state).
        ground: ``(N, 3)`` each character's ground transform ``(x, y, heading)``.
        compiled: False runs the numpy reference of the weights (for tests).

    Example::

        library = kinodyn.blend.library.builtin(["idle", "walk", "run"])
        mixer = Mixer(library)
        mixer.start("walk", priority=1)
        for _ in range(120):
            pose = mixer.step(1 / 60)
    """

    def __init__(self, library: ClipStore, n_characters: int = 1, config: BlendConfig = BlendConfig(),
                 neutral=None, record: bool = False, keep_log: bool | None = None):
        if not isinstance(library, ClipStore):
            raise ParameterError(f"library must be a ClipStore, got {type(library).__name__}")
        if not isinstance(n_characters, (int, np.integer)) or n_characters < 1:
            raise ParameterError(f"n_characters must be a positive integer, got {n_characters!r}")
        self.library = library
        self.config = config
        self.n = int(n_characters)
        self.keep_log = record if keep_log is None else keep_log
        self.time = 0.0
        self.slots = Slots(self.n, config.max_actions)
        self.ground = np.zeros((self.n, 3))
        self.footlock = FootLock(library.skeleton, self.n, config)
        self.compiled = True
        self.sequences = _library.sequences(library)
        self.neutral = self._neutral_pose(neutral)
        self.neutral_rest = self.footlock.rest_of_pose(*self.neutral)
        self.chars = [Character(i, self.slots, library, self.sequences, config, self.keep_log) for i in range(self.n)]
        if config.closing_step and self.footlock.legs is not None:
            nf = self._neutral_feet()
            for c in self.chars:
                c.neutral_feet = nf
        self.recordings = [Recording() for _ in range(self.n)] if record else None

    @property
    def support(self) -> np.ndarray:
        """``(N,)`` planted foot carrying most weight: 0 none, 1 left, 2 right (the foot lock's)."""
        return self.footlock.support

    # ------------------------------------------------------------------ setup
    def _neutral_pose(self, neutral):
        lib = self.library
        if isinstance(neutral, Motion):
            tmp = _library.add_clip(ClipStore.empty(lib.skeleton), "neutral",
                                    neutral[:2] if neutral.num_frames >= 2 else neutral)
            rot, z = tmp.sample(np.array([0]), np.array([0.0]))
            return rot[0], float(z[0])
        k, t = _library.neutral_source(lib, self.sequences, neutral)
        rot, z = lib.sample(np.array([k]), np.array([t]))
        return rot[0], float(z[0])

    def _neutral_feet(self) -> np.ndarray:
        """``(2, 2)`` horizontal positions of the neutral pose's lowest left and right foot points, in
        its facing frame with the root at the origin."""
        from kinodyn import contacts

        rot, z = self.neutral
        pose = Motion(self.library.skeleton, np.array([[0.0, 0.0, z]]), rot[None], 60.0)
        pts = contacts.foot_points(pose)
        return np.stack([p[0, p[0, :, 2].argmin(), :2] for p in (pts["left"], pts["right"])])

    # ------------------------------------------------------------------ commands
    def start(self, clip, character: int = 0, priority: float = 0.0, ramp_in: float | None = None,
              ramp_out: float | None = None, speed: float = 1.0, key=None, auto_stop: bool = True,
              at: float | None = None):
        """Start an action playing ``clip`` on ``character``; returns its key.

        Args:
            clip: library clip name or index.
            priority: higher overrides lower.
            ramp_in, ramp_out: activation / deactivation durations (default: the config's).
            speed: time scaling of the clip (and of its sequence).
            key: identifier (default: the clip name, suffixed when taken).
            auto_stop: a non-cyclic clip fades out by itself at its end.
            at: time of the command, within the frame being prepared (default: the mixer's time).
        """
        c = self._char(character)
        idx = self.library.index(clip)
        if not (np.isfinite(speed) and speed > 0):
            raise ParameterError(f"speed must be a positive number, got {speed!r}")
        if not np.isfinite(priority):
            raise ParameterError(f"priority must be a finite number, got {priority!r}")
        ri = self.config.ramp_in if ramp_in is None else float(ramp_in)
        ro = self.config.ramp_out if ramp_out is None else float(ramp_out)
        if ri < 0 or ro < 0 or not (np.isfinite(ri) and np.isfinite(ro)):
            raise ParameterError(f"ramps must be non-negative seconds, got ramp_in={ri}, ramp_out={ro}")
        if key is None:
            base = self.library.names[idx]
            key, i = base, 1
            while key in c.actions:
                i += 1
                key = f"{base}#{i}"
        c.start(key, idx, float(speed), float(priority), ri, ro, auto_stop, self._at(at))
        return key

    def stop(self, key, character: int = 0, at: float | None = None) -> None:
        """Stop an action: it fades out over its ``ramp_out``. A start still waiting is cancelled; an action
        stopped while another waits for its synchronized start plays on until that one starts (hand-over).
        """
        self._char(character).stop(key, self._at(at))

    def _at(self, at) -> float:
        if at is None:
            return self.time
        at = float(at)
        if not np.isfinite(at) or at < self.time - 1e-9:
            raise ParameterError(f"a command cannot be dated before the mixer's time {self.time:.6f} s, got {at}")
        return at

    def actions(self, character: int = 0) -> dict:
        """The character's :class:`ActionState` objects by key."""
        return dict(self._char(character).actions)

    def _char(self, i) -> Character:
        if not isinstance(i, (int, np.integer)) or not 0 <= int(i) < self.n:
            raise ParameterError(f"character must be an index in [0, {self.n}), got {i!r}")
        return self.chars[int(i)]


    # ------------------------------------------------------------------ per frame
    def step(self, dt: float) -> Pose:
        """Advance every character by ``dt`` seconds and return their poses."""
        if not (np.isfinite(dt) and dt > 0):
            raise ParameterError(f"dt must be a positive number of seconds, got {dt!r}")
        t = self.time + float(dt)
        for i in np.nonzero(self.slots.next <= t)[0]:
            self.chars[i].advance(t)
        self.time = t
        return self._evaluate(t, dt=float(dt))

    def pose(self) -> Pose:
        """The poses at the current time without advancing (no root motion)."""
        return self._evaluate(self.time, move=False)

    def _evaluate(self, t: float, move: bool = True, dt: float = 0.0) -> Pose:
        """Poses of every character at time ``t`` (batched; see the module docstring)."""
        P, sl = self.library, self.slots
        S = max(int(sl.count.max()), 1)
        r = sl.ramp[:, :S]
        h, tau, w, wn = mix_weights(t, sl.seg[:, :S], sl.speed[:, :S], r, sl.prio[:, :S], self.compiled)
        clip = sl.clip[:, :S]
        i0, a, cyc, g = P.locate(clip, tau)
        fresh = sl.fresh[:, :S]
        g_prev = np.where(fresh[..., None], g, sl.prev_g[:, :S])
        cyc_prev = np.where(fresh, cyc, sl.prev_cyc[:, :S])
        sl.prev_g[:, :S] = g
        sl.prev_cyc[:, :S] = cyc
        sl.prev_tau[:, :S] = tau
        sl.fresh[:] = False
        phase = P.frame_phase[np.where(a < 0.5, i0, i0 + 1)]
        q, zz = self._blend(i0, a, w, wn)
        if move:
            g = unroll_loops(P.loop[clip], g, np.maximum(cyc - cyc_prev, 0))
            d = (w[..., None] * xform.relative(g_prev, g)).sum(axis=1)
            self.ground = xform.compose(self.ground, d)
        g = self.ground
        root = np.stack([g[:, 0], g[:, 1], zz], axis=1)
        q[:, 0] = quat.mul(quat.from_heading(g[:, 2]), q[:, 0])
        follow = self.config.enforce or self.config.root_motion == "support"
        if move and follow and self.footlock.legs is not None:
            sh = P.left_share
            total = np.maximum(w.sum(axis=1) + wn, 1e-12)
            left = ((w * (sh[i0] * (1.0 - a) + sh[i0 + 1] * a)).sum(axis=1) + 0.5 * wn) / total
            rest = ((w * P.rest[clip]).sum(axis=1) + wn * self.neutral_rest) / total
            root, q = self.footlock.constrain(root, q, w, wn, phase, left, rest, dt, g[:, 2], pin=self.config.enforce)
            self.ground = np.concatenate([root[:, :2], g[:, 2:]], axis=1)
        if self.recordings is not None and move:
            held = self.config.enforce and self.footlock.legs is not None
            self._record(t, h, w, wn, r, self.footlock.offset if held else None)
        return Pose(root, q)

    def _blend(self, i0, a, w, wn):
        """Blended facing-frame rotations ``(N, J, 4)`` and root heights ``(N,)`` of the sampled frames."""
        P = self.library
        nrot, nz = self.neutral
        if self.config.average == "markley":
            a4 = a[..., None, None]
            rot = P.rot[i0] * (1.0 - a4) + P.rot[i0 + 1] * a4
            q = blend_rotations(rot, w, nrot, wn, "markley")
        else:
            q = blend_frames_fast(P.rot, i0, a, w, nrot, wn)
        zdb = P.z
        z = zdb[i0] * (1.0 - a) + zdb[i0 + 1] * a
        return q, (w * z).sum(axis=1) + wn * nz

    def _record(self, t, h, w, wn, r, offset=None):
        for n, rec in enumerate(self.recordings):
            fi = len(rec.times)
            rec.times.append(t)
            rec.neutral.append(float(wn[n]))
            rec.lock_offset.append((np.nan, np.nan) if offset is None else tuple(offset[n]))
            for s, key in enumerate(self.slots.keys[n]):
                if key is None:
                    continue
                rec.action_time.setdefault(key, {})[fi] = float(h[n, s]) if np.isfinite(r[n, s, 0]) else np.nan
                rec.weight.setdefault(key, {})[fi] = float(w[n, s])

    # ------------------------------------------------------------------ offline
    def sequence_of(self, key, character: int = 0) -> PhaseSequence:
        """The adapted support-phase sequence of a playing action."""
        return self._char(character).actions[key].seq
