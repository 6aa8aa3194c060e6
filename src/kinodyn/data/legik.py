"""Analytic two-bone inverse kinematics for the built-in clips (hip-knee-ankle, shoulder-elbow-wrist).

The solver lives in :mod:`kinodyn.ik` (one IK module for the clips, the foot lock and contact); this
module keeps the names the procedural clips use.
"""

from __future__ import annotations

from kinodyn.ik import TwoBoneSolution, bend_direction, knee_angle, two_bone_fk, two_bone_ik

__all__ = ["TwoBoneSolution", "bend_direction", "knee_angle", "two_bone_fk", "two_bone_ik"]
