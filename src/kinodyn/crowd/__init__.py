"""Crowds of single-rigid-body characters posed from multidimensional keyframe sets.

Mitake et al., "Physics-driven multi dimensional keyframe animation for artist-directable interactive
character" (Eurographics 2009): each background character is one rigid body in MuJoCo, balanced by an
inverted-pendulum controller with a fall / brake / lie / stand-up state machine (section 4); its pose
is interpolated from keyframes placed in a keyframe space of tilt, travelled distance and behaviour
(section 5). Modules:

* :mod:`~kinodyn.crowd.body`: the rigid body and the rigid body space R (4.1).
* :mod:`~kinodyn.crowd.controller`: the inverted-pendulum controller and the state machine (4.2).
* :mod:`~kinodyn.crowd.keyframes`: the keyframe space Q, the periodic mapping and keyframe-set files
  (5.1 to 5.3); :mod:`~kinodyn.crowd.interpolate`: their batched interpolation (one compiled kernel).
* :mod:`~kinodyn.crowd.authoring`: how the built-in set of figure 8 (``keyframes.json``) is authored.
* :mod:`~kinodyn.crowd.behaviours`: the character AI (idle, go to, wander, follow, flee).
* :mod:`~kinodyn.crowd.crowd`: many characters stepped and posed together, pushes, balls, props.
* :mod:`~kinodyn.crowd.impacts`: the 54-reaction experiment of section 6 and the automatic observer;
  :mod:`~kinodyn.crowd.figures`: stick-figure contact sheets.
* interface: ``command`` (``kinodyn crowd run|impacts``), ``bench`` (``kinodyn bench crowd``),
  ``demo`` (the demo part), ``register`` (what the package adds).

Uses the foundation (skeleton, motion, math.quat, data) and MuJoCo directly.
"""
