"""Settings of a simulated world (:class:`WorldConfig`): frame rate, substeps, gravity, ground, contacts.

Units: seconds, metres, m/s^2; the timestep is ``1 / (fps * substeps)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinodyn.errors import ParameterError

__all__ = ["MAX_SPEED", "WorldConfig"]

#: A state with a joint or body speed above this (rad/s or m/s) counts as exploded.
MAX_SPEED = 500.0


@dataclass(frozen=True)
class WorldConfig:
    """Settings of a world.

    Attributes:
        fps: output frames per second (the rate of :meth:`World.step`, of recording and of divergence
            checks).
        substeps: physics steps per frame (dt = 1 / (fps * substeps)).
        gravity: m/s^2 along -Z (0 for none).
        ground: add a ground plane at z = 0.
        friction: ground friction.
        contact_timeconst: contact stiffness as a time constant (s); 0 uses twice the timestep (MuJoCo's
            stiffest stable setting, which keeps a fast ball from sinking into a chest).
        impact_gap: contacts of one pair closer in time than this (s) form one impact.
        max_speed: speed (m/s, rad/s) above which the state counts as exploded.
    """

    fps: float = 60.0
    substeps: int = 4
    gravity: float = 9.81
    ground: bool = True
    friction: float = 1.0
    contact_timeconst: float = 0.0
    impact_gap: float = 0.05
    max_speed: float = MAX_SPEED

    def __post_init__(self):
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ParameterError(f"fps must be a positive number, got {self.fps!r}")
        if not (isinstance(self.substeps, (int, np.integer)) and self.substeps >= 1):
            raise ParameterError(f"substeps must be a positive integer, got {self.substeps!r}")
        if not np.isfinite(self.gravity):
            raise ParameterError(f"gravity must be a finite number, got {self.gravity!r}")
        if not (np.isfinite(self.friction) and self.friction >= 0):
            raise ParameterError(f"friction must be non-negative, got {self.friction!r}")
        if not (np.isfinite(self.contact_timeconst) and self.contact_timeconst >= 0):
            raise ParameterError(f"contact_timeconst must be non-negative, got {self.contact_timeconst!r}")
        if not (np.isfinite(self.max_speed) and self.max_speed > 0):
            raise ParameterError(f"max_speed must be positive, got {self.max_speed!r}")

    @property
    def timestep(self) -> float:
        return 1.0 / (self.fps * self.substeps)
