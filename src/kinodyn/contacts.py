"""Foot contacts and foot sliding.

A foot touches the ground when one of its points (ankle, toe, toe tip) is both low and slow: below a
height threshold above the floor and moving slower than a speed threshold, the two parameters of
Multon et al., "support-phase synchronization", section 4.2. The speed test tells a planted foot from
one that sweeps close to the floor during a swing. The height is measured from the ground the foot
stands on near each instant (:func:`support_level`), so tilted, raised and soft capture floors, falls
and get-ups keep their contacts; for a foot that is the body's only support the speed limit grows with
the body's speed (a stumbling foot slides while it carries the body).

The *sliding* measure used across kinodyn to judge quality is the horizontal speed of the foot's
lowest point while the foot is in contact: a planted foot should not move.

Shapes: ``F`` frames, ``P`` points of one foot. Heights and speeds in metres and metres per second.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinodyn import roles
from kinodyn._arrays import percentile
from kinodyn.errors import ParameterError, UnknownNameError
from kinodyn.kinematics import forward_kinematics, linear_velocity
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = ["ContactConfig", "FootContacts", "find_feet", "foot_points", "detect", "intervals", "sliding",
           "SlidingReport", "support_level"]

SIDES = roles.SIDES


@dataclass(frozen=True)
class ContactConfig:
    """Thresholds of foot-contact detection.

    Attributes:
        height: metres above the floor under which a foot point may touch (the paper's first parameter).
        speed: metres per second under which a low foot point is planted (the paper's second parameter).
        floor: floor height in metres, or ``None`` to estimate the floor from the clip: a plane fitted
            through the lowest foot points while they are slow (capture floors are rarely exactly at 0
            and often tilted by a few centimetres over the capture area), shifted down to the 2nd
            percentile of the lowest points. Clips that cover little ground get a level floor.
        min_frames: contact or flight runs shorter than this many frames are merged into their
            neighbours (removes single-frame flicker).
        relative_speed: a foot point moving slower than this fraction of the root's horizontal speed
            counts as slow too, up to :data:`RELATIVE_CAP` times ``speed``, while the other foot is
            well up (:data:`SWING_HEIGHT`), so this foot is the body's only support, and the body moves
            slower than a run (:data:`RELATIVE_BODY_MAX`): a stumbling walk slides its supporting foot
            at several tenths of a metre per second, while a swinging foot moves at about twice the
            body's speed; 0 keeps the limit at ``speed``.

    With an estimated floor, the height test is made against the *support level* each foot stands on
    near each instant (:func:`support_level`): a clip that stands on a raised platform, steps down from
    it, falls onto a mat or gets up from the floor keeps its contacts, where a single floor height for
    the whole clip would put the feet either through it or out of reach.
    """

    height: float = 0.05
    speed: float = 0.35
    floor: float | None = None
    min_frames: int = 2
    relative_speed: float = 0.5

    def __post_init__(self):
        if not (np.isfinite(self.height) and self.height > 0):
            raise ParameterError(f"height threshold must be a positive number of metres, got {self.height}")
        if not (np.isfinite(self.speed) and self.speed > 0):
            raise ParameterError(f"speed threshold must be a positive number of m/s, got {self.speed}")
        if self.floor is not None and not np.isfinite(self.floor):
            raise ParameterError(f"floor must be finite or None, got {self.floor}")
        if self.min_frames < 1:
            raise ParameterError(f"min_frames must be at least 1, got {self.min_frames}")
        if not (np.isfinite(self.relative_speed) and self.relative_speed >= 0):
            raise ParameterError(f"relative_speed must be a non-negative fraction, got {self.relative_speed}")


def find_feet(skeleton: Skeleton, feet: dict[str, list[str]] | None = None) -> dict[str, np.ndarray]:
    """Joint indices of each foot (``{"left": ..., "right": ...}``), found by joint names.

    A foot is every joint whose name says foot, ankle, toe or heel on that side (``LeftFoot``,
    ``LeftToeBase``, ``lfoot``, ``l_ankle``, ``RightToe``...). Pass ``feet`` (side -> joint names) to
    override.

    Raises:
        UnknownNameError: a foot cannot be found; the message lists the joints.
    """
    if feet is not None:
        out = {}
        for side in SIDES:
            if side not in feet or not feet[side]:
                raise ParameterError(f"feet override needs a non-empty list for {side!r}, got {feet.get(side)!r}")
            out[side] = skeleton.indices(feet[side])
        return out
    out = roles.feet(skeleton)
    for s in SIDES:
        if not out[s]:
            raise UnknownNameError(
                f"cannot find the {s} foot by joint names (looked for foot/ankle/toe/heel with a side marker); "
                f"pass feet={{'left': [...], 'right': [...]}}; joints are: {', '.join(skeleton.names)}")
    return {s: np.array(v, dtype=np.int64) for s, v in out.items()}


def foot_points(motion: Motion, feet: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """World positions ``(F, P, 3)`` of each foot's points: its joints plus their end sites."""
    feet = find_feet(motion.skeleton) if feet is None else feet
    gr, gp = forward_kinematics(motion)
    sk = motion.skeleton
    out = {}
    for side, idx in feet.items():
        pts = [gp[:, idx]]
        ends = roles.end_sites_of(sk, idx)
        if len(ends):
            par = sk.end_parents[ends]
            pts.append(gp[:, par] + quat.mul_vec(gr[:, par], sk.end_offsets[ends]))
        out[side] = np.concatenate(pts, axis=1)
    return out


@dataclass(frozen=True)
class FootContacts:
    """Per-foot contact labels of a clip.

    Attributes:
        labels: ``{"left": (F,) bool, "right": (F,) bool}``.
        lowest: ``{side: (F, 3)}`` world position of the foot's lowest point in each frame.
        lowest_velocity: ``{side: (F, 3)}`` velocity of that point (m/s).
        floor: the floor height used (at x = y = 0).
        fps: frame rate of the clip.
        floor_slope: ``(2,)`` floor slope along x and y (zero for a level floor).
    """

    labels: dict[str, np.ndarray]
    lowest: dict[str, np.ndarray]
    lowest_velocity: dict[str, np.ndarray]
    floor: float
    fps: float
    floor_slope: tuple[float, float] = (0.0, 0.0)

    def floor_height(self, xy) -> np.ndarray:
        """Floor height under points ``xy (..., 2)``."""
        xy = np.asarray(xy, dtype=np.float64)
        return self.floor + xy[..., 0] * self.floor_slope[0] + xy[..., 1] * self.floor_slope[1]

    def as_array(self) -> np.ndarray:
        """``(F, 2)`` bool, columns left and right."""
        return np.stack([self.labels[s] for s in SIDES], axis=1)

    def intervals(self) -> dict[str, np.ndarray]:
        """``{side: (K, 2)}`` start (inclusive) and stop (exclusive) frames of each contact."""
        return {s: intervals(self.labels[s]) for s in SIDES}


def _clean(labels: np.ndarray, min_frames: int) -> np.ndarray:
    """Merge runs shorter than ``min_frames`` into their neighbours."""
    if min_frames <= 1 or len(labels) == 0:
        return labels
    out = labels.copy()
    for value in (True, False):  # drop short contacts, then fill short gaps
        iv = intervals(out == value)
        for a, b in iv:
            if b - a < min_frames and a > 0 and b < len(out):
                out[a:b] = not value
    return out


def detect(motion: Motion, config: ContactConfig = ContactConfig(),
           feet: dict[str, np.ndarray] | None = None) -> FootContacts:
    """Label each foot in contact or not in every frame (height and speed thresholds).

    Args:
        motion: the clip.
        config: thresholds (:class:`ContactConfig`).
        feet: optional foot joint indices per side (see :func:`find_feet`).
    """
    pts = foot_points(motion, feet)
    vel = {side: linear_velocity(pts[side], motion.fps) for side in SIDES}
    if config.floor is None:
        floor, slope = _estimate_floor(pts, vel, config)
    else:
        floor, slope = float(config.floor), np.zeros(2)
    root = np.asarray(motion.root_pos, dtype=np.float64)
    body = _window_speed(root[:, None, :2], motion.fps)[:, 0]
    limit = np.where(body < RELATIVE_BODY_MAX,
                     np.clip(config.relative_speed * body, config.speed, RELATIVE_CAP * config.speed), config.speed)
    heights = {side: pts[side][..., 2] - (floor + pts[side][..., :2] @ slope) for side in SIDES}
    speeds = {side: _window_speed(pts[side], motion.fps) for side in SIDES}
    slow = {side: speeds[side] < config.speed for side in SIDES}
    if config.floor is None:
        ground, level = _ground_and_levels({s: heights[s].min(axis=1) for s in SIDES},
                                           {s: slow[s].any(axis=1) for s in SIDES}, motion.fps)
    else:
        ground, level = np.zeros(len(root)), {side: np.zeros(len(root)) for side in SIDES}
    # the faster limit holds for the body's only support: a foot while the other is well up
    up = {s: heights[s].min(axis=1) - level[s] > SWING_HEIGHT * config.height for s in SIDES}
    limit = np.where(np.stack([up[s] for s in SIDES[::-1]]), limit, config.speed)  # (2, F): left, right
    slow = {s: slow[s] | (speeds[s] < limit[i][:, None]) for i, s in enumerate(SIDES)}
    labels, lowest, lowest_vel = {}, {}, {}
    for side in SIDES:
        p = pts[side]  # (F, P, 3)
        height = heights[side]
        # the lowest point is near the ground while some point of the foot is slow: a foot rolling over
        # its toes or pivoting on its heel is planted even though its low points sweep
        # (a foot very close to the ground that turns on it, for a while, may do so at up to 1.5 times
        # the speed threshold; a landing foot passes that band in a frame or two)
        above = height.min(axis=1) - level[side]
        touching = (above < config.height) & slow[side].any(axis=1)
        # (the band starts at the foot's level but at most LOW_FRACTION * height above the ground: a foot
        # sliding down from a raised level is not turning on the ground)
        band = np.minimum(level[side], ground + LOW_FRACTION * config.height)
        turning = ((height.min(axis=1) - band < LOW_FRACTION * config.height)
                   & (speeds[side].min(axis=1) < 1.5 * limit[SIDES.index(side)]) & ~touching)
        for a, b in intervals(turning):
            touching[a:b] = (b - a) >= TURN_TIME * motion.fps
        labels[side] = _clean(touching, config.min_frames)
        k = np.argmin(height, axis=1)
        rows = np.arange(len(p))
        lowest[side] = p[rows, k]
        lowest_vel[side] = vel[side][rows, k]
    return FootContacts(labels, lowest, lowest_vel, floor, motion.fps, (float(slope[0]), float(slope[1])))


#: Seconds of a foot point's displacement its detection speed is measured over (steadier than one frame
#: at high capture rates, where marker jitter alone reads as tenths of a metre per second).
SPEED_SPAN = 1.0 / 30.0
#: Half-width (s) of the window both feet's ground is taken over (its low percentile of their slow lowest
#: heights), the half-width of the window of a foot's own level (the median of its slow lowest heights:
#: short, since a soft floor gives under a crouch within a few tenths of a second), and the most (m) a
#: foot's level may stand above both feet's.
LEVEL_WINDOW = 1.0
OWN_WINDOW = 0.3
LEVEL_PERCENTILE = 10.0
LEVEL_OWN_PERCENTILE = 50.0
LEVEL_RAISE = 0.06
#: Fraction of the height threshold under which a foot counts as planted at up to 1.5 times the speed threshold.
LOW_FRACTION = 0.4
#: Seconds a foot must stay in that band to count as turning on the ground.
TURN_TIME = 0.1
#: The most the speed limit grows with the body's speed, as a multiple of the speed threshold.
RELATIVE_CAP = 2.0
#: Multiple of the height threshold above its level the other foot must be for a foot to get that limit.
SWING_HEIGHT = 2.0
#: Body speed (m/s) from which the limit stays at the threshold: a run plants its supporting foot, and its
#: landing foot sweeps in faster than a walk's.
RELATIVE_BODY_MAX = 2.5


def _window_speed(p, fps: float) -> np.ndarray:
    """``(F, P)`` speed of points ``p (F, P, D)`` over :data:`SPEED_SPAN` (central, clamped at the ends)."""
    n = len(p)
    k = max(1, int(fps * SPEED_SPAN / 2 + 1e-9))
    i = np.arange(n)
    a, b = np.clip(i - k, 0, n - 1), np.clip(i + k, 0, n - 1)
    span = np.maximum(b - a, 1) / fps
    return np.linalg.norm(p[b] - p[a], axis=-1) / span[:, None]


def _low_track(h, ok, fps: float, q: float = LEVEL_PERCENTILE, window: float = LEVEL_WINDOW) -> np.ndarray:
    """``(F,)`` the ``q`` percentile of ``h[ok]`` within ``window`` seconds of each frame, evaluated
    every 0.1 s and interpolated (NaN everywhere when too few frames are ``ok``)."""
    n = len(h)
    half = max(1, int(round(window * fps)))
    need = max(3, int(round(0.1 * fps)))
    centers = np.arange(0, n, max(1, int(round(0.1 * fps))))
    if n and centers[-1] != n - 1:
        centers = np.r_[centers, n - 1]  # sorted and unique (np.unique would import numpy.ma)
    vals = np.full(len(centers), np.nan)
    for j, c in enumerate(centers):
        a, b = max(0, c - half), min(n, c + half + 1)
        x = h[a:b][ok[a:b]]
        if len(x) >= need:
            vals[j] = percentile(x, q)
    good = np.isfinite(vals)
    if not good.any():
        return np.full(n, np.nan)
    return np.interp(np.arange(n), centers[good], vals[good])


def support_level(low: dict, slow: dict, fps: float) -> dict:
    """Height of the ground each foot stands on near each frame, relative to the fitted floor.

    Args:
        low: ``{side: (F,)}`` height of the foot's lowest point above the fitted floor plane.
        slow: ``{side: (F,) bool}`` frames where some point of the foot is slow.
        fps: frame rate.

    Returns:
        ``{side: (F,)}``: the median of the foot's slow lowest heights within :data:`OWN_WINDOW` (a foot
        standing flat rests its lowest point higher than one rolling over its toes), between both
        feet's low percentile within :data:`LEVEL_WINDOW` (the ground nearby) and :data:`LEVEL_RAISE`
        above it, and never below 0 (the fitted floor stays the lowest ground); where a foot is never
        slow nearby, both feet's level, else 0.
    """
    return _ground_and_levels(low, slow, fps)[1]


def _ground_and_levels(low: dict, slow: dict, fps: float) -> tuple[np.ndarray, dict]:
    """Both feet's ground ``(F,)`` (never below 0) and each foot's level (:func:`support_level`)."""
    both = _low_track(np.concatenate([low[s] for s in SIDES]).reshape(2, -1).min(axis=0),
                      np.logical_or(*[slow[s] for s in SIDES]), fps)
    both = np.where(np.isfinite(both), both, 0.0)
    out = {}
    for s in SIDES:
        own = _low_track(low[s], slow[s], fps, LEVEL_OWN_PERCENTILE, OWN_WINDOW)
        own = np.where(np.isfinite(own), own, both)
        out[s] = np.maximum(np.clip(own, both, both + LEVEL_RAISE), 0.0)
    return np.maximum(both, 0.0), out


#: A floor plane is fitted only when the planted points spread over at least this many metres.
_PLANE_MIN_SPREAD = 1.0
#: Largest floor slope accepted from a fit (about 3 degrees); steeper fits mean the data is not a floor.
_PLANE_MAX_SLOPE = 0.05


def _estimate_floor(pts, vel, config: ContactConfig) -> tuple[float, np.ndarray]:
    """Floor height at the origin and slope ``(2,)`` from the clip's lowest foot points."""
    lows, slow = [], []
    for side in SIDES:
        p = pts[side]
        k = np.argmin(p[..., 2], axis=1)
        rows = np.arange(len(p))
        lows.append(p[rows, k])
        slow.append(np.linalg.norm(vel[side][rows, k], axis=-1) < config.speed)
    low = np.concatenate(lows)
    planted = low[np.concatenate(slow)]
    slope = np.zeros(2)
    if len(planted) >= 10 and np.ptp(planted[:, :2], axis=0).max() >= _PLANE_MIN_SPREAD:
        # Keep the planted points near the bottom (stance), fit z = a x + b y + c by least squares.
        base = percentile(planted[:, 2], 2.0)
        near = planted[planted[:, 2] < base + config.height]
        if len(near) >= 10 and np.ptp(near[:, :2], axis=0).max() >= _PLANE_MIN_SPREAD:
            a = np.c_[near[:, :2], np.ones(len(near))]
            coef = np.linalg.lstsq(a, near[:, 2], rcond=None)[0]
            if np.all(np.abs(coef[:2]) <= _PLANE_MAX_SLOPE):
                slope = coef[:2]
    floor = float(percentile(low[:, 2] - low[:, :2] @ slope, 2.0))
    return floor, slope


def intervals(labels) -> np.ndarray:
    """``(K, 2)`` start (inclusive) and stop (exclusive) indices of the True runs of ``labels (F,)``."""
    x = np.asarray(labels, dtype=bool).astype(np.int8)
    d = np.diff(np.concatenate([[0], x, [0]]))
    return np.stack([np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]], axis=1)


@dataclass(frozen=True)
class SlidingReport:
    """Foot sliding of a clip: horizontal speed of the lowest foot point while in contact (m/s).

    Attributes:
        mean: mean over all contact frames of both feet (the headline figure).
        per_foot: mean per side.
        p95: 95th percentile over contact frames.
        contact_frames: number of contact frames counted.
    """

    mean: float
    per_foot: dict[str, float]
    p95: float
    contact_frames: int

    @property
    def cm_per_s(self) -> float:
        return 100.0 * self.mean


def sliding(motion: Motion, contacts: FootContacts | None = None, config: ContactConfig = ContactConfig(),
            feet: dict[str, np.ndarray] | None = None) -> SlidingReport:
    """Foot sliding measure (see :class:`SlidingReport`); contacts are detected when not given."""
    c = detect(motion, config, feet) if contacts is None else contacts
    speeds, per = [], {}
    for side in SIDES:
        sp = np.linalg.norm(c.lowest_velocity[side][:, :2], axis=-1)[c.labels[side]]
        per[side] = float(sp.mean()) if len(sp) else 0.0
        speeds.append(sp)
    allsp = np.concatenate(speeds)
    if len(allsp) == 0:
        return SlidingReport(0.0, per, 0.0, 0)
    return SlidingReport(float(allsp.mean()), per, float(percentile(allsp, 95)), int(len(allsp)))
