"""Crowds of single-rigid-body characters posed from multidimensional keyframe sets.

Mitake et al., "Physics-driven multi dimensional keyframe animation for artist-directable interactive
character" (Eurographics 2009): each background character is one rigid body in MuJoCo, balanced by an
inverted-pendulum controller with a fall / brake / lie / stand-up state machine (section 4); its pose
is interpolated from keyframes placed in a keyframe space of tilt, travelled distance and behaviour
(section 5). Modules:

* :mod:`~kinodyn.crowd.body`: the rigid body and the rigid body space R (4.1).
* :mod:`~kinodyn.crowd.controller`: the inverted-pendulum controller and the state machine (4.2).
* :mod:`~kinodyn.crowd.keyframes`: the keyframe space Q, the periodic mapping, keyframe-set files and
  their interpolation (5.1 to 5.3).
* :mod:`~kinodyn.crowd.crowd`: many characters stepped and posed together, pushes, balls, props.

Uses the foundation (skeleton, motion, math.quat, data) and MuJoCo directly.
"""
