"""The motion: a skeleton animated by root positions and local joint rotations sampled at ``fps``.

``Motion`` is a frozen dataclass of read-only arrays; every edit returns a new motion
(:meth:`Motion.replace`). Shapes: ``root_pos (F, 3)`` metres in the world (Z up), ``local_rot (F, J, 4)``
unit quaternions ``(w, x, y, z)`` relative to the parent joint. ``translations (F, J, 3)`` is optional and
only present when a file animates non-root joint translations; otherwise the skeleton's offsets are used.
The root joint is at ``root_pos`` (the skeleton's root offset is not added, as in BVH files whose root
channels are absolute positions).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from kinodyn._arrays import readonly
from kinodyn.errors import MotionError, ParameterError
from kinodyn.math import interp, quat, xform
from kinodyn.skeleton import Skeleton

__all__ = ["Motion", "MAX_RESAMPLE_JOINT_FRAMES"]

#: the most frames x joints one :meth:`Motion.resample` makes (about 1.6 GB of rotations), so a typo in
#: a frame rate is an error rather than an allocation of many gigabytes
MAX_RESAMPLE_JOINT_FRAMES = 50_000_000


@dataclass(frozen=True, eq=False)
class Motion:
    """A clip: ``skeleton``, ``root_pos (F, 3)``, ``local_rot (F, J, 4)`` at ``fps`` frames per second.

    Attributes:
        skeleton: the :class:`~kinodyn.skeleton.Skeleton` being animated.
        root_pos: ``(F, 3)`` world position of the root joint, metres.
        local_rot: ``(F, J, 4)`` local rotations; the root's is its world rotation.
        fps: frames per second (> 0).
        translations: optional ``(F, J, 3)`` animated local translations replacing the offsets.
        name: a label (file stem, clip name).
    """

    skeleton: Skeleton
    root_pos: np.ndarray
    local_rot: np.ndarray
    fps: float
    translations: np.ndarray | None = None
    name: str = ""

    def __post_init__(self):
        if not isinstance(self.skeleton, Skeleton):
            raise MotionError(f"skeleton must be a Skeleton, got {type(self.skeleton).__name__}")
        j = self.skeleton.num_joints
        rp = np.asarray(self.root_pos, dtype=np.float64)
        lr = np.asarray(self.local_rot, dtype=np.float64)
        if lr.ndim != 3 or lr.shape[1:] != (j, 4):
            raise MotionError(f"local_rot must have shape (F, {j}, 4), got {lr.shape}")
        f = lr.shape[0]
        if rp.shape != (f, 3):
            raise MotionError(f"root_pos must have shape ({f}, 3), got {rp.shape}")
        fps = float(self.fps)
        if not np.isfinite(fps) or fps <= 0:
            raise MotionError(f"fps must be a positive number, got {self.fps!r}")
        if not np.all(np.isfinite(rp)):
            raise MotionError(f"root_pos has non-finite values (first at frame {_first_bad(rp)})")
        if not np.all(np.isfinite(lr)):
            raise MotionError(f"local_rot has non-finite values (first at frame {_first_bad(lr)})")
        norms = np.sqrt(np.einsum("...i,...i->...", lr, lr))
        if f and np.any(np.abs(norms - 1.0) > 1e-6):
            if np.any(norms < 1e-9):
                raise MotionError("local_rot contains zero quaternions")
            lr = lr / norms[..., None]
        object.__setattr__(self, "root_pos", readonly(rp))
        object.__setattr__(self, "local_rot", readonly(lr))
        object.__setattr__(self, "fps", fps)
        if self.translations is not None:
            tr = np.asarray(self.translations, dtype=np.float64)
            if tr.shape != (f, j, 3):
                raise MotionError(f"translations must have shape ({f}, {j}, 3), got {tr.shape}")
            if not np.all(np.isfinite(tr)):
                raise MotionError("translations have non-finite values")
            object.__setattr__(self, "translations", readonly(tr))

    # ------------------------------------------------------------------ basics
    @property
    def num_frames(self) -> int:
        return self.local_rot.shape[0]

    def __len__(self) -> int:
        return self.num_frames

    @property
    def num_joints(self) -> int:
        return self.skeleton.num_joints

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return max(self.num_frames - 1, 0) / self.fps

    @property
    def dt(self) -> float:
        return 1.0 / self.fps

    def times(self) -> np.ndarray:
        """``(F,)`` frame times in seconds from 0."""
        return np.arange(self.num_frames) / self.fps

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return (f"Motion({label}{self.num_frames} frames at {self.fps:g} fps = {self.duration:.2f} s, "
                f"{self.num_joints} joints)")

    def digest(self) -> str:
        """A hash of what the motion plays (skeleton, frames, rate; not its name): two motions with the same
        digest play the same. 40 hex digits."""
        h = hashlib.blake2b(digest_size=20)
        sk = self.skeleton
        h.update(f"{self.fps!r}|{','.join(sk.names)}|".encode())
        for a in (sk.parents, sk.offsets, sk.end_parents, sk.end_offsets, self.root_pos, self.local_rot,
                  np.zeros(0) if self.translations is None else self.translations):
            h.update(np.ascontiguousarray(a).tobytes())
            h.update(b"|")
        return h.hexdigest()

    def replace(self, **changes) -> "Motion":
        """A copy with some fields changed (MJX's ``replace``)."""
        kw = dict(skeleton=self.skeleton, root_pos=self.root_pos, local_rot=self.local_rot, fps=self.fps,
                  translations=self.translations, name=self.name)
        kw.update(changes)
        return Motion(**kw)

    def local_positions(self) -> np.ndarray:
        """``(F, J, 3)`` local translations with the root's world position in slot 0."""
        if self.translations is not None:
            lp = np.array(self.translations)
        else:
            lp = np.broadcast_to(self.skeleton.offsets, (self.num_frames, self.num_joints, 3)).copy()
        lp[:, 0] = self.root_pos
        return lp

    def __getitem__(self, item) -> "Motion":
        """Frames by slice or index array: ``motion[10:50]``, ``motion[::2]`` (fps divided by the step)."""
        if isinstance(item, (int, np.integer)):
            item = slice(int(item), int(item) + 1 if int(item) != -1 else None)
        fps = self.fps
        if isinstance(item, slice) and item.step not in (None, 1):
            if item.step <= 0:
                raise ParameterError(f"frame slices need a positive step, got {item.step}")
            fps = self.fps / item.step
        tr = None if self.translations is None else self.translations[item]
        return Motion(self.skeleton, self.root_pos[item], self.local_rot[item], fps, tr, self.name)

    def trim(self, start_s: float = 0.0, stop_s: float | None = None) -> "Motion":
        """Frames between two times in seconds (inclusive of the frame at ``start_s``)."""
        a = int(round(start_s * self.fps))
        b = self.num_frames if stop_s is None else int(round(stop_s * self.fps)) + 1
        return self[max(a, 0):min(b, self.num_frames)]

    # ------------------------------------------------------------------ kinematics
    def fk(self) -> tuple[np.ndarray, np.ndarray]:
        """Global rotations ``(F, J, 4)`` and positions ``(F, J, 3)`` of every joint."""
        from kinodyn.kinematics import forward_kinematics

        return forward_kinematics(self)

    def global_positions(self) -> np.ndarray:
        """``(F, J, 3)`` world joint positions."""
        return self.fk()[1]

    # ------------------------------------------------------------------ edits
    def resample(self, fps: float) -> "Motion":
        """The same motion sampled at another rate: slerp for rotations, lerp for positions.

        The new clip covers the same duration (its last frame is at or before the old last frame).
        """
        fps = float(fps)
        if not np.isfinite(fps) or fps <= 0:
            raise ParameterError(f"fps must be positive, got {fps}")
        n = int(np.floor(self.duration * fps + 1e-6)) + 1
        if n * self.num_joints > MAX_RESAMPLE_JOINT_FRAMES:
            raise ParameterError(f"fps {fps:g} makes {n:,} frames of {self.num_joints} joints from "
                                 f"{self.duration:g} s, more than {MAX_RESAMPLE_JOINT_FRAMES:,} joint-frames; "
                                 "choose a lower fps")
        t = np.arange(n) / fps
        tr = None if self.translations is None else interp.lerp_frames(self.translations, self.fps, t)
        return Motion(self.skeleton, interp.lerp_frames(self.root_pos, self.fps, t),
                      interp.slerp_frames(quat.unroll(self.local_rot), self.fps, t), fps, tr, self.name)

    def scaled(self, s: float) -> "Motion":
        """Change of length unit: skeleton offsets and root positions multiplied by ``s``."""
        if not np.isfinite(s) or s <= 0:
            raise ParameterError(f"scale must be a positive number, got {s}")
        tr = None if self.translations is None else self.translations * s
        return Motion(self.skeleton.scaled(s), self.root_pos * s, self.local_rot, self.fps, tr, self.name)

    def mirrored(self, axis: int = 1) -> "Motion":
        """Left/right mirror image across the plane normal to ``axis`` (default Y, the lateral axis).

        Joints swap sides by name (:meth:`Skeleton.mirror_map`); mirroring twice gives the original.
        """
        m = self.skeleton.mirror_map()
        flip = np.ones(3)
        flip[axis] = -1.0
        qflip = np.concatenate([[1.0], -flip])  # reflecting a rotation keeps the axis component along `axis`
        rp = self.root_pos * flip
        lr = self.local_rot[:, m] * qflip
        tr = None if self.translations is None else self.translations[:, m] * flip
        return Motion(self.skeleton.mirrored(axis), rp, lr, self.fps, tr, self.name)

    def ground(self, forward=None) -> np.ndarray:
        """``(F, 3)`` ground transform (x, y, heading) of the root in every frame."""
        return xform.from_root(self.root_pos, self.local_rot[:, 0], forward)

    def facing_frame(self, forward=None) -> "Motion":
        """The motion seen from its own root: floor position and heading removed in every frame."""
        g = self.ground(forward)
        q_h, _ = xform.to_quat_pos(g)
        rp = np.array(self.root_pos)
        rp[:, :2] = 0.0
        lr = np.array(self.local_rot)
        lr[:, 0] = quat.inv_mul(q_h, lr[:, 0])
        return self.replace(root_pos=rp, local_rot=lr)

    def transformed(self, g, forward=None) -> "Motion":
        """The whole clip moved on the floor by ground transform ``g (3,)`` (x, y, heading)."""
        g = np.asarray(g, dtype=np.float64)
        q, p = xform.to_quat_pos(g)
        rp = quat.mul_vec(q, self.root_pos) + p
        lr = np.array(self.local_rot)
        lr[:, 0] = quat.mul(q, lr[:, 0])
        return self.replace(root_pos=rp, local_rot=lr)

    def aligned_to(self, g, frame: int = 0, forward=None) -> "Motion":
        """The clip moved so that the ground transform of ``frame`` equals ``g (3,)``."""
        cur = self.ground(forward)[frame]
        return self.transformed(xform.compose(g, xform.inverse(cur)), forward)

    def concatenate(self, other: "Motion", align: bool = True, drop_first: bool = True,
                    forward=None) -> "Motion":
        """This clip followed by ``other``.

        Args:
            other: a motion of the same skeleton topology and fps.
            align: move ``other`` on the floor so it starts where (and facing where) this one ends.
            drop_first: skip ``other``'s first frame (it lands on this clip's last frame when aligned).
        """
        if not self.skeleton.same_topology(other.skeleton):
            raise MotionError("cannot concatenate motions of different skeletons "
                              f"({self.num_joints} vs {other.num_joints} joints or other names/parents)")
        if abs(self.fps - other.fps) > 1e-9:
            raise MotionError(f"cannot concatenate motions at {self.fps:g} and {other.fps:g} fps; resample first")
        if align:
            other = other.aligned_to(self.ground(forward)[-1], 0, forward)
        if drop_first:
            other = other[1:]
        if (self.translations is None) != (other.translations is None):
            raise MotionError("cannot concatenate a motion with animated translations and one without")
        tr = None if self.translations is None else np.concatenate([self.translations, other.translations])
        return self.replace(root_pos=np.concatenate([self.root_pos, other.root_pos]),
                            local_rot=np.concatenate([self.local_rot, quat.unroll(np.concatenate(
                                [self.local_rot[-1:], other.local_rot]))[1:]]), translations=tr)

    def retargeted(self, skeleton: Skeleton) -> "Motion":
        """The same joint rotations on a skeleton of the same topology but other bone lengths.

        Root positions scale with the ratio of the two skeletons' root heights in the rest pose, so
        strides keep their proportion to the legs.
        """
        if not self.skeleton.same_topology(skeleton):
            raise MotionError("retargeting needs a skeleton with the same joint names and parents")
        h0 = -self.skeleton.rest_positions()[:, 2].min()
        h1 = -skeleton.rest_positions()[:, 2].min()
        s = h1 / h0 if h0 > 1e-9 and h1 > 1e-9 else skeleton.height() / max(self.skeleton.height(), 1e-9)
        return self.replace(skeleton=skeleton, root_pos=self.root_pos * s, translations=None)


def _first_bad(a: np.ndarray) -> int:
    bad = ~np.isfinite(a.reshape(len(a), -1)).all(axis=1)
    return int(np.argmax(bad))
