"""The T-pose frame that some BVH converters put before the capture.

The cgspeed conversion of the CMU database (the "MotionBuilder-friendly" BVH files) starts every take
with one added frame: the actor's skeleton in a T-pose, arms stretched sideways and legs straight,
standing at the first captured frame's root position. It is not motion capture; played as a clip it
shows a T-pose (sunk into the floor when the take starts lying down) and then a pop to frame 1.

The test is geometric, so it needs no joint names and works in any unit or facing: frame 0 is a
T-pose when its joints lie close to one vertical plane (thickness across the plane at most
:data:`TPOSE_MAX_THICKNESS` of the body's height) and spread along that plane about as wide as the body
is tall (:data:`TPOSE_MIN_SPAN` to :data:`TPOSE_MAX_SPAN` of the height, the arm span), with the widest
joints above the root (arms, not legs). It counts as *added* only when frame 1 is not a T-pose and the
pose jumps from frame 0 to frame 1 (root-relative joint positions) by more than
:data:`TPOSE_MIN_JUMP` of the height and more than :data:`TPOSE_JUMP_RATIO` times the typical
frame-to-frame change after it. A take that really starts in a held T-pose is therefore kept whole.

Measured on the shared CMU files: an added T-pose has span 0.98-1.05 and thickness 0.13-0.17 of the
height and jumps 0.63-1.43 m to frame 1; captured frames (cgspeed 3dsMax-friendly, SNU-retargeted,
the built-in clips) have span at most 0.71 or a jump below 0.14 m.
"""

from __future__ import annotations

import sys

import numpy as np

from kinodyn._arrays import median
from kinodyn.motion import Motion

__all__ = [
    "ADDED_TPOSE_NOTE",
    "TPOSE_JUMP_RATIO",
    "TPOSE_MAX_SPAN",
    "TPOSE_MAX_THICKNESS",
    "TPOSE_MIN_JUMP",
    "TPOSE_MIN_SPAN",
    "drop_added_tpose",
    "has_added_tpose",
    "skip_added_tpose",
]

#: lateral span of a T-pose over its height (the arm span is about the body height)
TPOSE_MIN_SPAN = 0.85
TPOSE_MAX_SPAN = 1.3
#: thickness across the body's plane over its height
TPOSE_MAX_THICKNESS = 0.3
#: the jump from frame 0 to frame 1 (largest root-relative joint displacement) over the height
TPOSE_MIN_JUMP = 0.1
#: ... and over the median frame-to-frame change of the next frames
TPOSE_JUMP_RATIO = 5.0
#: what ``kinodyn info`` says about such a file
ADDED_TPOSE_NOTE = ("frame 0 is a T-pose added by the file's converter, not motion capture (view and render "
                    "skip it; convert --drop-tpose removes it)")
_NEXT_FRAMES = 30  # frames after frame 1 whose changes give the typical frame-to-frame change


def _is_tpose(pos: np.ndarray) -> bool:
    """Whether one pose ``pos (J, 3)`` (world joint positions, Z up) is a T-pose (see the module)."""
    height = float(np.ptp(pos[:, 2]))
    if height <= 0.0:
        return False
    xy = pos[:, :2] - pos[:, :2].mean(axis=0)
    _, _, axes = np.linalg.svd(xy, full_matrices=False)
    lateral, across = xy @ axes[0], xy @ axes[1]
    span, thickness = float(np.ptp(lateral)) / height, float(np.ptp(across)) / height
    widest = pos[[int(np.argmin(lateral)), int(np.argmax(lateral))], 2]
    return (TPOSE_MIN_SPAN <= span <= TPOSE_MAX_SPAN and thickness <= TPOSE_MAX_THICKNESS
            and bool(np.all(widest > pos[0, 2])))


def has_added_tpose(motion: Motion) -> bool:
    """Whether frame 0 of ``motion`` is an added T-pose unlike the frames after it (see the module).

    Only the first frames are looked at (forward kinematics of at most 32 frames), so it is cheap on
    long takes. Motions of fewer than two frames have nothing to compare with and give False.
    """
    if motion.num_frames < 2:
        return False
    pos = motion[: _NEXT_FRAMES + 2].global_positions()
    if not _is_tpose(pos[0]) or _is_tpose(pos[1]):
        return False
    rel = pos - pos[:, :1]
    steps = np.linalg.norm(np.diff(rel, axis=0), axis=-1).max(axis=-1)  # (n-1,) largest joint change
    height = float(np.ptp(pos[0, :, 2]))
    typical = float(median(steps[1:])) if len(steps) > 1 else 0.0
    return bool(steps[0] > TPOSE_MIN_JUMP * height and steps[0] > TPOSE_JUMP_RATIO * typical)


def drop_added_tpose(motion: Motion) -> tuple[Motion, bool]:
    """``(motion without its added T-pose frame, True)``, or ``(motion, False)`` when it has none."""
    if has_added_tpose(motion):
        return motion[1:], True
    return motion, False


def skip_added_tpose(motion: Motion, label, out=None) -> Motion:
    """:func:`drop_added_tpose` for the commands that show motions: prints one note naming ``label``
    (on ``out``, default stderr) when the frame is skipped."""
    m, dropped = drop_added_tpose(motion)
    if dropped:
        print(f"kinodyn: note: {label}: skipped frame 0, a T-pose added by the converter "
              "(--keep-tpose shows it)", file=out if out is not None else sys.stderr)
    return m
