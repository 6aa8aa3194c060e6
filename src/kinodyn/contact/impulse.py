"""Impulse-based dynamics of simulated objects: restitution, Coulomb friction, virtual coupling.

Schmidl and Lin, "Impulses" and "Adding friction", after Mirtich (1995) and Schmidl and Milenkovic
(2004). Simulated objects move under gravity between collisions; a collision is a contact with
negative relative normal velocity ``v_perp = n . v_ab`` (7), resolved by an impulse ``j n`` on A and
``-j n`` on B with

    j = -(1 + e) v_perp / (1/m_a + 1/m_b + n.(I_a^-1 (r_a x n)) x r_a + n.(I_b^-1 (r_b x n)) x r_b)   (9)

so that ``v_perp+ = -e v_perp-`` (8), and a friction impulse ``j_t = -mu j v_t / |v_t|`` (10) that is
capped where it would stop the sliding, so it never reverses it. Contacts are resolved one at a time
in a priority queue, most negative ``v_perp`` first, until none approaches. A contact approaching slower
than ``resting_speed``, or than gravity adds in ``resting_steps`` integration steps, is a resting
contact and gets ``e = 0`` (the micro-collision treatment of resting contact): so an object lying on
a table does not bounce on the speed one step of gravity gives it, however long the step. Driven
objects follow their tracker through the virtual coupling spring
``m x'' = -K x - R x'`` (6) (``x`` measured from the tracker; K = 1000, R = 40).

Each contact of a convex pair is placed at the centre of its manifold (the witness point and the
vertices of the simulated piece within the contact margin), so a block resting on a face is pushed at
its centre of pressure. Fast objects stop at their time of impact (bisection) before the collision is
resolved. :class:`Bodies` is the mutable state. Metres, kilograms, seconds; ``(w, x, y, z)``.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, replace

import numpy as np

from kinodyn.contact.collide import CollisionWorld
from kinodyn.contact.setting import coefficients
from kinodyn.math.array_kernels import cross3, qaxis, qmat, qmul

__all__ = ["Bodies", "ImpulseConfig", "ImpulseStats", "apply_impulses", "contact_rows", "couple", "step"]


@dataclass(frozen=True)
class ImpulseConfig:
    """Impulse dynamics settings.

    Attributes:
        gravity: ``(3,)`` m/s^2.
        substeps: integration steps per frame. Two are enough: at 60 Hz the rebound (e^2 h) and the
            sliding block (mu g) stay within 1.5 % and 0.1 % of their analytic values, as with eight;
            one step lets a sliding block stick (resting contacts then eat its friction).
        margin: distance within which two pieces are in contact (m).
        resting_speed: approach speed below which a contact is resting (e = 0), m/s.
        resting_steps: ... or below the speed gravity adds in this many steps (at 2 substeps of 60 Hz,
            0.12 m/s; at 8 substeps ``resting_speed`` is the larger).
        toi_depth: overlap that stops a step at the time of impact (m).
        max_impulses: impulses per resolution before giving up.
        coupling_k, coupling_r: virtual coupling stiffness (N/m) and damping (N s/m) (equation 6).
    """

    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    substeps: int = 2
    margin: float = 5e-4
    resting_speed: float = 0.08
    resting_steps: float = 1.5
    toi_depth: float = 1e-3
    max_impulses: int = 200
    coupling_k: float = 1000.0
    coupling_r: float = 40.0


@dataclass
class ImpulseStats:
    """Counts of one frame: collisions (restitution impulses), resting impulses, time-of-impact stops."""

    collisions: int = 0
    resting: int = 0
    toi: int = 0


class Bodies:
    """Mutable rigid-body state of the world's simulated objects (and the velocities of driven ones).

    Attributes: ``pos (N, 3)``, ``quat (N, 4)`` mirror the world; ``vel``, ``omega (N, 3)`` linear and
    angular velocities (world); ``inv_mass (N,)`` (0: immovable); ``inv_inertia (N, 3, 3)`` in the body
    frame; ``simulated (N,)`` which objects integrate.
    """

    def __init__(self, world: CollisionWorld):
        n = world.num_objects
        self.world = world
        kinds = [o.kind for o in world.objects]
        self.simulated = np.array([k == "simulated" for k in kinds])
        self.driven = np.array([k == "driven" for k in kinds])
        self.vel = np.array([o.velocity for o in world.objects], dtype=np.float64).reshape(n, 3)
        self.omega = np.zeros((n, 3))
        self.inv_mass = np.zeros(n)
        self.inv_inertia = np.zeros((n, 3, 3))
        for k, o in enumerate(world.objects):
            if self.simulated[k]:
                self.inv_mass[k] = 1.0 / o.mass
                self.inv_inertia[k] = np.linalg.inv(o.inertia())
        self.materials = [o.material for o in world.objects]
        self.coupled = np.zeros(n, bool)

    def inv_inertia_world(self, k: int) -> np.ndarray:
        """``(3, 3)`` inverse inertia of object ``k`` in the world frame."""
        r = qmat(self.world.quat[k])
        return r @ self.inv_inertia[k] @ r.T

    def point_velocity(self, k: int, p) -> np.ndarray:
        return self.vel[k] + cross3(self.omega[k], p - self.world.pos[k])


def _manifold_point(world: CollisionWorld, bodies: Bodies, ga, gb, point, margin) -> np.ndarray:
    """Centre of pressure of a convex pair: the simulated pieces' vertices within ``margin`` of the other
    piece, weighted by how far inside the margin they are (deeper pushes harder), or the witness point."""
    pts, wts = [], []
    for g, other in ((ga, gb), (gb, ga)):
        if bodies.simulated[world.geom_object[g]]:
            v = world.piece_vertices(g)
            if len(v):
                d = world.point_distance(other, v, distmax=2 * margin)
                near = d < margin
                pts.append(v[near])
                wts.append(margin - d[near])
    if not pts or not sum(len(p) for p in pts):
        return point, False
    p, w = np.concatenate(pts), np.concatenate(wts)
    return (w[:, None] * p).sum(axis=0) / w.sum(), len(p) >= 3


def _approach(bodies: Bodies, a, b, n, p) -> tuple[float, np.ndarray]:
    v = bodies.point_velocity(a, p) - bodies.point_velocity(b, p)
    return float(n @ v), v


def _apply(bodies: Bodies, k, imp, p, sign) -> None:
    if bodies.inv_mass[k] == 0.0:
        return
    bodies.vel[k] += sign * imp * bodies.inv_mass[k]
    if bodies.simulated[k]:
        bodies.omega[k] += sign * bodies.inv_inertia_world(k) @ cross3(p - bodies.world.pos[k], imp)


def _eff(bodies: Bodies, k, p, d) -> float:
    """Inverse effective mass of object ``k`` at ``p`` along ``d`` (the terms of equation 9)."""
    if bodies.inv_mass[k] == 0.0:
        return 0.0
    out = bodies.inv_mass[k]
    if bodies.simulated[k]:
        r = p - bodies.world.pos[k]
        out += float(d @ cross3(bodies.inv_inertia_world(k) @ cross3(r, d), r))
    return out


def _impulse(bodies: Bodies, a, b, n, p, face, cfg: ImpulseConfig, stats: ImpulseStats) -> bool:
    """Equations 7-10 for one contact; True when an impulse was applied. A resting contact over a face
    (``face``: three or more manifold vertices) also stops rocking about the face's tangent axes: a
    rigid block flat on a rigid table cannot tilt into it."""
    vn, v = _approach(bodies, a, b, n, p)
    if vn >= -1e-9:
        return False
    e, mu = coefficients(bodies.materials[a], bodies.materials[b])
    if -vn < cfg.resting_speed:
        e = 0.0
        stats.resting += 1
        if face:
            for k in (a, b):
                if bodies.simulated[k]:
                    bodies.omega[k] = (bodies.omega[k] @ n) * n
        vn, v = _approach(bodies, a, b, n, p)
        if vn >= -1e-9:
            return True
    else:
        stats.collisions += 1
    j = -(1.0 + e) * vn / (_eff(bodies, a, p, n) + _eff(bodies, b, p, n))
    _apply(bodies, a, j * n, p, 1.0)
    _apply(bodies, b, j * n, p, -1.0)
    vt = v - (n @ v) * n
    speed = float(np.linalg.norm(vt))
    if speed > 1e-9 and mu > 0:
        t = vt / speed
        stop = speed / max(_eff(bodies, a, p, t) + _eff(bodies, b, p, t), 1e-12)
        jt = min(mu * j, stop)  # Coulomb, capped where sliding would stop: never reverses it
        _apply(bodies, a, -jt * t, p, 1.0)
        _apply(bodies, b, -jt * t, p, -1.0)
    return True


def contact_rows(bodies: Bodies, cfg: ImpulseConfig, objects) -> list:
    """The contacts of ``objects`` within the margin: ``(a, b, normal, manifold point, face)`` rows."""
    world = bodies.world
    c = world.contacts(objects, first=bodies.simulated, margin=cfg.margin)
    return [(int(c.object_a[i]), int(c.object_b[i]), c.normal[i])
            + _manifold_point(world, bodies, c.piece_a[i], c.piece_b[i], c.point[i], cfg.margin)
            for i in range(len(c))]


def apply_impulses(bodies: Bodies, cfg: ImpulseConfig, stats: ImpulseStats, rows) -> int:
    """Resolve every approaching contact of ``rows`` (:func:`contact_rows`) with impulses in a priority
    queue (most negative normal velocity first); returns the number of impulses applied."""
    heap = [(_approach(bodies, a, b, n, p)[0], i) for i, (a, b, n, p, _) in enumerate(rows)]
    heapq.heapify(heap)
    count = 0
    while heap and count < cfg.max_impulses:
        vn, i = heapq.heappop(heap)
        a, b, n, p, face = rows[i]
        if vn >= -1e-9 or not _impulse(bodies, a, b, n, p, face, cfg, stats):
            continue
        count += 1
        for k, (a2, b2, n2, p2, _) in enumerate(rows):  # contacts of the bodies that changed come back
            if a2 in (a, b) or b2 in (a, b):
                v2 = _approach(bodies, a2, b2, n2, p2)[0]
                if v2 < -1e-9:
                    heapq.heappush(heap, (v2, k))
    return count


def _move(bodies: Bodies, objs, v0, dt) -> None:
    """Positions after ``dt`` with the average of the start and end velocities (exact under gravity)."""
    w = bodies.world
    pos = w.pos[objs] + 0.5 * (v0 + bodies.vel[objs]) * dt
    quats = w.quat[objs].copy()
    for i, k in enumerate(objs):
        rate = float(np.linalg.norm(bodies.omega[k]))
        if rate > 1e-12:
            q = qmul(qaxis(bodies.omega[k] / rate, rate * dt), quats[i])
            quats[i] = q / np.linalg.norm(q)
    w.set_poses(objs, pos, quats)


def step(bodies: Bodies, dt: float, cfg: ImpulseConfig, stats: ImpulseStats) -> None:
    """Advance the simulated objects by ``dt``: collisions, gravity, resting contacts, motion, and a
    stop at the time of impact when a fast object would pass into another."""
    sim = np.nonzero(bodies.simulated)[0]
    if not len(sim):
        return
    world, g = bodies.world, np.asarray(cfg.gravity, float)
    resting = cfg.resting_steps * float(np.linalg.norm(g)) * dt
    if resting > cfg.resting_speed:
        cfg = replace(cfg, resting_speed=resting)
    left = dt
    for _ in range(8):
        rows = contact_rows(bodies, cfg, sim)
        apply_impulses(bodies, cfg, stats, rows)  # collisions
        v0 = bodies.vel[sim].copy()
        p0, q0 = world.pos[sim].copy(), world.quat[sim].copy()
        bodies.vel[sim] += g * left
        apply_impulses(bodies, cfg, stats, rows)  # resting contacts against gravity
        _move(bodies, sim, v0, left)
        c = world.contacts(sim)
        if not len(c) or c.depth.max() <= cfg.toi_depth:
            return
        # time of impact: the latest fraction of the step at which nothing overlaps deeper than toi_depth
        p1 = world.pos[sim].copy()
        lo, hi = 0.0, 1.0
        for _ in range(16):
            mid = 0.5 * (lo + hi)
            world.set_poses(sim, p0 + mid * (p1 - p0), q0)
            c = world.contacts(sim)
            if len(c) and c.depth.max() > cfg.toi_depth * 0.5:
                hi = mid
            else:
                lo = mid
        world.set_poses(sim, p0 + lo * (p1 - p0), q0)
        bodies.vel[sim] = v0 + g * left * lo
        stats.toi += 1
        left *= 1.0 - lo
        if left < 1e-7:
            return


def couple(bodies: Bodies, k: int, target, target_vel, dt: float, mass: float, cfg: ImpulseConfig) -> None:
    """Equation 6 for driven object ``k``: the spring ``-K x - R x'`` toward its tracker (``target (3,)``,
    ``target_vel (3,)``) over ``dt``, integrated implicitly (stable for any K, R); moves the object."""
    w = bodies.world
    x = w.pos[k] - target
    v = bodies.vel[k] - target_vel
    kk, rr = cfg.coupling_k / mass, cfg.coupling_r / mass
    # implicit Euler on (x, v): v' = (v - dt kk x) / (1 + dt rr + dt^2 kk)
    v_new = (v - dt * kk * x) / (1.0 + dt * rr + dt * dt * kk)
    x_new = x + dt * v_new
    bodies.vel[k] = target_vel + v_new
    w.set_poses([k], target + x_new, w.quat[k])
