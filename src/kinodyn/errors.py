"""Exceptions raised by kinodyn.

Every error kinodyn raises on purpose derives from :class:`KinodynError`, so a caller can catch them all
with one clause. Each kind of problem has its own subclass, and each also derives from the matching
built-in (``ValueError`` for bad data, ``RuntimeError`` for simulations) so generic code keeps working.
Messages name the argument or file, what was expected and what was found.
"""

from __future__ import annotations

from os import PathLike

__all__ = [
    "KinodynError",
    "ParameterError",
    "SkeletonError",
    "MotionError",
    "FileFormatError",
    "BVHParseError",
    "AMCParseError",
    "SimulationError",
    "SimulationDivergedError",
    "UnknownNameError",
]


class KinodynError(Exception):
    """Base class of every error kinodyn raises on purpose."""


class ParameterError(KinodynError, ValueError):
    """An argument or configuration value is outside what the function accepts."""


class UnknownNameError(KinodynError, KeyError):
    """A name (joint, clip, benchmark, method) is not known; the message lists the valid ones."""

    def __str__(self) -> str:  # KeyError quotes its argument; keep the message readable.
        return str(self.args[0]) if self.args else ""


class SkeletonError(KinodynError, ValueError):
    """A skeleton is malformed (parents out of order, bad offsets, mismatched names)."""


class MotionError(KinodynError, ValueError):
    """Motion arrays have the wrong shape, non-finite values, or do not fit their skeleton."""


class FileFormatError(KinodynError, ValueError):
    """A file could not be read: the message names the file and, where known, the line."""

    def __init__(self, message: str, path: str | PathLike | None = None, line: int | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        where = ""
        if self.path is not None:
            where = self.path if line is None else f"{self.path}:{line}"
        super().__init__(f"{where}: {message}" if where else message)
        self.reason = message


class BVHParseError(FileFormatError):
    """A BVH file is malformed."""


class AMCParseError(FileFormatError):
    """An ASF skeleton or AMC motion file is malformed."""


class SimulationError(KinodynError, RuntimeError):
    """A physics simulation could not be set up or run."""


class SimulationDivergedError(SimulationError):
    """The simulation state became non-finite or exploded; nothing was written out."""

    def __init__(self, message: str, step: int | None = None, body: str | None = None):
        self.step = step
        self.body = body
        super().__init__(message)
