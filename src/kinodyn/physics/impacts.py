"""Impacts on simulated characters: projectiles, impulsive pushes, contacts between characters.

The fast dynamic-response paper (section 7.2) trains on "throwing" a heavy ball at the character "while
varying its angle, speed, starting height and target landmark on the character"; :func:`launch` turns
those four parameters into the ball's start position and velocity (a ballistic arc through the target
point, reached at exactly the given launch speed). A push is an impulse at a body point: the velocities
jump by ``M^-1 J^T impulse`` at once, so the body's momentum changes by exactly the impulse.

Every contact between a character and something that is not the ground (a projectile, another character)
and every push is recorded as an :class:`Impact`: the time it started, the body it hit, the
impulse-weighted contact point and the total impulse on that body. Contacts of the same pair that
follow each other within ``gap`` seconds are one impact.

The impact stage of a :class:`~kinodyn.physics.world.World` is here too, as functions of the model, the
data and the handles: where a landmark will be when a ball arrives (:func:`landmark_point`), the
velocity jump of a push (:func:`push_velocity`), whether characters are close enough to watch their
contacts (:func:`characters_close`) and the contacts of the last step logged as impacts, switching a hit
kinematic character to dynamic (:func:`watch_contacts`).

Units: metres, seconds, kilograms, newton-seconds. World frame Z up.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.physics.assembly import geom_volume

__all__ = [
    "Impact",
    "ImpactLog",
    "aim",
    "characters_close",
    "check_push",
    "contact_impulses",
    "landmark_point",
    "launch",
    "push_velocity",
    "watch_contacts",
]

GRAVITY = np.array([0.0, 0.0, -9.81])


@dataclass(frozen=True)
class Impact:
    """One recorded impact.

    Attributes:
        time: seconds (world time) of the first contact or of the push.
        character: name of the character hit.
        body: name of the body (segment) hit.
        point: ``(3,)`` world point, impulse-weighted over the contact.
        impulse: ``(3,)`` total impulse on the body (N s), world frame.
        source: what hit it (``"ball0"``, ``"b/RightHand"``, ``"push"``).
        kind: ``"projectile"``, ``"character"`` or ``"push"``.
        duration: seconds from the first to the last contact step.
        peak_force: largest contact force magnitude (N).
    """

    time: float
    character: str
    body: str
    point: np.ndarray
    impulse: np.ndarray
    source: str
    kind: str
    duration: float = 0.0
    peak_force: float = 0.0

    def to_json(self) -> dict:
        return {"time": round(self.time, 6), "character": self.character, "body": self.body,
                "point": [round(float(x), 6) for x in self.point],
                "impulse": [round(float(x), 6) for x in self.impulse], "source": self.source, "kind": self.kind,
                "duration": round(self.duration, 6), "peak_force": round(self.peak_force, 3)}


def launch(target, speed: float, direction, height: float, distance: float = 3.0, gravity=GRAVITY):
    """Start point and velocity of a ball that reaches ``target`` with launch speed ``speed``.

    Args:
        target: ``(3,)`` world point to hit.
        speed: launch speed (m/s).
        direction: horizontal direction of travel: a heading angle (rad, 0 = +X, pi/2 = +Y) or a vector
            whose horizontal part is used.
        height: launch height above the floor (m).
        distance: horizontal distance from the target at launch (m).
        gravity: ``(3,)`` gravity vector.

    Returns:
        ``(start (3,), velocity (3,), flight_time)`` of the direct (flatter) arc.

    Raises:
        ParameterError: non-positive speed or distance, or a speed too low to reach the target.
    """
    target = np.asarray(target, dtype=np.float64)
    if not (np.isfinite(speed) and speed > 0):
        raise ParameterError(f"speed must be a positive number of m/s, got {speed!r}")
    if not (np.isfinite(distance) and distance > 0):
        raise ParameterError(f"distance must be a positive number of metres, got {distance!r}")
    if not np.isfinite(height):
        raise ParameterError(f"height must be a finite number of metres, got {height!r}")
    d = np.asarray(direction, dtype=np.float64)
    if d.ndim == 0:
        d = np.array([np.cos(d), np.sin(d), 0.0])
    d = np.array([d[0], d[1], 0.0])
    n = np.linalg.norm(d)
    if n < 1e-9:
        raise ParameterError(f"direction must have a horizontal part, got {direction!r}")
    d /= n
    start = target - d * distance
    start[2] = height
    g = np.asarray(gravity, dtype=np.float64)
    delta = target - start

    def need(t):  # launch speed that reaches the target after t seconds
        return np.linalg.norm(delta / t - 0.5 * g * t)

    # the needed speed falls then rises with t; take the direct arc, on the falling branch
    from scipy.optimize import brentq, minimize_scalar

    gn = np.linalg.norm(g)
    t_max = 4.0 * (np.linalg.norm(delta) / max(speed, 1e-9) + (speed / gn if gn > 0 else 1.0)) + 1.0
    res = minimize_scalar(need, bounds=(1e-4, t_max), method="bounded", options={"xatol": 1e-10})
    t_best, v_min = float(res.x), float(res.fun)
    if speed < v_min - 1e-9:
        raise ParameterError(f"a ball thrown at {speed:g} m/s from {distance:g} m away at height {height:g} m "
                             f"cannot reach the target; it needs at least {v_min:.2f} m/s")
    if abs(speed - v_min) < 1e-9:
        t = t_best
    else:
        t = brentq(lambda t: need(t) - speed, 1e-6, t_best, xtol=1e-12)
    vel = delta / t - 0.5 * g * t
    return start, vel, float(t)


def contact_impulses(model: mujoco.MjModel, data: mujoco.MjData, owner: np.ndarray, dt: float):
    """Contacts of the last step between a character and a non-ground object.

    Args:
        owner: ``(ngeom,)`` code of each geom: ``c >= 0`` character ``c``, ``-1`` static world (ground),
            ``-2 - p`` projectile ``p``.

    Returns:
        A list of ``(geom_a, geom_b, point (3,), impulse_on_a (3,), force_norm)`` where ``geom_a`` belongs
        to a character; a contact between two characters appears twice, once for each.
    """
    n = data.ncon
    if n == 0:
        return []
    g = data.contact.geom[:n]
    o = owner[g]
    lo, hi = o.min(axis=1), o.max(axis=1)
    # different owners, none of them the ground (-1), at least one a character (>= 0)
    idx = np.nonzero((lo != hi) & (lo != -1) & (hi >= 0))[0]
    if not len(idx):
        return []
    g1, g2 = g[:, 0], g[:, 1]
    out = []
    f6 = np.zeros(6)
    for i in idx:
        mujoco.mj_contactForce(model, data, int(i), f6)
        frame = data.contact.frame[i].reshape(3, 3)
        # frame rows are the contact axes; the normal points from geom1 to geom2 and the force is what
        # geom1 exerts on geom2.
        f_on_2 = frame.T @ f6[:3]
        p = data.contact.pos[i].copy()
        fn = float(np.linalg.norm(f_on_2))
        if fn == 0.0:  # inside the margin but not pushing
            continue
        a, b = int(g1[i]), int(g2[i])
        if owner[b] >= 0:
            out.append((b, a, p, f_on_2 * dt, fn))
        if owner[a] >= 0:
            out.append((a, b, p, -f_on_2 * dt, fn))
    return out


class ImpactLog:
    """Groups per-step contact impulses into :class:`Impact` records (mutable; owned by a World)."""

    def __init__(self, gap: float = 0.05):
        self.gap = gap
        self._open: dict[tuple, dict] = {}
        self.impacts: list[Impact] = []

    def add(self, key: tuple, time: float, character: str, body: str, point, impulse, source: str, kind: str,
            force: float, dt: float) -> None:
        ev = self._open.get(key)
        imp = np.asarray(impulse, dtype=np.float64)
        w = float(np.linalg.norm(imp))
        if ev is None:
            ev = {"time": time - dt, "last": time, "character": character, "body": body, "imp": np.zeros(3),
                  "pw": np.zeros(3), "w": 0.0, "source": source, "kind": kind, "peak": 0.0}
            self._open[key] = ev
        ev["imp"] += imp
        ev["pw"] += np.asarray(point) * w
        ev["w"] += w
        ev["last"] = time
        ev["peak"] = max(ev["peak"], force)

    def close(self, key: tuple) -> None:
        """Close one impact now (an instantaneous push)."""
        if key in self._open:
            self._close(key)

    def close_stale(self, time: float) -> None:
        """Close impacts with no contact for ``gap`` seconds."""
        for key in [k for k, ev in self._open.items() if time - ev["last"] > self.gap]:
            self._close(key)

    @staticmethod
    def _impact(ev) -> Impact:
        point = ev["pw"] / ev["w"] if ev["w"] > 0 else ev["pw"]
        return Impact(time=float(ev["time"]), character=ev["character"], body=ev["body"], point=point,
                      impulse=ev["imp"].copy(), source=ev["source"], kind=ev["kind"],
                      duration=float(ev["last"] - ev["time"]), peak_force=float(ev["peak"]))

    def _close(self, key) -> None:
        self.impacts.append(self._impact(self._open.pop(key)))
        self.impacts.sort(key=lambda i: i.time)

    def all(self) -> list[Impact]:
        """Closed impacts and the ones still in contact, sorted by time."""
        return sorted(self.impacts + [self._impact(ev) for ev in self._open.values()], key=lambda i: i.time)


# --------------------------------------------------------------------------- the world's impact stage


def landmark_point(model: mujoco.MjModel, data: mujoco.MjData, char, b: int, step: int) -> np.ndarray:
    """``(3,)`` world position of the volume-weighted centre of segment ``b``'s geometry at world step
    ``step``: predicted from the clip for a kinematic character, the current one otherwise."""
    m = model
    if char.mode == "kinematic" and char.clip is not None:
        d = mujoco.MjData(m)
        d.qpos[:] = data.qpos
        d.mocap_pos[:] = data.mocap_pos
        d.mocap_quat[:] = data.mocap_quat
        d.qpos[char.qadr:char.qadr + char.map.nq] = char.clip.state(step)[0]
    else:
        d = data
    mujoco.mj_kinematics(m, d)
    bid = char.body_ids[b]
    gs = np.arange(m.body_geomadr[bid], m.body_geomadr[bid] + m.body_geomnum[bid])
    vol = np.array([geom_volume(m, g) for g in gs])
    return (d.geom_xpos[gs] * vol[:, None]).sum(axis=0) / vol.sum()


def aim(landmark_at, t_now: float, at: float | None, speed: float, direction, height: float, distance: float,
        gravity: float):
    """Launch of a ball at a moving landmark: ``(start (3,), velocity (3,), launch_time)``.

    ``landmark_at(t)`` is the landmark's ``(3,)`` position at world time ``t``; ``at`` the arrival time
    (``None``: launch now at ``t_now``, aimed where the landmark is when the ball arrives, refined three
    times); the other arguments as :func:`launch` takes them, ``gravity`` in m/s^2 along -Z.

    Raises:
        ParameterError: the ball cannot arrive at ``at`` (its flight would have to start in the past).
    """
    t_hit = t_now if at is None else float(at)
    for _ in range(3):
        target = landmark_at(t_hit)
        start, vel, flight = launch(target, speed, direction, height, distance, np.array([0.0, 0.0, -gravity]))
        if at is None:
            t_hit = t_now + flight
        else:
            break
    t_launch = t_hit - flight if at is not None else t_now
    if t_launch < t_now - 1e-9:
        raise ParameterError(f"cannot make the ball arrive at t={t_hit:.3f} s: its flight takes {flight:.3f} s "
                             f"and the world is at t={t_now:.3f} s")
    return start, vel, t_launch


def push_velocity(model: mujoco.MjModel, data: mujoco.MjData, bid: int, impulse: np.ndarray, point=None):
    """``(nv,)`` velocity jump ``M^-1 J^T impulse`` of an impulse ``(3,)`` N s at world ``point`` (default
    the body's centre of mass) on MuJoCo body ``bid``, at the current pose. Returns ``(dv, point)``."""
    m, d = model, data
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_crb(m, d)
    mujoco.mj_factorM(m, d)
    if point is None:
        p = d.xipos[bid].copy()
    else:
        p = np.asarray(point, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ParameterError(f"point must be a finite (3,) world position, got {point!r}")
    jacp = np.zeros((3, m.nv))
    mujoco.mj_jac(m, d, jacp, None, p, bid)
    dv = np.zeros((1, m.nv))
    mujoco.mj_solveM(m, d, dv, (jacp.T @ impulse)[None, :])
    return dv[0], p


def check_push(model: mujoco.MjModel, qvel: np.ndarray, max_speed: float, impulse: np.ndarray,
               where: str) -> ParameterError | None:
    """The error to raise when a push would leave ``qvel (nv,)`` non-finite or with a speed above
    ``max_speed`` (m/s or rad/s), else ``None``; ``where`` names the body pushed."""
    speed = np.abs(np.nan_to_num(qvel, nan=np.inf))
    if not len(speed) or speed.max() <= max_speed:
        return None
    dof = int(np.argmax(speed))
    return ParameterError(f"an impulse of {np.linalg.norm(impulse):.4g} N s on {where} would move "
                          f"{model.body(model.dof_bodyid[dof]).name!r} at {speed[dof]:.4g} m/s or rad/s, above "
                          f"max_speed ({max_speed:g}); push with a smaller impulse or on a heavier body")


def characters_close(data: mujoco.MjData, characters, reach: np.ndarray) -> bool:
    """Whether two characters may touch within the next frame (their roots closer than their reaches
    ``(C,)`` plus a margin); contacts between characters are watched only then."""
    n = len(characters)
    if n < 2:
        return False
    d = data
    pos = np.empty((n, 3))
    for i, c in enumerate(characters):
        pos[i] = d.mocap_pos[c.mocap_id] if c.mocap_id >= 0 else d.qpos[c.qadr:c.qadr + 3]
    dist = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    near = dist < reach[:, None] + reach[None, :] + 0.5
    np.fill_diagonal(near, False)
    return bool(near.any())


def watch_contacts(model: mujoco.MjModel, data: mujoco.MjData, owner: np.ndarray, dt: float, t: float,
                   characters, projectiles, log: ImpactLog) -> bool:
    """Log the last step's contacts of characters with balls and each other in ``log`` (at world time
    ``t``) and switch a hit kinematic character whose ``on_impact`` is ``"switch"`` to dynamic, keeping
    the state this step produced. Returns whether someone switched."""
    hits = contact_impulses(model, data, owner, dt)
    switched = False
    for ga, gb, p, imp, fn in hits:
        ca = characters[owner[ga]]
        ob = owner[gb]
        if ob >= 0:
            other = characters[ob]
            if ca.mode == "kinematic" and ca.on_impact != "switch":
                continue  # a clip that does not react (an attacker's fist): nothing happens to it
            src = f"{other.name}/{model.body(model.geom_bodyid[gb]).name.split('/', 1)[-1]}"
            kind = "character"
        else:
            src = projectiles[-2 - ob].name
            kind = "projectile"
        b = int(np.searchsorted(ca.body_ids, model.geom_bodyid[ga]))
        log.add((ca.index, b, src), t, ca.name, ca.map.segments[b].name, p, imp, src, kind, fn, dt)
        if ca.mode == "kinematic" and ca.on_impact == "switch":
            # keep the state this step produced (it holds the impact) and simulate from here on
            ca.mode = "dynamic"
            ca.switch_time = t
            switched = True
    log.close_stale(t)
    return switched
