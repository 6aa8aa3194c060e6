"""Procedural cyclic clips: idle, a fighting stance, walk and run.

A gait is a periodic pattern of footsteps (left foot down at phase 0, right at phase 0.5) with the
pelvis moving at constant forward speed, bobbing, swaying, rolling and turning with the legs, the
chest counter-rotating, the arms swinging opposite to the legs and the head kept level. Every track
is a periodic function of time and every footstep a translate of the previous one by the stride, so a
clip of whole cycles loops exactly: its last frame is its first moved forward by the stride.

The legs are solved by IK on the planned feet (:func:`kinodyn.data.procedural.assemble`). Phase
conventions and the duty factor follow the gait-cycle description of Perry and Burnfield, *Gait
Analysis* (2010): a walk keeps each foot on the ground about 60 % of the cycle (double support), a run
less than 50 % (flight phases).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinodyn.data import procedural as P
from kinodyn.data.skeleton import SOLE
from kinodyn.math import quat

__all__ = ["RUN", "WALK", "GaitParams", "fighting_stance", "gait", "idle"]

_TAU = 2.0 * np.pi


@dataclass(frozen=True)
class GaitParams:
    """Parameters of a cyclic gait (lengths m, times s, angles deg).

    Attributes:
        speed: forward speed of the pelvis (m/s).
        period: duration of one cycle = two steps (s); a multiple of 1/60.
        duty: fraction of the cycle each foot is on the ground.
        reach: forward offset of the ball from the pelvis at mid-stance.
        width: lateral offset of each ball from the pelvis line.
        toe_out: outward turn of each foot.
        heel_off: seconds before lift-off during which the heel rises; heel_pitch: its angle at lift.
        swing_height: peak lift of the ball above the floor during a swing.
        swing_delay: fraction of the swing spent lifting/landing before/after travelling.
        swing_shape: exponents of the swing height profile (see :meth:`FootPlan.step`).
        swing_pitch: extra foot pitch keys along the swing (knee flexion lifts the heel).
        height, bob: mean pelvis height and its vertical amplitude (lowest at ``bob_phase``).
        sway: lateral pelvis amplitude (toward the stance foot).
        lean: forward tilt of the pelvis; spine_lean: extra forward bend of the chest.
        pelvis_yaw, pelvis_roll, chest_yaw: rotation amplitudes.
        arm_swing, arm_offset: shoulder swing amplitude and mean (negative = forward).
        elbow, elbow_swing: mean elbow flexion and its increase when the arm is forward.
        cycles: number of cycles in the clip.
    """

    speed: float
    period: float
    duty: float
    reach: float
    width: float
    toe_out: float
    heel_off: float
    heel_pitch: float
    swing_height: float
    swing_delay: float
    swing_shape: tuple[float, float]
    swing_pitch: tuple[tuple[float, float], ...]
    height: float
    bob: float
    bob_phase: float
    sway: float
    lean: float
    spine_lean: float
    pelvis_yaw: float
    pelvis_roll: float
    chest_yaw: float
    arm_swing: float
    arm_offset: float
    arm_abduction: float
    elbow: float
    elbow_swing: float
    cycles: int = 2


WALK = GaitParams(speed=1.4, period=1.0, duty=0.6, reach=-0.02, width=0.085, toe_out=6.0, heel_off=0.24,
                  heel_pitch=48.0, swing_height=0.05, swing_delay=0.04, swing_shape=(1.6, 1.6),
                  swing_pitch=((0.25, 15.0), (0.6, 0.0), (0.85, -8.0)), height=0.935, bob=0.018,
                  bob_phase=0.05, sway=0.02, lean=3.0, spine_lean=2.0, pelvis_yaw=5.0, pelvis_roll=4.0,
                  chest_yaw=4.0, arm_swing=17.0, arm_offset=-3.0, arm_abduction=7.0, elbow=16.0,
                  elbow_swing=14.0)

RUN = GaitParams(speed=3.2, period=0.7, duty=0.34, reach=-0.02, width=0.06, toe_out=4.0, heel_off=0.1,
                 heel_pitch=45.0, swing_height=0.25, swing_delay=0.04, swing_shape=(1.3, 1.6),
                 swing_pitch=((0.3, 35.0), (0.65, 10.0)), height=0.9, bob=0.035,
                 bob_phase=0.17, sway=0.012, lean=9.0, spine_lean=3.0, pelvis_yaw=8.0, pelvis_roll=5.0,
                 chest_yaw=8.0, arm_swing=32.0, arm_offset=-12.0, arm_abduction=10.0, elbow=82.0,
                 elbow_swing=18.0)


def _flat(x: float, y: float, heading_deg: float) -> P.FootState:
    return P.FootState(np.array([x, y, SOLE]), P.yaw(np.deg2rad(heading_deg)))


def gait(p: GaitParams, name: str = "") -> P.Assembled:
    """A clip of ``p.cycles`` cycles of the gait ``p`` starting at left-foot strike, heading +X."""
    T = p.period
    times = P.frame_times(p.cycles * T)
    phase = times / T
    stance_travel = p.speed * p.duty * T
    feet = {}
    for side, sign, t_off in (("Left", 1.0, 0.0), ("Right", -1.0, 0.5 * T)):
        def ball_x(k, t_off=t_off):
            return p.speed * (k * T + t_off) + p.reach + 0.5 * stance_travel

        ks = range(-2, p.cycles + 2)
        plan = P.FootPlan(_flat(ball_x(ks[0]), sign * p.width, sign * p.toe_out))
        for k in ks:
            t_lift = k * T + t_off + p.duty * T
            t_land = (k + 1) * T + t_off
            plan.step(t_lift, t_land, _flat(ball_x(k + 1), sign * p.width, sign * p.toe_out),
                      height=p.swing_height, heel_off=p.heel_off, heel_pitch_deg=p.heel_pitch,
                      delay=p.swing_delay, shape=p.swing_shape, pitch_keys=p.swing_pitch)
        feet[side] = plan

    c1 = np.cos(_TAU * phase)
    # Pelvis: forward at constant speed, bobbing twice a cycle, swaying toward the stance foot.
    mid_stance = 0.5 * p.duty
    root = np.stack([p.speed * times,
                     p.sway * np.cos(_TAU * (phase - mid_stance)),
                     p.height - p.bob * np.cos(2.0 * _TAU * (phase - p.bob_phase))], axis=-1)
    pel_yaw = -p.pelvis_yaw * c1  # left leg forward at phase 0 -> left hip forward -> negative yaw
    pel_roll = p.pelvis_roll * np.cos(_TAU * (phase - mid_stance))  # stance side up
    zeros = np.zeros_like(times)
    root_rot = P.euler(np.stack([pel_roll, np.full_like(times, p.lean), pel_yaw], axis=-1))

    # Chest counter-rotates, the spine takes out most of the pelvis roll, the head looks ahead.
    twist = p.chest_yaw * c1 - pel_yaw  # chest yaw relative to the pelvis
    local = {
        "Spine": P.euler(np.stack([-0.6 * pel_roll, np.full_like(times, 0.5 * p.spine_lean), 0.5 * twist], -1)),
        "Spine1": P.euler(np.stack([-0.3 * pel_roll, np.full_like(times, 0.5 * p.spine_lean), 0.5 * twist], -1)),
    }
    chest_yaw = p.chest_yaw * c1
    level = -(p.lean + p.spine_lean)
    local["Neck"] = P.euler(np.stack([-0.05 * pel_roll, np.full_like(times, 0.5 * level), -0.5 * chest_yaw], -1))
    local["Head"] = P.euler(np.stack([-0.05 * pel_roll, np.full_like(times, 0.5 * level), -0.5 * chest_yaw], -1))
    for side, sign, shift in (("Left", 1.0, 0.0), ("Right", -1.0, np.pi)):
        swing = np.cos(_TAU * phase + shift)  # +1: arm back (its leg forward), -1: arm forward
        local[f"{side}Arm"] = P.euler(np.stack([np.full_like(times, sign * p.arm_abduction),
                                                p.arm_offset + p.arm_swing * swing, zeros], -1))
        flex = p.elbow + p.elbow_swing * 0.5 * (1.0 - swing)
        local[f"{side}ForeArm"] = P.euler(np.stack([zeros, -flex, zeros], -1))
        local[f"{side}Hand"] = P.euler(np.stack([zeros, np.full_like(times, -8.0), zeros], -1))
    return P.assemble(P.BodyTracks(times, root, root_rot, local, feet), name)


def idle(name: str = "idle", duration: float = 4.0) -> P.Assembled:
    """Standing in place: slow breathing, a small weight shift and relaxed arms; loops every
    ``duration`` seconds."""
    times = P.frame_times(duration)
    ph = _TAU * times / duration
    feet = {s: P.FootPlan(P.stance_state(s)) for s in P.SIDES}
    base_h = P.standing_root_height() - 0.01
    root = np.stack([0.008 * np.sin(ph), 0.025 * np.sin(ph), base_h - 0.006 * (1.0 - np.cos(2.0 * ph))], -1)
    breath = np.sin(2.0 * ph)  # two breaths per loop
    root_rot = P.euler(np.stack([1.5 * np.sin(ph), np.full_like(times, 2.0), 1.5 * np.sin(ph + 0.6)], -1))
    z = np.zeros_like(times)
    local = {
        "Spine": P.euler(np.stack([-1.2 * np.sin(ph), 1.0 + 0.6 * breath, -0.8 * np.sin(ph + 0.6)], -1)),
        "Spine1": P.euler(np.stack([-0.5 * np.sin(ph), -1.0 - 0.8 * breath, -0.6 * np.sin(ph + 0.6)], -1)),
        "Neck": P.euler(np.stack([z, 2.0 + 0.3 * breath, 3.0 * np.sin(ph + 1.0)], -1)),
        "Head": P.euler(np.stack([0.8 * np.sin(ph), -2.0 + 0.5 * np.sin(ph + 2.0), 4.0 * np.sin(ph + 1.3)], -1)),
    }
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        local[f"{side}Shoulder"] = P.euler(np.stack([-sign * 1.5 * breath, z, z], -1))
        local[f"{side}Arm"] = P.euler(np.stack([sign * (5.0 + 1.0 * breath), -2.0 + 1.5 * np.sin(ph + sign),
                                                -sign * 12.0 + z], -1))
        local[f"{side}ForeArm"] = P.euler(np.stack([z, -14.0 - 2.0 * np.sin(ph + sign), z], -1))
        local[f"{side}Hand"] = P.euler(np.stack([-sign * 2.0 + z, -6.0 + z, z], -1))
    return P.assemble(P.BodyTracks(times, root, root_rot, local, feet), name)


def fighting_stance(name: str = "fighting_stance", duration: float = 2.0) -> P.Assembled:
    """A boxer's guard in place: left foot forward, right foot back and turned out, knees bent, the
    fists up at the chin; a light bounce on the balls of the feet (two per second) and a slow sway of
    the guard; loops every ``duration`` seconds. Its facing (+X, the pelvis turned 25 degrees toward the
    rear foot) is the direction the fighter faces."""
    times = P.frame_times(duration)
    ph = _TAU * times / duration
    bounce = np.sin(4.0 * ph)  # four small dips per loop: two per second
    feet = {"Left": P.FootPlan(P.stance_state("Left", dx=0.17, dy=0.02, dheading_deg=-14.0)),
            "Right": P.FootPlan(P.stance_state("Right", dx=-0.17, dy=-0.03, dheading_deg=-30.0))}
    base_h = P.standing_root_height() - 0.05
    root = np.stack([0.012 * np.sin(ph), 0.015 * np.sin(ph + 0.8), base_h - 0.008 * (1.0 + bounce)], -1)
    root_rot = P.euler(np.stack([1.0 * np.sin(ph), np.full_like(times, 6.0) + 0.6 * bounce,
                                 -25.0 + 3.0 * np.sin(ph + 0.4)], -1))
    z = np.zeros_like(times)
    sway = np.sin(ph + 1.2)
    local = {
        "Spine": P.euler(np.stack([-1.0 * sway, 4.0 + 0.5 * bounce, 8.0 + 1.5 * sway], -1)),
        "Spine1": P.euler(np.stack([-0.5 * sway, 3.0 + 0.3 * bounce, 6.0 + 1.0 * sway], -1)),
        "Neck": P.euler(np.stack([z, -4.0 - 0.4 * bounce, 6.0 - 1.5 * sway], -1)),
        "Head": P.euler(np.stack([0.5 * sway, -6.0 + z, 4.0 - 1.0 * sway], -1)),
    }
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        lead = 1.0 if side == "Left" else 0.0  # the lead hand sits a little higher and forward
        local[f"{side}Shoulder"] = P.euler(np.stack([z, z, sign * 6.0 + z], -1))
        local[f"{side}Arm"] = P.euler(np.stack([sign * (14.0 + 1.5 * bounce), -34.0 - 6.0 * lead + 2.0 * sway,
                                                -sign * 20.0 + z], -1))
        local[f"{side}ForeArm"] = P.euler(np.stack([z, -118.0 + 8.0 * lead + 2.0 * np.sin(ph + sign), z], -1))
        local[f"{side}Hand"] = P.euler(np.stack([z, -10.0 + z, z], -1))
    return P.assemble(P.BodyTracks(times, root, root_rot, local, feet), name)


def _hermite(key_times, values, slopes, times) -> np.ndarray:
    """Piecewise cubic Hermite curve through ``values`` with the given ``slopes`` (units per second)."""
    kt = np.asarray(key_times, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    m = np.asarray(slopes, dtype=np.float64)
    t = np.clip(times, kt[0], kt[-1])
    i = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(kt) - 2)
    h = kt[i + 1] - kt[i]
    s = (t - kt[i]) / h
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * v[i] + (s3 - 2 * s2 + s) * h * m[i] + (-2 * s3 + 3 * s2) * v[i + 1]
            + (s3 - s2) * h * m[i + 1])


_GRAVITY = 9.81

# Upper-body keys of the jump: time -> joint -> Euler degrees (rx, ry, rz); right side mirrored.
_JUMP_POSE = (
    (0.0, {"Spine": (0, 1, 0), "Spine1": (0, -1, 0), "Neck": (0, 2, 0), "Head": (0, -2, 0),
           "LeftArm": (5, -2, -12), "LeftForeArm": (0, -14, 0), "LeftHand": (-2, -6, 0)}),
    (0.25, {"Spine": (0, 5, 0), "Spine1": (0, 4, 0), "Neck": (0, -6, 0), "Head": (0, -4, 0),
            "LeftArm": (8, -20, 5), "LeftForeArm": (0, -25, 0), "LeftHand": (4, -6, 0)}),
    (0.47, {"Spine": (0, 12, 0), "Spine1": (0, 10, 0), "Neck": (0, -16, 0), "Head": (0, -12, 0),
            "LeftArm": (10, 22, 0), "LeftForeArm": (0, -15, 0), "LeftHand": (0, 10, 0)}),
    (0.68, {"Spine": (0, -4, 0), "Spine1": (0, -4, 0), "Neck": (0, 2, 0), "Head": (0, 2, 0),
            "LeftArm": (14, -70, 0), "LeftForeArm": (0, -20, 0), "LeftHand": (0, -5, 0)}),
    (0.9, {"Spine": (0, -2, 0), "Spine1": (0, -2, 0), "Neck": (0, 0, 0), "Head": (0, 0, 0),
           "LeftArm": (18, -120, 0), "LeftForeArm": (0, -25, 0), "LeftHand": (0, -5, 0)}),
    (1.1, {"Spine": (0, 4, 0), "Spine1": (0, 3, 0), "Neck": (0, -4, 0), "Head": (0, -3, 0),
           "LeftArm": (16, -70, 0), "LeftForeArm": (0, -30, 0), "LeftHand": (0, -5, 0)}),
    (1.32, {"Spine": (0, 12, 0), "Spine1": (0, 8, 0), "Neck": (0, -14, 0), "Head": (0, -10, 0),
            "LeftArm": (14, -35, 0), "LeftForeArm": (0, -35, 0), "LeftHand": (2, -5, 0)}),
    (2.1, {"Spine": (0, 1, 0), "Spine1": (0, -1, 0), "Neck": (0, 2, 0), "Head": (0, -2, 0),
           "LeftArm": (5, -2, -12), "LeftForeArm": (0, -14, 0), "LeftHand": (-2, -6, 0)}),
)


def _mirror_euler(e):
    return (-e[0], e[1], -e[2])


def jump(name: str = "jump") -> P.Assembled:
    """A standing vertical jump: the pelvis follows a true ballistic parabola between take-off and
    landing (g = 9.81 m/s^2), the feet roll onto the balls to push off and land ball first."""
    t_down, t_off, t_land, t_absorb, t_end = 0.47, 0.68, 1.10, 1.32, 2.1
    z_stand, z_crouch, z_off, z_land, z_absorb = 0.99, 0.80, 1.05, 1.03, 0.81
    flight = t_land - t_off
    v_off = (z_land - z_off) / flight + 0.5 * _GRAVITY * flight
    v_land = v_off - _GRAVITY * flight
    times = P.frame_times(t_end)
    tau = times - t_off
    z = np.where(times < t_off,
                 _hermite([0.0, t_down, t_off], [z_stand, z_crouch, z_off], [0.0, 0.0, v_off], times),
                 np.where(times <= t_land, z_off + v_off * tau - 0.5 * _GRAVITY * tau * tau,
                          _hermite([t_land, t_absorb, t_end], [z_land, z_absorb, z_stand], [v_land, 0.0, 0.0],
                                   times)))
    x = P.key_track([0.0, t_down, t_off, t_land, t_absorb, t_end], [0.0, -0.07, 0.0, 0.01, -0.05, 0.0], times)
    root = np.stack([x, np.zeros_like(x), z], axis=-1)
    pitch = P.key_track([0.0, t_down, t_off, 0.9, t_land, t_absorb, t_end], [2.0, 28.0, 4.0, 0.0, 6.0, 24.0, 2.0],
                        times)
    root_rot = P.euler(np.stack([np.zeros_like(x), pitch, np.zeros_like(x)], axis=-1))

    kt = [k[0] for k in _JUMP_POSE]
    local = {}
    for joint in _JUMP_POSE[0][1]:
        eul = np.array([k[1][joint] for k in _JUMP_POSE], dtype=np.float64)
        local[joint] = P.quat_spline(kt, P.euler(eul), times)
        if joint.startswith("Left"):
            mir = np.array([_mirror_euler(e) for e in eul])
            local[joint.replace("Left", "Right")] = P.quat_spline(kt, P.euler(mir), times)

    feet = {}
    push_pitch, land_pitch = 45.0, 25.0
    tuck = 0.04
    for side in P.SIDES:
        stand = P.stance_state(side)
        plan = P.FootPlan(stand)
        plan.roll(t_down + 0.05, t_off, push_pitch, "ball")
        landing = P.FootState(stand.ball, quat.mul(stand.rot, quat.from_axis_angle([0.0, 1.0, 0.0],
                                                                                   np.deg2rad(land_pitch))),
                              -np.deg2rad(land_pitch))
        plan.step(t_off, t_land, landing, height=_GRAVITY * flight ** 2 / 8.0 + tuck, delay=0.0, shape=(1.0, 1.0))
        plan.roll(t_land, t_land + 0.12, -land_pitch, "ball")
        feet[side] = plan
    return P.assemble(P.BodyTracks(times, root, root_rot, local, feet), name)
