"""Physics characters on MuJoCo: a body for any skeleton, PD tracking, kinematic/dynamic switching, impacts.

The simulated character of the dynamic-response capability (Zordan et al.; the fast dynamic-response
paper, sections 3, 6 and 7), shared by avatar contact and the fight scenes:

* :mod:`~kinodyn.physics.body`: a MuJoCo body (through :class:`mujoco.MjSpec`) for any
  :class:`~kinodyn.skeleton.Skeleton`, with the explicit index map between skeleton joints and MuJoCo
  ``qpos``/``qvel``/controls.
* :mod:`~kinodyn.physics.tracking`: inertia-scaled PD servos running inside MuJoCo, gains changeable at
  run time.
* :mod:`~kinodyn.physics.world`: the one mutable simulator: characters played kinematically or simulated,
  switching at any frame, trajectories read back as Motions, divergence detection.
* :mod:`~kinodyn.physics.impacts`: projectiles, pushes and the impact log.
* :mod:`~kinodyn.physics.state`: per-body state, centre of mass and foot contacts as feature arrays.
* :mod:`~kinodyn.physics.rollout`: batched rollouts on all cores for training data
  (``kinodyn.physics.rollout.rollout``).
* :mod:`~kinodyn.physics.render`: offscreen OpenGL drawing with MuJoCo's renderer, which
  :mod:`kinodyn.viz.render` uses to film a scene.

The world's stages: :mod:`~kinodyn.physics.assembly` (model assembly), :mod:`~kinodyn.physics.playback`
(clips and servo targets), :mod:`~kinodyn.physics.impacts`, :mod:`~kinodyn.physics.recording`
(recording and divergence checks), over the handles of :mod:`~kinodyn.physics.handles`; the body's parts:
:mod:`~kinodyn.physics.layout` (segments), :mod:`~kinodyn.physics.geoms` (collision shapes) and
:mod:`~kinodyn.physics.conversions` (poses to ``qpos`` and servo targets).

Only this package imports ``mujoco`` (besides the physics benchmark's Python servo baseline, which
calls the engine step by step to measure what the in-engine servos save).
"""

from kinodyn.physics.body import (
                                  SEGMENT_RADII,
                                  BodyConfig,
                                  BodyMap,
                                  CharacterBody,
                                  Segment,
                                  build_body,
                                  motion_to_qpos,
                                  pose_to_ctrl,
                                  qpos_to_local_rot,
)
from kinodyn.physics.impacts import Impact, launch
from kinodyn.physics.recording import no_log_file
from kinodyn.physics.rollout import RolloutResult, clip_controls, impact_batch
from kinodyn.physics.state import CharacterState, character_state, states_from_qpos
from kinodyn.physics.tracking import DEFAULT_GAINS, PDConfig
from kinodyn.physics.world import Character, Projectile, World, WorldConfig, step_parallel

no_log_file()  # diverging simulations raise SimulationDivergedError, not a MUJOCO_LOG.TXT where the user is

__all__ = [
                                  "DEFAULT_GAINS",
                                  "SEGMENT_RADII",
                                  "BodyConfig",
                                  "BodyMap",
                                  "Character",
                                  "CharacterBody",
                                  "CharacterState",
                                  "Impact",
                                  "PDConfig",
                                  "Projectile",
                                  "RolloutResult",
                                  "Segment",
                                  "World",
                                  "WorldConfig",
                                  "build_body",
                                  "character_state",
                                  "clip_controls",
                                  "impact_batch",
                                  "launch",
                                  "motion_to_qpos",
                                  "pose_to_ctrl",
                                  "qpos_to_local_rot",
                                  "states_from_qpos",
                                  "step_parallel",
]
