"""The character AI: simple behaviours that set each body's target velocity and heading (section 3).

Mitake et al., section 3 and figure 1: the character AI decides the goal of attitude and locomotion
for the controller (here a target horizontal velocity and heading) and the behaviour value B for the
animation. Behaviours, one per character, all evaluated together on arrays:

* :data:`IDLE`: stand still, keep the heading;
* :data:`GOTO`: walk to a point, slowing down within ``arrive_radius``;
* :data:`WANDER`: walk with a heading that drifts randomly (a random walk of ``wander_rate`` rad/sqrt(s));
* :data:`FOLLOW`: walk to a place ``follow_distance`` behind another character;
* :data:`FLEE`: walk away from a point while within ``flee_radius`` of it.

State is explicit (:class:`AIState`, mutated by :func:`decide`); randomness comes from its generator.
Shapes: N characters; positions are world ``(x, y)`` in metres, velocities m/s, angles radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from kinodyn.crowd.body import RigidState
from kinodyn.errors import ParameterError

__all__ = [
    "BEHAVIOURS",
    "FLEE",
    "FOLLOW",
    "GOTO",
    "IDLE",
    "WANDER",
    "AIConfig",
    "AIState",
    "decide",
    "decide_fast",
    "new_ai",
]

IDLE, GOTO, WANDER, FOLLOW, FLEE = range(5)
BEHAVIOURS = ("idle", "goto", "wander", "follow", "flee")


@dataclass(frozen=True)
class AIConfig:
    """Parameters of the behaviours (metres, seconds, radians)."""

    speed: float = 1.2
    arrive_radius: float = 1.0
    wander_rate: float = 0.8
    follow_distance: float = 1.2
    flee_radius: float = 6.0

    def __post_init__(self):
        for k, v in self.__dict__.items():
            if not (np.isfinite(v) and v > 0):
                raise ParameterError(f"AIConfig.{k} must be a positive number, got {v!r}")


@dataclass
class AIState:
    """What each character is doing (mutable; :func:`decide` advances the wander headings).

    Attributes:
        kind: ``(N,)`` behaviour codes.
        target: ``(N, 2)`` goal point (GOTO) or the point to flee from (FLEE).
        leader: ``(N,)`` index of the character to follow (FOLLOW).
        speed: ``(N,)`` walking speed, m/s.
        wander: ``(N,)`` current wander heading.
        rng: the generator behind the wandering.
    """

    kind: np.ndarray
    target: np.ndarray
    leader: np.ndarray
    speed: np.ndarray
    wander: np.ndarray
    rng: np.random.Generator


def new_ai(n: int, headings: np.ndarray, cfg: AIConfig, rng: np.random.Generator) -> AIState:
    """N idle characters with speeds spread +-15 % around ``cfg.speed``."""
    return AIState(kind=np.full(n, IDLE, np.int64), target=np.zeros((n, 2)), leader=np.zeros(n, np.int64),
                   speed=cfg.speed * rng.uniform(0.85, 1.15, n), wander=np.array(headings, float), rng=rng)


def _toward(delta: np.ndarray, speed: np.ndarray, slow: float) -> np.ndarray:
    dist = np.linalg.norm(delta, axis=1)
    gain = np.minimum(1.0, dist / slow) * speed / np.maximum(dist, 1e-9)
    return delta * gain[:, None]


def decide(ai: AIState, s: RigidState, cfg: AIConfig, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Target velocities ``(N, 2)`` and headings ``(N,)`` for the controller."""
    n = s.r.shape[0]
    pos = s.r[:, :2]
    v = np.zeros((n, 2))
    k = ai.kind
    go = k == GOTO
    v[go] = _toward(ai.target[go] - pos[go], ai.speed[go], cfg.arrive_radius)
    wa = k == WANDER
    ai.wander[wa] += cfg.wander_rate * np.sqrt(dt) * ai.rng.standard_normal(int(wa.sum()))
    v[wa] = ai.speed[wa, None] * np.stack([np.cos(ai.wander[wa]), np.sin(ai.wander[wa])], axis=1)
    fo = k == FOLLOW
    if fo.any():
        lead = ai.leader[fo]
        behind = pos[lead] - cfg.follow_distance * s.forward[lead, :2]
        v[fo] = _toward(behind - pos[fo], ai.speed[fo] * 1.2, cfg.arrive_radius)
    fl = k == FLEE
    away = pos[fl] - ai.target[fl]
    dist = np.linalg.norm(away, axis=1)
    near = dist < cfg.flee_radius
    v_fl = np.zeros_like(away)
    v_fl[near] = away[near] * (1.5 * ai.speed[fl][near] / np.maximum(dist[near], 1e-9))[:, None]
    v[fl] = v_fl
    moving = np.linalg.norm(v, axis=1) > 0.15
    heading = np.where(moving, np.arctan2(v[:, 1], v[:, 0]), s.heading)
    return v, heading


@numba.njit(cache=True, inline="always")
def _toward1(dx, dy, speed, slow):
    dist = np.sqrt(dx * dx + dy * dy)
    gain = min(1.0, dist / slow) * speed / max(dist, 1e-9)
    return dx * gain, dy * gain


@numba.njit(cache=True)
def _decide_kernel(kind, target, leader, speed, wander, noise, pos, forward, heading, arrive, follow, flee,
                   v, out_heading):
    k_noise = 0
    for i in range(kind.shape[0]):
        vx, vy = 0.0, 0.0
        k = kind[i]
        if k == GOTO:
            vx, vy = _toward1(target[i, 0] - pos[i, 0], target[i, 1] - pos[i, 1], speed[i], arrive)
        elif k == WANDER:
            wander[i] += noise[k_noise]
            k_noise += 1
            vx, vy = speed[i] * np.cos(wander[i]), speed[i] * np.sin(wander[i])
        elif k == FOLLOW:
            j = leader[i]
            bx, by = pos[j, 0] - follow * forward[j, 0], pos[j, 1] - follow * forward[j, 1]
            vx, vy = _toward1(bx - pos[i, 0], by - pos[i, 1], speed[i] * 1.2, arrive)
        elif k == FLEE:
            ax, ay = pos[i, 0] - target[i, 0], pos[i, 1] - target[i, 1]
            dist = np.sqrt(ax * ax + ay * ay)
            if dist < flee:
                g = 1.5 * speed[i] / max(dist, 1e-9)
                vx, vy = ax * g, ay * g
        v[i, 0], v[i, 1] = vx, vy
        out_heading[i] = np.arctan2(vy, vx) if np.sqrt(vx * vx + vy * vy) > 0.15 else heading[i]


def decide_fast(ai: AIState, s: RigidState, cfg: AIConfig, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`decide` in one compiled pass (the same random draws, so the same crowd from a seed)."""
    n = s.r.shape[0]
    noise = cfg.wander_rate * np.sqrt(dt) * ai.rng.standard_normal(int(np.count_nonzero(ai.kind == WANDER)))
    v, heading = np.empty((n, 2)), np.empty(n)
    _decide_kernel(ai.kind, ai.target, ai.leader, ai.speed, ai.wander, noise, s.r, s.forward, s.heading,
                   float(cfg.arrive_radius), float(cfg.follow_distance), float(cfg.flee_radius), v, heading)
    return v, heading
