"""Building blocks of the procedural clips: foot plans, keyframe tracks and whole-body assembly.

A clip is assembled from tracks sampled at the clip's frame times:

* the pelvis (root) position and rotation;
* local rotations of the upper body (spine, neck, head, clavicles, arms), usually keyframes
  interpolated with Catmull-Rom splines (:func:`key_track`);
* one :class:`FootPlan` per foot: stances, where the ball of the foot stays exactly in place (the heel
  may rise about it), joined by swings along smooth arcs, or splines through foot keys;
* optionally a hand target per arm.

:func:`assemble` turns them into a :class:`~kinodyn.motion.Motion`: the legs (and the arms that have
targets) are solved with the analytic two-bone IK of :mod:`kinodyn.data.legik`, knees bending toward
the facing direction, so a planted foot has exactly constant world position.

Conventions: those of :mod:`kinodyn.data.skeleton` (Z up, metres, facing +X). Euler angles, only used
for authoring, are degrees ``(rx, ry, rz)`` about the joint's rest axes, composed as
``R = Rz(rz) Ry(ry) Rx(rx)`` (:func:`euler`). Times are seconds; ``F`` is the number of frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinodyn.data import legik
from kinodyn.data.skeleton import ANKLE_HEIGHT, BALL, FOREARM, HEEL, SHIN, SOLE, THIGH, UPPER_ARM, humanoid
from kinodyn.errors import ParameterError
from kinodyn.math import interp, quat
from kinodyn.motion import Motion

__all__ = [
    "FPS",
    "SIDES",
    "STANCE",
    "Assembled",
    "BodyTracks",
    "FootPlan",
    "FootState",
    "assemble",
    "bump",
    "euler",
    "fk",
    "frame_times",
    "key_track",
    "quat_spline",
    "smoothstep",
    "stance_state",
    "standing_root_height",
    "yaw",
]

#: Frame rate of every built-in clip.
FPS = 60.0
SIDES = ("Left", "Right")
_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])
_ELBOW_HINGE = np.array([0.0, -1.0, 0.0])
_ELBOW_BEND = legik.bend_direction([0.0, 0.0, -1.0], _ELBOW_HINGE)

#: Neutral standing stance of each foot relative to the pelvis' floor point: ankle (x, y) and the
#: toe-out angle (deg) of the left foot; the right foot is its mirror image.
STANCE = {"ankle": (0.0, 0.11), "toe_out": 6.0}


def frame_times(duration: float, fps: float = FPS) -> np.ndarray:
    """``(F,)`` frame times from 0 to ``duration`` inclusive (``duration`` is rounded to whole frames)."""
    n = int(np.rint(duration * fps)) + 1
    return np.arange(n) / fps


def smoothstep(x) -> np.ndarray:
    """Quintic ease ``6x^5 - 15x^4 + 10x^3`` of ``x`` clipped to [0, 1] (zero speed and acceleration at
    both ends)."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def bump(x) -> np.ndarray:
    """``64 x^3 (1-x)^3`` on [0, 1], zero outside: a smooth hump with peak 1 at 0.5 and zero speed and
    acceleration at both ends."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return 64.0 * (x * (1.0 - x)) ** 3


def euler(deg) -> np.ndarray:
    """Quaternions ``(..., 4)`` from Euler angles in degrees ``(..., 3)`` = ``(rx, ry, rz)``, composed
    ``Rz(rz) Ry(ry) Rx(rx)``."""
    e = np.deg2rad(np.asarray(deg, dtype=np.float64))
    return quat.from_euler(e[..., ::-1], "zyx")


def yaw(angle_rad) -> np.ndarray:
    """Rotations ``(..., 4)`` about +Z."""
    return quat.from_heading(angle_rad)


def quat_spline(key_times, key_quats, times, ends: str = "zero") -> np.ndarray:
    """Catmull-Rom spline through rotation keys ``(K, ..., 4)``, evaluated at ``times (T,)``.

    The keys are put in one hemisphere (:func:`kinodyn.math.quat.unroll`), interpolated component-wise
    and normalized: smooth (C1) and exact at the keys.
    """
    q = quat.unroll(np.asarray(key_quats, dtype=np.float64))
    return quat.normalize(interp.catmull_rom(key_times, q, times, ends=ends))


def key_track(key_times, key_values, times, ends: str = "zero") -> np.ndarray:
    """Catmull-Rom spline through keys ``(K, ...)`` at ``times``; ``ends="zero"`` eases in and out."""
    kt = np.asarray(key_times, dtype=np.float64)
    if len(kt) == 1:
        return np.repeat(np.asarray(key_values, dtype=np.float64)[:1], len(times), axis=0)
    return interp.catmull_rom(kt, key_values, times, ends=ends)


# --------------------------------------------------------------------------- feet


@dataclass(frozen=True)
class FootState:
    """Where a foot is: the world position of its ball ``(3,)``, its world rotation ``(4,)`` and the
    toe joint's flexion (rad, about the foot's Y axis; negative lifts the toes relative to the foot)."""

    ball: np.ndarray
    rot: np.ndarray
    toe: float = 0.0

    def ankle(self) -> np.ndarray:
        """World position ``(3,)`` of the ankle."""
        return self.ball - quat.mul_vec(self.rot, BALL)

    def heel(self) -> np.ndarray:
        return self.ball + quat.mul_vec(self.rot, HEEL - BALL)


def stance_state(side: str, x: float = 0.0, y: float = 0.0, heading: float = 0.0, dx: float = 0.0,
                 dy: float = 0.0, dheading_deg: float = 0.0) -> FootState:
    """The flat foot of the neutral stance under a pelvis standing at ``(x, y)`` facing ``heading``
    (rad), moved by ``(dx, dy)`` metres and turned by ``dheading_deg`` in that frame."""
    sign = 1.0 if side == "Left" else -1.0
    ax, ay = STANCE["ankle"]
    h_local = np.deg2rad(sign * STANCE["toe_out"] + dheading_deg)
    c, s = np.cos(h_local), np.sin(h_local)
    ball_local = np.array([ax + dx + c * BALL[0], sign * ay + dy + s * BALL[0]])
    ch, sh = np.cos(heading), np.sin(heading)
    ball = np.array([x + ch * ball_local[0] - sh * ball_local[1], y + sh * ball_local[0] + ch * ball_local[1],
                     SOLE])
    return FootState(ball, yaw(heading + h_local))


@dataclass
class _Segment:
    t0: float
    t1: float
    fn: object  # times (n,) -> (ball (n, 3), rot (n, 4), toe (n,))
    end: FootState


class FootPlan:
    """The trajectory of one foot as a sequence of segments; the foot holds still between them.

    Segments are added in time order. While no segment is active the foot keeps the last state
    exactly, which is what makes planted feet slide-free.
    """

    def __init__(self, start: FootState):
        self.start = start
        self.segments: list[_Segment] = []

    @property
    def state(self) -> FootState:
        """The state after the last segment."""
        return self.segments[-1].end if self.segments else self.start

    @property
    def t_end(self) -> float:
        return self.segments[-1].t1 if self.segments else -np.inf

    def _add(self, t0: float, t1: float, fn, end: FootState) -> FootPlan:
        if t1 < t0:
            raise ParameterError(f"a foot segment must not end before it starts, got [{t0}, {t1}]")
        if t0 < self.t_end - 1e-9:
            raise ParameterError(f"foot segments must be added in time order: {t0} starts before {self.t_end}")
        self.segments.append(_Segment(float(t0), float(t1), fn, end))
        return self

    def roll(self, t0: float, t1: float, pitch_deg: float, pivot: str = "ball",
             toe_follow: bool = True, toe_deg: float | None = None) -> FootPlan:
        """Tilt the foot in place by ``pitch_deg`` about its Y axis (positive raises the heel) over
        ``[t0, t1]``, keeping the ball (``pivot="ball"``) or the heel (``"heel"``) fixed. With
        ``toe_follow`` the toes keep their world orientation (they stay flat on the floor); with
        ``toe_deg`` the toe joint goes to that angle instead."""
        s0 = self.state
        pitch = np.deg2rad(pitch_deg)
        heel0 = s0.heel()

        def fn(t):
            a = pitch * smoothstep((t - t0) / max(t1 - t0, 1e-9))
            rot = quat.mul(s0.rot, quat.from_axis_angle(_Y, a))
            if pivot == "ball":
                ball = np.broadcast_to(s0.ball, (len(t), 3)).copy()
            elif pivot == "heel":
                ball = heel0 + quat.mul_vec(rot, BALL - HEEL)
            else:
                raise ParameterError(f"pivot must be 'ball' or 'heel', got {pivot!r}")
            if toe_deg is not None:
                toe = s0.toe + (np.deg2rad(toe_deg) - s0.toe) * smoothstep((t - t0) / max(t1 - t0, 1e-9))
            else:
                toe = s0.toe - a if toe_follow else np.full(len(t), s0.toe)
            return ball, rot, toe

        b, r, tt = fn(np.array([t1]))
        return self._add(t0, t1, fn, FootState(b[0], r[0], float(tt[0])))

    def step(self, t_lift: float, t_land: float, target: FootState, height: float = 0.08,
             heel_off: float = 0.0, heel_pitch_deg: float = 0.0, delay: float = 0.04,
             side_bulge: float = 0.0, shape: tuple[float, float] = (2.0, 1.5),
             pitch_keys: tuple[tuple[float, float], ...] = ()) -> FootPlan:
        """Lift the foot at ``t_lift`` and put it down at ``target`` at ``t_land``.

        Args:
            height: peak lift of the ball above the straight path (m).
            heel_off: seconds before the lift during which the heel rises about the ball to
                ``heel_pitch_deg`` (toe-off); the toes stay flat.
            delay: fraction of the swing at each end during which the foot only moves vertically, so
                a foot near the floor never slides.
            side_bulge: sideways offset (m, +Y of the foot's heading) of the path's middle, to swing
                around the other leg.
            shape: exponents ``(a, b)`` of the height profile ``s^a (1-s)^b`` (scaled to peak at
                ``height``); ``a > b`` peaks late, ``a < b`` early. ``b < 2`` makes the foot come down
                from above rather than skim the floor.
            pitch_keys: ``(s, deg)`` pairs of extra pitch (positive: toes down) added to the foot's
                rotation along the swing (``s`` in (0, 1); zero at both ends); the toes take half of it
                back.
        """
        if heel_off > 0 and heel_pitch_deg != 0:
            self.roll(t_lift - heel_off, t_lift, heel_pitch_deg, "ball")
        s0 = self.state
        dur = max(t_land - t_lift, 1e-9)
        p0, p1 = s0.ball, target.ball
        q0, q1 = s0.rot, target.rot
        lateral = quat.mul_vec(q0, _Y)
        a, b = shape
        s_peak = a / (a + b)
        norm = 1.0 / (s_peak ** a * (1.0 - s_peak) ** b)
        pk_t = np.array([0.0] + [k[0] for k in pitch_keys] + [1.0])
        pk_v = np.deg2rad(np.array([0.0] + [k[1] for k in pitch_keys] + [0.0]))

        def fn(t):
            s = np.clip((t - t_lift) / dur, 0.0, 1.0)
            x = np.clip((s - delay) / max(1.0 - 2.0 * delay, 1e-9), 0.0, 1.0)
            w = x * x * (3.0 - 2.0 * x)
            sr = smoothstep(s)
            lift = height * norm * s ** a * (1.0 - s) ** b
            ball = p0 + (p1 - p0) * w[:, None]
            ball[:, 2] = p0[2] + (p1[2] - p0[2]) * sr + lift
            ball += side_bulge * bump(s)[:, None] * lateral
            extra = interp.catmull_rom(pk_t, pk_v, s, ends="zero") if len(pitch_keys) else np.zeros_like(s)
            rot = quat.mul(quat.slerp(q0, q1, sr), quat.from_axis_angle(_Y, extra))
            toe = s0.toe + (target.toe - s0.toe) * sr - 0.5 * extra
            return ball, rot, toe

        return self._add(t_lift, t_land, fn, target)

    def spline(self, t0: float, keys: list[tuple[float, FootState]]) -> FootPlan:
        """Move from the current state (at ``t0``) through foot keys ``(time, state)`` along
        Catmull-Rom splines that ease in at ``t0`` and out at the last key."""
        if not keys:
            raise ParameterError("a foot spline needs at least one key")
        s0 = self.state
        times = np.array([t0] + [k[0] for k in keys], dtype=np.float64)
        states = [s0] + [k[1] for k in keys]
        balls = np.array([s.ball for s in states])
        rots = np.array([s.rot for s in states])
        toes = np.array([s.toe for s in states])

        def fn(t):
            return key_track(times, balls, t), quat_spline(times, rots, t), key_track(times, toes, t)

        return self._add(t0, times[-1], fn, states[-1])

    def track(self, t0: float, key_times, fn) -> FootPlan:
        """Follow ``fn(times) -> (ball (T, 3), rot (T, 4), toe (T,))`` from ``t0`` to the last of
        ``key_times``, easing from the current state into it by the first key time."""
        s0 = self.state
        ta, t1 = max(float(key_times[0]), t0), float(key_times[-1])
        if t1 <= t0:
            raise ParameterError(f"a tracked foot segment must end after it starts, got {t0} to {t1}")

        def blended(t):
            ball, rot, toe = fn(t)
            w = smoothstep((t - t0) / (ta - t0)) if ta > t0 else np.ones_like(t)
            ball = (1.0 - w[:, None]) * s0.ball + w[:, None] * ball
            rot = quat.slerp(np.broadcast_to(s0.rot, rot.shape), rot, w)
            return ball, rot, (1.0 - w) * s0.toe + w * toe

        b, r, tt = fn(np.array([t1]))
        return self._add(t0, t1, blended, FootState(b[0], r[0], float(tt[0])))

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ball positions ``(F, 3)``, foot rotations ``(F, 4)`` and toe angles ``(F,)`` at ``times``."""
        t = np.asarray(times, dtype=np.float64)
        n = len(t)
        ball = np.broadcast_to(self.start.ball, (n, 3)).copy()
        rot = np.broadcast_to(self.start.rot, (n, 4)).copy()
        toe = np.full(n, float(self.start.toe))
        for seg in self.segments:
            after = t > seg.t1
            ball[after] = seg.end.ball
            rot[after] = seg.end.rot
            toe[after] = seg.end.toe
            inside = (t >= seg.t0) & (t <= seg.t1)
            if inside.any():
                b, r, tt = seg.fn(t[inside])
                ball[inside], rot[inside], toe[inside] = b, r, tt
        return ball, quat.unroll(rot), toe


# --------------------------------------------------------------------------- body


@dataclass
class BodyTracks:
    """Everything sampled at the frame times that :func:`assemble` needs.

    Attributes:
        times: ``(F,)`` seconds.
        root_pos: ``(F, 3)`` pelvis positions.
        root_rot: ``(F, 4)`` pelvis world rotations.
        local: joint name -> ``(F, 4)`` local rotations (joints left out stay at the rest pose).
        feet: ``"Left"``/``"Right"`` -> :class:`FootPlan` or sampled ``(ball, rot, toe)``.
        hands: optional ``"Left"``/``"Right"`` -> ``(target (F, 3), pole (F, 3), weight (F,))``: the
            wrist is put on the target by arm IK, blended with the keyframed arm by ``weight``.
    """

    times: np.ndarray
    root_pos: np.ndarray
    root_rot: np.ndarray
    local: dict[str, np.ndarray] = field(default_factory=dict)
    feet: dict = field(default_factory=dict)
    hands: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Assembled:
    """A generated clip and how well the IK met its targets.

    Attributes:
        motion: the clip.
        ik_error: largest distance (m) between a solved ankle or wrist and its target over all frames.
    """

    motion: Motion
    ik_error: float


def fk(root_pos, local_rot) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations ``(F, J, 4)`` and positions ``(F, J, 3)`` of the humanoid (pure numpy: the
    clips are short, and this keeps generation free of JIT start-up time)."""
    sk = humanoid()
    lp = np.broadcast_to(sk.offsets, local_rot.shape[:-1] + (3,)).copy()
    lp[..., 0, :] = root_pos
    return quat.fk(local_rot, lp, sk.parents)


def _foot_samples(foot, times):
    if isinstance(foot, FootPlan):
        return foot.sample(times)
    return foot


def assemble(tracks: BodyTracks, name: str = "") -> Assembled:
    """Solve the limbs and build the clip (see the module docstring)."""
    sk = humanoid()
    t = np.asarray(tracks.times, dtype=np.float64)
    f = len(t)
    lr = quat.identity((f, sk.num_joints))
    root_rot = quat.normalize(np.asarray(tracks.root_rot, dtype=np.float64))
    root_pos = np.asarray(tracks.root_pos, dtype=np.float64)
    lr[:, 0] = root_rot
    for jname, q in tracks.local.items():
        lr[:, sk.index(jname)] = quat.normalize(q)
    err = 0.0
    pelvis_fwd = quat.mul_vec(root_rot, _X)
    for side in SIDES:
        if side not in tracks.feet:
            continue
        ball, frot, toe = _foot_samples(tracks.feet[side], t)
        ankle = ball - quat.mul_vec(frot, BALL)
        j_hip = sk.index(f"{side}UpLeg")
        hip = root_pos + quat.mul_vec(root_rot, sk.offsets[j_hip])
        pole = pelvis_fwd + quat.mul_vec(frot, _X)
        sol = legik.two_bone_ik(hip, root_rot, ankle, pole, THIGH, SHIN)
        lr[:, j_hip] = sol.upper_local
        lr[:, sk.index(f"{side}Leg")] = sol.lower_local
        lr[:, sk.index(f"{side}Foot")] = quat.inv_mul(sol.lower_world, frot)
        lr[:, sk.index(f"{side}ToeBase")] = quat.from_axis_angle(_Y, toe)
        _, end = legik.two_bone_fk(hip, root_rot, sol.upper_local, sol.lower_local, THIGH, SHIN)
        err = max(err, float(np.max(np.linalg.norm(end - ankle, axis=-1))))
    if tracks.hands:
        gr, gp = fk(root_pos, lr)
        for side, (target, pole, weight) in tracks.hands.items():
            j_arm = sk.index(f"{side}Arm")
            j_par = sk.parents[j_arm]
            # Blend in target space: at weight 0 the keyed wrist position and elbow direction, which
            # the solver reproduces exactly, so the keyed arm and the solved arm join smoothly.
            w = np.clip(np.asarray(weight, dtype=np.float64), 0.0, 1.0)[:, None]
            wrist = gp[:, sk.index(f"{side}Hand")]
            elbow_dir = quat.mul_vec(gr[:, j_arm], _ELBOW_BEND)
            goal = (1.0 - w) * wrist + w * np.asarray(target, dtype=np.float64)
            pole = np.asarray(pole, dtype=np.float64)
            pole = pole / np.linalg.norm(pole, axis=-1, keepdims=True)
            bend = (1.0 - w) * elbow_dir + w * pole
            sol = legik.two_bone_ik(gp[:, j_arm], gr[:, j_par], goal, bend, UPPER_ARM, FOREARM,
                                    hinge=_ELBOW_HINGE)
            lr[:, j_arm] = sol.upper_local
            lr[:, sk.index(f"{side}ForeArm")] = sol.lower_local
            _, end = legik.two_bone_fk(gp[:, j_arm], gr[:, j_par], sol.upper_local, sol.lower_local,
                                       UPPER_ARM, FOREARM)
            err = max(err, float(np.max(np.linalg.norm(end - goal, axis=-1))))
    motion = Motion(sk, root_pos, quat.unroll(lr), FPS, name=name)
    return Assembled(motion, err)


def standing_root_height() -> float:
    """Pelvis height of the neutral stance with softly bent knees."""
    return ANKLE_HEIGHT + 0.855 + 0.06
