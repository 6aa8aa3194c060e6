"""Inverse kinematics, one home for every solver kinodyn has.

- :mod:`kinodyn.ik.twobone`: analytic two-bone chains (the built-in clips' limbs, the foot lock).
- :mod:`kinodyn.ik.ccd`: cyclic coordinate descent on chains of any length, with hinge limits and reach
  cones (contact's overlap avoidance; scene generation reuses it).
- :mod:`kinodyn.ik.cones`: the compiled joint-limit projections (hinge ranges, reach cones, twist)
  the CCD solver applies after every turn.

The two-bone names are re-exported here (``from kinodyn.ik import two_bone_ik``); the CCD solver is
used as ``from kinodyn.ik import ccd``.
"""

from kinodyn.ik.twobone import (TwoBoneSolution, bend_direction, knee_angle, two_bone_delta,
                                two_bone_delta_kernel, two_bone_fk, two_bone_ik)

__all__ = ["TwoBoneSolution", "bend_direction", "knee_angle", "two_bone_delta", "two_bone_delta_kernel",
           "two_bone_fk", "two_bone_ik"]
