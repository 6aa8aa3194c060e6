"""Clips authored as keyframes in ``keyframes.json`` (punch, kick, push, reactions, falls, turns).

The file is meant to be read and edited by people. Its parts:

* ``poses``: named upper-body poses, joint -> Euler degrees ``[rx, ry, rz]`` about the joint's rest
  axes (X forward, Y left, Z up), composed ``R = Rz Ry Rx`` (:func:`kinodyn.data.procedural.euler`).
* ``clips``: one entry per clip with
    - ``duration`` (s), ``description``, ``tags``;
    - ``root``: pelvis keys ``{"t", "pos": [x, y, z], "rot": [rx, ry, rz]}`` (world, metres/degrees);
    - ``pose``: upper-body keys ``{"t", "base": pose name, JOINT: [rx, ry, rz], ...}``; a key starts from
      the previous key (the first from ``base``, default ``"stand"``) and overrides the joints it lists;
    - ``feet``: per side, a list of foot actions in time order (the foot starts in the neutral stance
      under the pelvis at t = 0 and holds still between actions):
        * ``{"step": [t_lift, t_land], "to": [dx, dy, dheading]}``: step to the neutral stance under
          the pelvis at landing time, moved by ``dx, dy`` metres and turned ``dheading`` degrees in the
          pelvis' floor frame; or ``"at": [x, y, heading]`` in the world; or ``"leg": {UpLeg, Leg, Foot,
          ToeBase}`` Euler keys: land where those leg angles put the foot, lowered or raised until its
          lowest point rests on the floor. Options: ``height``,
          ``heel_off: [seconds, degrees]``, ``bulge``, ``shape``, ``pitch_keys``.
        * ``{"roll": [t0, t1], "pitch": deg, "pivot": "ball" | "heel"}``: tilt the foot in place; the
          toes stay flat unless ``"toe_follow": false`` or ``"toe": deg`` (final toe angle) is given.
        * ``{"spline": t0, "keys": [{"t", "ankle" | "ball": [x, y, z], "rot": [rx, ry, rz], "toe": deg,
          "frame": "pelvis"}]}``: move through keys (positions in the world, or with ``"frame":
          "pelvis"`` in the pelvis' floor frame at ``t0``).
        * ``{"legs": t0, "keys": [{"t", "UpLeg", "Leg", "Foot", "ToeBase": [rx, ry, rz]}]}``: the leg
          follows keyed joint angles, carried by the pelvis (a leg off the floor: rolls, kicks from the
          floor); from the foot's state at ``t0`` it eases into the keyed leg by the first key.
    - ``hands``: per side ``{"pole": [x, y, z], "keys": [{"t", "pos": [x, y, z], "w": weight}]}``: wrist
      targets in the world (every clip starts at the origin facing +X), blended over the keyed arm
      with weight ``w``; the elbow points toward ``pole``; targets out of reach are pulled in to
      98.5 % of the arm's length.
    - ``floor_guard`` (optional, for falls): after solving, wherever a joint or end site would dip
      under the floor the pelvis is lifted by a smoothed amount (planted feet stay where they are).
    - ``start`` (optional): per side ``[dx, dy, dheading]`` moving the starting foot from the neutral
      stance, or a foot key ``{"ball" | "ankle": [x, y, z], "rot": [rx, ry, rz], "toe": deg}`` in the
      world (a clip that starts lying down, as a fall ends).

Interpolation is Catmull-Rom everywhere (easing in and out at the first and last keys).
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

import numpy as np

from kinodyn.data import procedural as P
from kinodyn.data.skeleton import BALL, FOREARM, SHIN, THIGH, UPPER_ARM, humanoid
from kinodyn.errors import ParameterError, UnknownNameError
from kinodyn.math import quat

__all__ = ["UPPER_BODY", "build", "clip_spec", "keyed_names", "keyframe_data"]

#: Joints driven by pose keys (the legs are solved from the feet).
UPPER_BODY = ("Spine", "Spine1", "Neck", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
              "RightShoulder", "RightArm", "RightForeArm", "RightHand")
_DOWN = np.array([0.0, 0.0, -1.0])
FLOOR_MARGIN = 0.004


@lru_cache(maxsize=1)
def keyframe_data() -> dict:
    """The parsed ``keyframes.json`` shipped with the package."""
    text = resources.files("kinodyn.data").joinpath("keyframes.json").read_text(encoding="utf-8")
    return json.loads(text)


def keyed_names() -> list[str]:
    return list(keyframe_data()["clips"])


def clip_spec(name: str) -> dict:
    clips = keyframe_data()["clips"]
    if name not in clips:
        raise UnknownNameError(f"no keyframed clip named {name!r}; keyframed clips: {', '.join(clips)}")
    return clips[name]


def _resolve_pose_keys(keys: list[dict], poses: dict) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Key times ``(K,)`` and joint -> ``(K, 4)`` rotations of the pose keys."""
    times, resolved = [], []
    current = None
    for k in keys:
        base = k.get("base")
        if base is not None or current is None:
            base = base or "stand"
            if base not in poses:
                raise UnknownNameError(f"no pose named {base!r}; poses: {', '.join(poses)}")
            current = dict(poses[base])
        else:
            current = dict(current)
        for joint, v in k.items():
            if joint in ("t", "base"):
                continue
            if joint not in UPPER_BODY:
                raise ParameterError(f"pose keys may set upper-body joints only ({', '.join(UPPER_BODY)}), "
                                     f"got {joint!r}")
            current[joint] = v
        times.append(float(k["t"]))
        resolved.append(current)
    out = {}
    for joint in UPPER_BODY:
        eul = np.array([r.get(joint, [0.0, 0.0, 0.0]) for r in resolved], dtype=np.float64)
        out[joint] = P.euler(eul)
    return np.array(times), out


class _Root:
    """Pelvis keys as continuous functions of time."""

    def __init__(self, keys: list[dict]):
        self.t = np.array([float(k["t"]) for k in keys])
        self.pos = np.array([k["pos"] for k in keys], dtype=np.float64)
        self.rot = P.euler(np.array([k.get("rot", [0.0, 0.0, 0.0]) for k in keys], dtype=np.float64))

    def sample(self, times) -> tuple[np.ndarray, np.ndarray]:
        times = np.atleast_1d(np.asarray(times, dtype=np.float64))
        return P.key_track(self.t, self.pos, times), P.quat_spline(self.t, self.rot, times) \
            if len(self.t) > 1 else np.repeat(self.rot[:1], len(times), axis=0)

    def ground(self, t: float) -> tuple[float, float, float]:
        """Floor position and heading (rad) of the pelvis at time ``t``."""
        p, q = self.sample([t])
        return float(p[0, 0]), float(p[0, 1]), float(quat.heading(q[0]))


def _leg_target(side: str, root: _Root, t: float, leg: dict) -> P.FootState:
    """Where the foot is when the leg has the given Euler angles and the pelvis its pose at ``t``,
    moved vertically so that its lowest point (ankle, ball, heel or toe tip) rests at ``SOLE``."""
    sk = humanoid()
    p, q = root.sample([t])
    p, q = p[0], q[0]
    hip = p + quat.mul_vec(q, sk.offsets[sk.index(f"{side}UpLeg")])
    thigh = quat.mul(q, P.euler(leg.get("UpLeg", [0, 0, 0])))
    knee = hip + quat.mul_vec(thigh, THIGH * _DOWN)
    shank = quat.mul(thigh, P.euler(leg.get("Leg", [0, 0, 0])))
    ankle = knee + quat.mul_vec(shank, SHIN * _DOWN)
    foot = quat.mul(shank, P.euler(leg.get("Foot", [0, 0, 0])))
    toe = float(np.deg2rad(leg.get("ToeBase", [0, 0, 0])[1]))
    state = P.FootState(ankle + quat.mul_vec(foot, BALL), foot, toe)
    if leg.get("floor", True):
        low = min(z for z in _foot_point_heights(state))
        state = P.FootState(state.ball + np.array([0.0, 0.0, P.SOLE - low]), state.rot, state.toe)
    return state


def _leg_track(side: str, root: _Root, keys: list[dict]):
    """``fn(times) -> (ball (T, 3), rot (T, 4), toe (T,))``: where the keyed leg angles put the foot."""
    sk = humanoid()
    kt = np.array([float(k["t"]) for k in keys])
    joints = {j: P.euler(np.array([k.get(j, [0.0, 0.0, 0.0]) for k in keys], dtype=np.float64))
              for j in ("UpLeg", "Leg", "Foot")}
    toe_keys = np.deg2rad([float(k.get("ToeBase", [0.0, 0.0, 0.0])[1]) for k in keys])

    def fn(times):
        times = np.atleast_1d(np.asarray(times, dtype=np.float64))
        q = {j: P.quat_spline(kt, v, times) if len(kt) > 1 else np.repeat(v[:1], len(times), 0)
             for j, v in joints.items()}
        p, r = root.sample(times)
        hip = p + quat.mul_vec(r, sk.offsets[sk.index(f"{side}UpLeg")])
        thigh = quat.mul(r, q["UpLeg"])
        knee = hip + quat.mul_vec(thigh, THIGH * _DOWN)
        shank = quat.mul(thigh, q["Leg"])
        ankle = knee + quat.mul_vec(shank, SHIN * _DOWN)
        foot = quat.mul(shank, q["Foot"])
        return ankle + quat.mul_vec(foot, BALL), foot, P.key_track(kt, toe_keys, times)

    return fn


def _foot_point_heights(state: P.FootState) -> list[float]:
    """Heights of the ankle, (virtual) heel, ball and toe tip of a foot state."""
    sk = humanoid()
    tip_offset = sk.end_offsets[list(sk.end_parents).index(sk.index("LeftToeBase"))]
    toe_rot = quat.mul(state.rot, quat.from_axis_angle([0.0, 1.0, 0.0], state.toe))
    tip = state.ball + quat.mul_vec(toe_rot, tip_offset)
    return [float(state.ankle()[2]), float(state.heel()[2]), float(state.ball[2]), float(tip[2])]


def _foot_key_state(side: str, key: dict, frame) -> P.FootState:
    rot = P.euler(key.get("rot", [0.0, 0.0, 0.0]))
    gx, gy, gh = frame
    g = quat.from_heading(gh)
    if "ankle" in key:
        pos = np.asarray(key["ankle"], dtype=np.float64)
    elif "ball" in key:
        pos = np.asarray(key["ball"], dtype=np.float64)
    else:
        raise ParameterError(f"a {side} foot key needs 'ankle' or 'ball', got {sorted(key)}")
    if key.get("frame") == "pelvis":
        pos = quat.mul_vec(g, pos) + np.array([gx, gy, 0.0])
        rot = quat.mul(g, rot)
    ball = pos + quat.mul_vec(rot, BALL) if "ankle" in key else pos
    return P.FootState(ball, rot, float(np.deg2rad(key.get("toe", 0.0))))


def _foot_plan(side: str, actions: list[dict], root: _Root, start_offset=(0.0, 0.0, 0.0)) -> P.FootPlan:
    gx, gy, gh = root.ground(0.0)
    if isinstance(start_offset, dict):
        plan = P.FootPlan(_foot_key_state(side, start_offset, (0.0, 0.0, 0.0)))
    else:
        plan = P.FootPlan(P.stance_state(side, gx, gy, gh, *start_offset))
    for a in actions:
        if "step" in a:
            t0, t1 = (float(x) for x in a["step"])
            if "at" in a:
                x, y, h = a["at"]
                target = P.FootState(np.array([x, y, P.SOLE]), P.yaw(np.deg2rad(h)))
            elif "leg" in a:
                target = _leg_target(side, root, t1, a["leg"])
            else:
                dx, dy, dh = a.get("to", (0.0, 0.0, 0.0))
                target = P.stance_state(side, *root.ground(t1), dx, dy, dh)
            ho = a.get("heel_off", (0.0, 0.0))
            plan.step(t0, t1, target, height=a.get("height", 0.07), heel_off=ho[0], heel_pitch_deg=ho[1],
                      side_bulge=a.get("bulge", 0.0), shape=tuple(a.get("shape", (2.0, 1.5))),
                      pitch_keys=tuple(tuple(k) for k in a.get("pitch_keys", ())),
                      delay=a.get("delay", 0.04))
        elif "roll" in a:
            t0, t1 = (float(x) for x in a["roll"])
            plan.roll(t0, t1, a["pitch"], a.get("pivot", "ball"), a.get("toe_follow", True), a.get("toe"))
        elif "spline" in a:
            t0 = float(a["spline"])
            frame = root.ground(t0)
            plan.spline(t0, [(float(k["t"]), _foot_key_state(side, k, frame)) for k in a["keys"]])
        elif "legs" in a:
            t0 = float(a["legs"])
            plan.track(t0, [float(k["t"]) for k in a["keys"]], _leg_track(side, root, a["keys"]))
        else:
            raise ParameterError(f"unknown foot action {sorted(a)} (expected step, roll, spline or legs)")
    return plan


def _hand_tracks(hands: dict, times, root_pos, root_rot, local) -> dict:
    """Wrist targets in the world, pulled within reach, with poles and weights."""
    sk = humanoid()
    f = len(times)
    lr = quat.identity((f, sk.num_joints))
    lr[:, 0] = root_rot
    for j, q in local.items():
        lr[:, sk.index(j)] = q
    _, gp = P.fk(root_pos, lr)
    out = {}
    for side, spec in hands.items():
        keys = spec["keys"]
        kt = [float(k["t"]) for k in keys]
        pos = P.key_track(kt, np.array([k["pos"] for k in keys], dtype=np.float64), times)
        w = np.clip(P.key_track(kt, np.array([k.get("w", 1.0) for k in keys], dtype=np.float64), times), 0, 1)
        target = pos
        shoulder = gp[:, sk.index(f"{side}Arm")]
        v = target - shoulder
        dist = np.linalg.norm(v, axis=-1, keepdims=True)
        reach = 0.985 * (UPPER_ARM + FOREARM)
        target = shoulder + v * np.minimum(1.0, reach / np.maximum(dist, 1e-9))
        pole = np.broadcast_to(np.asarray(spec.get("pole", [-0.3, 0.0, -1.0]), dtype=np.float64), (f, 3))
        out[side] = (target, pole, w)
    return out


def _lowest(motion) -> np.ndarray:
    """``(F,)`` height of the lowest joint or end site."""
    sk = motion.skeleton
    gr, gp = P.fk(motion.root_pos, motion.local_rot)
    ep = gp[:, sk.end_parents] + quat.mul_vec(gr[:, sk.end_parents], sk.end_offsets)
    return np.minimum(gp[..., 2].min(axis=1), ep[..., 2].min(axis=1))


def _start(value):
    return value if isinstance(value, dict) else tuple(value)


def build(name: str, spec: dict | None = None) -> P.Assembled:
    """Generate the keyframed clip ``name`` (from ``keyframes.json`` unless ``spec`` is given)."""
    data = keyframe_data()
    spec = clip_spec(name) if spec is None else spec
    times = P.frame_times(float(spec["duration"]))
    root = _Root(spec["root"])
    root_pos, root_rot = root.sample(times)
    kt, keyed = _resolve_pose_keys(spec.get("pose", [{"t": 0.0}]), data["poses"])
    local = {j: (P.quat_spline(kt, q, times) if len(kt) > 1 else np.repeat(q[:1], len(times), 0))
             for j, q in keyed.items()}
    feet = {side: _foot_plan(side, spec.get("feet", {}).get(side, []), root,
                             _start(spec.get("start", {}).get(side, (0.0, 0.0, 0.0))))
            for side in P.SIDES}
    hands = _hand_tracks(spec["hands"], times, root_pos, root_rot, local) if spec.get("hands") else {}
    tracks = P.BodyTracks(times, root_pos, root_rot, local, feet, hands)
    out = P.assemble(tracks, name)
    if spec.get("floor_guard", False):
        # Safety net for lying poses: lift the pelvis where a body part would dip under the floor.
        low = _lowest(out.motion)
        lift = np.maximum(FLOOR_MARGIN - low, 0.0)
        if lift.max() > 0:
            k = max(1, round(0.1 * P.FPS))
            kernel = np.hanning(2 * k + 1)
            kernel /= kernel.sum()
            padded = np.pad(lift, 2 * k, mode="edge")
            dilated = np.array([padded[i:i + 2 * k + 1].max() for i in range(len(padded) - 2 * k)])
            smooth = np.convolve(dilated, kernel, mode="valid")  # >= lift everywhere
            tracks.root_pos = root_pos + smooth[:, None] * np.array([0.0, 0.0, 1.0])
            if hands:
                tracks.hands = _hand_tracks(spec["hands"], times, tracks.root_pos, root_rot, local)
            out = P.assemble(tracks, name)
    return out
