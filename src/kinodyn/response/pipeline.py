"""The dynamic-response pipeline (dynamic response, sections 3 and 6, figure 2).

1. The character plays its base motion kinematically in a :class:`kinodyn.physics.World`.
2. At the impact (a thrown ball, a push, another character's punch) the world switches it to simulation
   from the motion's state; its PD servos keep tracking the interrupted motion.
3. At the end of the classification window (``classify_s`` after contact) the reaction clip and its
   timing are chosen. The timing needs the simulation further on, so a lookahead copy of the world,
   started from the current state, simulates ``horizon_s`` more seconds still tracking the interrupted
   motion (the paper's "rewind": the original world is never stepped back). Choice: exhaustive search
   over every clip, or a classifier's clip plus the fast alignment (or its few most probable clips, each
   aligned, the lowest error D chosen: ``ResponseConfig.candidates``).
4. From then on the servos track a slerp blend with ease-in/ease-out weights from the interrupted motion
   to the chosen clip, which reaches the clip's matched frame at the matched simulation frame (6.1).
5. Over that transition, root position (linear), root orientation and joint rotations (slerp) of the
   simulated frames are blended into the clip placed at the matched frame, with the same weights (6.2);
   from there the clip plays kinematically.

The output is one continuous :class:`~kinodyn.motion.Motion` plus :class:`Stages`, the frame ranges of
motion data, simulation, transition and clip. Uses :mod:`kinodyn.physics` through its public API and
:func:`kinodyn.math.quat.slerp` for the blends.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from kinodyn.errors import MotionError, ParameterError, SimulationError
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.response.align import AlignConfig, fast_align
from kinodyn.response.search import body_tracks, exhaustive, windows

__all__ = ["Attacker", "Ball", "Observation", "Push", "Response", "ResponseConfig", "Stages", "check_inputs",
           "ease_weights", "eieo", "fast_choice", "fast_errors", "label", "label_search", "looped", "observe",
           "ranked", "recover", "respond"]


@dataclass(frozen=True)
class Ball:
    """A ball thrown at the character (section 7.2).

    Attributes:
        speed: launch speed (m/s).
        direction: horizontal heading of travel (rad, world frame; 0 flies along +X).
        height: launch height (m).
        target: landmark aimed at (``chest``, ``head``, ``pelvis``, ``stomach``, ...).
        mass, radius: kg, m.
        time: world time (s) the ball is timed to arrive.
        aim: optional ``(x, y, z)`` world point the ball flies at instead of the landmark (it may miss).
        distance: horizontal distance (m) from the aim point at launch.
    """

    speed: float = 9.0
    direction: float = np.pi
    height: float = 1.5
    target: str = "chest"
    mass: float = 4.0
    radius: float = 0.11
    time: float = 1.0
    aim: tuple | None = None
    distance: float = 2.0

    def __post_init__(self):
        if not (self.speed > 0 and self.mass > 0 and self.radius > 0 and self.time > 0 and self.distance > 0):
            raise ParameterError(f"ball speed, mass, radius and time must be > 0, got {self}")


@dataclass(frozen=True)
class ResponseConfig:
    """Timing of the response (seconds) and how the clip is chosen.

    Attributes:
        classify_s: simulation after contact before the clip and timing are chosen (0.1 s in the paper).
        horizon_s: lookahead simulated for the timing search.
        min_transition_s: shortest transition from the choice to the clip.
        settle_s: how long the contact is watched for after ``Ball.time`` before the ball counts as a miss.
        tail_s: clip time played after the transition (None: the rest of the clip).
        align: :class:`AlignConfig` of the fast alignment.
        candidates: how many of the classifier's most probable clips the fast alignment times; the one
            whose timing has the lowest error D is chosen. 1 is the paper's pipeline (the classifier's
            clip); each further candidate costs one more alignment.
    """

    classify_s: float = 0.1
    horizon_s: float = 0.6
    min_transition_s: float = 0.25
    settle_s: float = 0.4
    tail_s: float | None = None
    align: AlignConfig = AlignConfig()
    candidates: int = 1

    def __post_init__(self):
        if isinstance(self.candidates, bool) or not isinstance(self.candidates, (int, np.integer)) \
                or self.candidates < 1:
            raise ParameterError(f"candidates must be a whole number >= 1, got {self.candidates!r}")
        if not (self.classify_s >= 0 and self.min_transition_s > 0
                and self.horizon_s > self.classify_s + self.min_transition_s and self.settle_s > 0):
            raise ParameterError("need classify_s >= 0, min_transition_s > 0, settle_s > 0 and horizon_s > "
                                 f"classify_s + min_transition_s; got {self}")


@dataclass(frozen=True)
class Stages:
    """Frame ranges ``[start, stop)`` of each stage in the output motion. The simulation ends with the
    frame the choice is made in; the transition starts with the first frame the blended target drives."""

    motion: tuple[int, int]
    simulation: tuple[int, int]
    transition: tuple[int, int]
    clip: tuple[int, int]

    def labels(self) -> np.ndarray:
        """``(F,)`` stage index per frame: 0 motion data, 1 simulation, 2 transition, 3 clip."""
        out = np.zeros(self.clip[1], dtype=np.int64)
        for k, (a, b) in enumerate((self.motion, self.simulation, self.transition, self.clip)):
            out[a:b] = k
        return out


@dataclass(frozen=True)
class Response:
    """A computed response.

    Attributes:
        motion: the whole output (motion data, simulation, transition, clip), at the world's fps.
        stages: :class:`Stages`.
        clip: name of the chosen reaction clip; clip_index its index in the library.
        sim_frame, clip_frame: the matched frames (simulation frames counted from the impact).
        error: error D at the match.
        impact_time: world time of the contact; impulse ``(3,)`` N s received.
        simulated: the raw simulated frames (impact to the end of the transition) as a Motion.
        lookahead: the lookahead simulation the timing was searched on (a Motion).
        features: the simulation states at the classification samples, for the classifier.
        probabilities: the classifier's class probabilities (None for the exhaustive choice).
        candidates: ``((clip index, error D), ...)`` the clips the fast alignment timed, most probable
            first (``ResponseConfig.candidates`` of them; empty for the exhaustive choice).
        interrupted: the base motion as it would have played on, over the output's frames up to the
            end of the transition (the reference a reaction is judged against).
        hits: the :class:`kinodyn.physics.Impact` records the character received (time, body, point,
            impulse, source), for the viewer's impact arrows.
    """

    motion: Motion
    stages: Stages
    clip: str
    clip_index: int
    sim_frame: int
    clip_frame: int
    error: float
    impact_time: float
    impulse: np.ndarray
    simulated: Motion
    lookahead: Motion
    features: tuple
    probabilities: np.ndarray | None = None
    interrupted: Motion | None = None
    hits: tuple = ()
    candidates: tuple = ()


def eieo(u) -> np.ndarray:
    """Ease-in/ease-out weight ``(...)`` for normalized time ``u`` in [0, 1]: ``(1 - cos(pi u)) / 2``."""
    u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * u)


def ease_weights(n: int) -> np.ndarray:
    """``(n,)`` EIEO weights over ``n`` frames, 0 at the first and 1 at the last."""
    return eieo(np.linspace(0.0, 1.0, n)) if n > 1 else np.ones(max(n, 0))


def check_inputs(base: Motion, library) -> None:
    """Raise a kinodyn error unless ``base`` can play against ``library``: a non-empty library of the base's
    skeleton and frame rate."""
    if len(library) == 0:
        raise ParameterError("the reaction library is empty")
    if not base.skeleton.same_topology(library.skeleton):
        raise MotionError(f"the base motion's skeleton ({base.skeleton.num_joints} joints) is not the reaction "
                          f"library's ({library.skeleton.num_joints} joints)")
    if abs(base.fps - library.fps) > 1e-9:
        raise MotionError(f"the base motion is at {base.fps:g} fps and the library at {library.fps:g}; resample")


def looped(base: Motion, seconds: float) -> Motion:
    """``base`` repeated end to end (each repetition moved on the floor) to last at least ``seconds``."""
    out = base
    while out.duration < seconds:
        out = out.concatenate(base)
    return out


@dataclass(frozen=True)
class Push:
    """An impulsive push (N s, world frame) on a body (``chest``, ``pelvis``, ...) at world time ``time``."""

    impulse: tuple = (0.0, -120.0, 0.0)
    body: str = "chest"
    time: float = 1.0


@dataclass(frozen=True)
class Attacker:
    """Another character whose clip (a punch, a push) hits the responding one.

    Attributes:
        motion: the attacker's clip (same skeleton and fps as the base motion), played kinematically; it
            ignores the contact and finishes its clip.
        at: ``(x, y, heading)`` ground transform of the attacker's first frame.
        contact_s, max_impulse: the blow stays in contact until it has passed ``max_impulse`` N s (a
            strong punch passes 10-30) or for ``contact_s`` seconds; then the attacker's bodies stop
            colliding (a kinematic fist has unlimited mass and would keep driving into the body).
    """

    motion: Motion
    at: tuple = (0.0, 0.0, 0.0)
    contact_s: float = 0.1
    max_impulse: float = 25.0


_BODIES: dict = {}


def _body(skeleton):
    """The physics body of ``skeleton``, built once per process (bodies are immutable once built)."""
    from kinodyn.physics import build_body

    key = (skeleton.names, skeleton.parents.tobytes(), skeleton.offsets.tobytes())
    if key not in _BODIES:
        _BODIES[key] = build_body(skeleton)
    return _BODIES[key]


def _world(skeleton, fps: float, base_track: Motion, impact, lookahead_of=None):
    """The world of a response: the responding character (``hit``) playing ``base_track``, the attacker
    if any; for a lookahead copy (``lookahead_of`` = the original world) the same bodies, the hit
    character left dynamic and the attacker playing on from the original's time."""
    from kinodyn.physics import World, WorldConfig

    w = World(WorldConfig(fps=fps))
    hit = w.add_character(_body(skeleton), name="hit")
    other = None
    if isinstance(impact, Attacker):
        other = w.add_character(_body(skeleton), name="attacker")
        other.on_impact = "ignore"
        start = 0.0 if lookahead_of is None else min(lookahead_of.time, impact.motion.duration)
        other.play(_placed(impact), start=start)
    if isinstance(impact, Ball):
        w.add_projectile(impact.mass, impact.radius)
    if lookahead_of is None:
        hit.play(base_track)
    else:
        w.set_state(lookahead_of.get_state())
    return w, hit, other


def _impulse(world, hit) -> np.ndarray:
    """``(3,)`` total impulse (N s) the character ``hit`` has received so far."""
    imps = [i.impulse for i in world.impacts if i.character == hit.name]
    return np.sum(imps, axis=0) if imps else np.zeros(3)


def _release(world, other) -> None:
    """Stop the attacker's bodies colliding with anything (MuJoCo ``contype``/``conaffinity`` of its geoms)."""
    world.model.geom_contype[other.geom_ids] = 0
    world.model.geom_conaffinity[other.geom_ids] = 0


def _placed(att: Attacker) -> Motion:
    return att.motion.aligned_to(np.asarray(att.at, dtype=np.float64), 0)


def _strike(world, hit, impact, cfg: ResponseConfig) -> int:
    """Deliver the impact and step until the character is hit; returns the impact's frame."""
    fps = world.config.fps
    if isinstance(impact, Ball) and impact.aim is None:
        world.throw(hit, impact.target, impact.mass, impact.radius, impact.speed, impact.direction, impact.height,
                    distance=impact.distance, at=impact.time, projectile=world.projectiles[0])
        deadline = impact.time + cfg.settle_s
    elif isinstance(impact, Ball):
        from kinodyn.physics import launch

        start, vel, flight = launch(np.asarray(impact.aim, dtype=np.float64), impact.speed, impact.direction,
                                    impact.height, impact.distance)
        if flight > impact.time:
            raise ParameterError(f"the ball's flight takes {flight:.2f} s, longer than its arrival time "
                                 f"{impact.time:.2f} s")
        world.run(impact.time - flight)
        world.projectiles[0].set_state(start, vel)
        deadline = impact.time + cfg.settle_s
    elif isinstance(impact, Push):
        world.run(impact.time)
        world.push(hit, impact.body, np.asarray(impact.impulse, dtype=np.float64))
        deadline = impact.time
    elif isinstance(impact, Attacker):
        deadline = impact.motion.duration
    else:
        raise ParameterError(f"impact must be a Ball, a Push or an Attacker, got {type(impact).__name__}")
    while hit.mode == "kinematic" and world.time < deadline - 1e-9:
        world.step()
    if hit.mode == "kinematic":
        raise ParameterError(f"the {type(impact).__name__.lower()} missed the character: no contact by "
                             f"t = {deadline:.2f} s ({impact})")
    return int(round(hit.switch_time * fps))


def _blend_into(sim: Motion, clip: Motion, w: np.ndarray) -> Motion:
    """Frames of ``sim`` blended into ``clip`` (same length ``n``) with weights ``w (n,)`` (6.2): root
    position linearly, root and joint rotations by slerp."""
    rp = sim.root_pos * (1.0 - w[:, None]) + clip.root_pos * w[:, None]
    lr = quat.slerp(sim.local_rot, clip.local_rot, w[:, None])
    return sim.replace(root_pos=rp, local_rot=lr)


def _target(base: Motion, clip: Motion, fm: int, n: int, tail: int) -> Motion:
    """Servo target from the choice on (6.1): ``n`` frames easing from ``base`` into ``clip`` so that the
    last one is clip frame ``fm``, then ``tail`` more clip frames."""
    k = np.clip(fm - (n - 1) + np.arange(n), 0, clip.num_frames - 1)
    lr = quat.slerp(base.local_rot[:n], clip.local_rot[k], ease_weights(n)[:, None])
    after = clip.local_rot[np.clip(fm + 1 + np.arange(tail), 0, clip.num_frames - 1)]
    rp = np.concatenate([base.root_pos[:n], np.repeat(base.root_pos[n - 1:n], tail, axis=0)])
    return base.replace(root_pos=rp, local_rot=np.concatenate([lr, after]), name="transition target")


def ranked(probabilities, first: int, n: int) -> np.ndarray:
    """The ``n`` most probable clip indices by ``probabilities (K,)``, ``first`` (the classifier's choice)
    leading, then the others by falling probability (ties by index)."""
    order = np.argsort(-np.asarray(probabilities, dtype=np.float64), kind="stable")
    return np.concatenate([[first], order[order != first]])[:n].astype(np.int64)


def fast_choice(track, library, select, features, config: ResponseConfig = ResponseConfig()):
    """The fast path's choice on a simulated segment's body tracks ``track`` ``(pos, rot)``: the
    classifier's ``config.candidates`` most probable clips (``select(features) -> (clip, probabilities)``),
    each timed by the fast alignment, the lowest error D chosen (the most probable on a tie).

    Returns ``(clip, AlignResult, probabilities, ((clip, error D), ...) timed, most probable first)``.
    """
    k, probs = select(features)
    if config.candidates > 1 and probs is None:
        raise ParameterError(f"candidates={config.candidates} ranks clips by the classifier's probabilities, "
                             "and this classifier gives none (a plain SVC); calibrate it or use candidates=1")
    clips = ranked(probs, int(k), config.candidates) if config.candidates > 1 else [int(k)]
    timed = [(int(c), fast_align(None, track, library, int(c), config.align)) for c in clips]
    k, a = min(timed, key=lambda t: t[1].error)
    return k, a, probs, tuple((c, float(t.error)) for c, t in timed)


def _searched(lookahead: Motion, library, skip: int) -> tuple[np.ndarray, np.ndarray]:
    """The body tracks ``(pos, rot)`` of the lookahead from frame ``skip`` on, where a clip's timing is
    searched (checked to hold one search window)."""
    pos, rot = body_tracks(lookahead)
    if len(pos) - skip < library.window:
        raise ParameterError(f"horizon_s leaves fewer frames than the {library.window}-frame search window")
    return pos[skip:], rot[skip:]


def _skip(config: ResponseConfig, fps: float) -> int:
    """Lookahead frames before the earliest clip frame a transition may reach (``min_transition_s``)."""
    return max(1, int(round(config.min_transition_s * fps)))


def _choose(lookahead: Motion, library, skip: int, select, features, cfg: ResponseConfig):
    """Clip and timing on the lookahead simulation (frames from ``skip`` on): exhaustive, or the fast
    path (:func:`fast_choice`). Returns ``(clip, sim_frame, clip_frame, error, probabilities, timed)``."""
    pos, rot = _searched(lookahead, library, skip)
    if select is None:
        r = exhaustive(windows(pos, rot, library.window), library)
        return r.clip, r.sim_frame + skip, r.clip_frame, r.error, None, ()
    k, a, probs, timed = fast_choice((pos, rot), library, select, features, cfg)
    return k, int(round(a.sim_frame)) + skip, int(round(a.clip_frame)), a.error, probs, timed


def _states(world, hit, times) -> list:
    from kinodyn.physics import character_state

    out = []
    for t in times:
        while world.time < t - 1e-9:
            world.step()
        out.append(character_state(world, hit))
    return out


@dataclass
class Observation:
    """What the pipeline knows at the end of the classification window (mutable: holds the world).

    Attributes:
        world, hit: the world (stopped at ``choice_frame``) and the responding character.
        track: the base motion looped, as played from world frame 0.
        impact_frame, choice_frame: world frames of the contact and of the end of the classification window.
        states: :class:`kinodyn.physics.CharacterState` at the feature times after contact.
        lookahead: the lookahead simulation from ``choice_frame`` on (a Motion).
    """

    world: object
    hit: object
    track: Motion
    impact_frame: int
    choice_frame: int
    states: tuple
    lookahead: Motion


def observe(base: Motion, impact, config: ResponseConfig = ResponseConfig(),
            feature_times=(0.0, 0.1, 0.2)) -> Observation:
    """Stages 1-3 up to the choice: play ``base``, deliver ``impact``, simulate the classification window,
    sample the states at ``feature_times`` after contact, and simulate the lookahead on a copy."""
    if not isinstance(impact, (Ball, Push, Attacker)):
        raise ParameterError(f"impact must be a Ball, a Push or an Attacker, got {type(impact).__name__}")
    fps = base.fps
    classify = max(config.classify_s, max(feature_times))
    t_end = (impact.time if not isinstance(impact, Attacker) else impact.motion.duration) + config.settle_s
    track = looped(base, t_end + classify + config.horizon_s + 0.1)
    world, hit, other = _world(base.skeleton, fps, track, impact)
    c = _strike(world, hit, impact, config)
    if other is not None:
        t_stop = world.time + impact.contact_s
        while world.time < t_stop - 1e-9 and np.linalg.norm(_impulse(world, hit)) < impact.max_impulse:
            world.step()
        _release(world, other)
    states = _states(world, hit, [c / fps + t for t in feature_times])
    t0 = c + int(round(classify * fps))
    while round(world.time * fps) < t0:
        world.step()
    # Lookahead on a copy of the world from now: the timing search needs the simulation further on.
    ahead, ahead_hit, ahead_other = _world(base.skeleton, fps, track, impact, lookahead_of=world)
    if ahead_other is not None:
        _release(ahead, ahead_other)
    n_ahead = int(round(config.horizon_s * fps))
    ahead.track(ahead_hit, track[t0:t0 + n_ahead + 2])
    ahead.step(n_ahead)
    return Observation(world, hit, track, c, t0, tuple(states), ahead.trajectory(ahead_hit))


def label_search(obs: Observation, library, config: ResponseConfig = ResponseConfig()):
    """The exhaustive search of an observation's lookahead (:class:`kinodyn.response.search.SearchResult`,
    ``sim_frame`` counted from the choice frame), with every clip's best error D in ``per_clip``."""
    skip = _skip(config, obs.world.config.fps)
    r = exhaustive(windows(*_searched(obs.lookahead, library, skip), library.window), library)
    return replace(r, sim_frame=r.sim_frame + skip)


def fast_errors(obs: Observation, library, config: ResponseConfig = ResponseConfig()) -> np.ndarray:
    """``(K,)`` the error D of every clip's timing found by the fast alignment on an observation's
    lookahead (what a choice among the classifier's candidates compares, for every clip at once)."""
    track = _searched(obs.lookahead, library, _skip(config, obs.world.config.fps))
    return np.array([fast_align(None, track, library, c, config.align).error for c in range(len(library))])


def label(obs: Observation, library, config: ResponseConfig = ResponseConfig()):
    """The exhaustive choice for an observation: ``(clip, sim_frame, clip_frame, error)`` with
    ``sim_frame`` counted from the choice frame (the training label of section 7.2)."""
    r = label_search(obs, library, config)
    return r.clip, r.sim_frame, r.clip_frame, r.error


def respond(base: Motion, library, impact=Ball(), select=None, config: ResponseConfig = ResponseConfig(),
            feature_times=(0.0, 0.1, 0.2)) -> Response:
    """Play ``base`` (looped) until ``impact`` hits, simulate the reaction and return to a library clip.

    Args:
        base: the motion the character plays before the impact (walk, idle, a fighting stance); same
            skeleton and fps as the library.
        library: a :class:`kinodyn.response.library.ReactionLibrary`.
        impact: a :class:`Ball`, :class:`Push` or :class:`Attacker`.
        select: ``select(states) -> (clip index, probabilities)`` (a trained classifier); ``None`` runs
            the exhaustive search over every clip instead (the quality reference).
        config: :class:`ResponseConfig`.
        feature_times: seconds after contact at which the states handed to ``select`` are sampled
            (the classification window must cover them).

    Raises:
        ParameterError: empty library, a ball that misses, an impact of unknown kind.
        MotionError: base and library of different skeletons or frame rates.
        SimulationDivergedError: the physics blew up.
    """
    check_inputs(base, library)
    obs = observe(base, impact, config, feature_times)
    world, hit, track, c, t0, states, lookahead = (obs.world, obs.hit, obs.track, obs.impact_frame, obs.choice_frame,
                                                   obs.states, obs.lookahead)
    fps = base.fps
    skip = _skip(config, fps)
    k, fs, fm, err, probs, timed = _choose(lookahead, library, skip, select, states, config)
    clip = library.clip(k)
    # 6.1: from the choice on, track the ease-in/ease-out blend into the clip.
    tail = clip.num_frames if config.tail_s is None else int(round(config.tail_s * fps))
    world.track(hit, _target(track[t0:], clip, fm, fs + 1, 2))
    world.step(fs)
    sim = world.trajectory(hit)
    t1 = t0 + fs
    if sim.num_frames != t1 + 1:
        raise SimulationError(f"expected {t1 + 1} recorded frames, found {sim.num_frames}")
    # 6.2: blend the simulated transition into the clip placed at the matched frame; then the clip plays.
    placed = clip.aligned_to(sim.ground()[t1], fm)
    k_idx = np.clip(fm - fs + np.arange(fs + 1), 0, clip.num_frames - 1)
    trans = _blend_into(sim[t0:t1 + 1], placed[k_idx], ease_weights(fs + 1))
    rest = placed[fm + 1:min(clip.num_frames, fm + 1 + tail)]
    out = sim[:t0].concatenate(trans, align=False, drop_first=False)
    if rest.num_frames:
        out = out.concatenate(rest, align=False, drop_first=False)
    out = out.replace(name=f"{base.name} -> {clip.name}")
    # Frame t0 is the state the choice is made in, simulated under the interrupted motion's target (the
    # blend's weight is 0 there): the simulation's last frame. The transition is what the blended target
    # drives, from t0 + 1.
    stages = Stages((0, c), (c, t0 + 1), (t0 + 1, t1 + 1), (t1 + 1, out.num_frames))
    impulse = _impulse(world, hit)
    hits = tuple(i for i in world.impacts if i.character == hit.name)
    return Response(out, stages, clip.name, k, fs, fm, float(err), c / fps, impulse, sim[c:], lookahead,
                    states, probs, track[:t1 + 1], hits, timed)


def recover(motion: Motion, clip: str, then="idle", blend_s: float = 0.4) -> Motion:
    """A fallen character gets up: ``motion`` (whose last frame is the last frame of the built-in fall
    ``clip``, as a :class:`Response` that played its clip to the end) followed by the fall's get-up
    (:data:`kinodyn.data.library.GET_UP`, starting in the pose the fall ends in) and then ``then`` (a
    built-in clip name or a Motion, default ``"idle"``), eased in from the get-up's last pose over
    ``blend_s`` seconds (the same ease-in/ease-out slerp as the transition of 6.2).

    Raises:
        ParameterError: ``clip`` has no get-up, or ``blend_s`` is negative.
        MotionError: ``motion`` or ``then`` is not on the built-in skeleton at its frame rate.
    """
    from kinodyn.data import library as data

    if clip not in data.GET_UP:
        raise ParameterError(f"no get-up follows clip {clip!r}; falls with a get-up: {', '.join(data.GET_UP)}")
    if not blend_s >= 0:
        raise ParameterError(f"blend_s must be >= 0 seconds, got {blend_s}")
    getup = data.load(data.GET_UP[clip])
    nxt = data.load(then) if isinstance(then, str) else then
    for m, what in ((motion, "motion"), (nxt, "then")):
        if not m.skeleton.same_topology(getup.skeleton) or abs(m.fps - getup.fps) > 1e-9:
            raise MotionError(f"{what} must be on the built-in skeleton at {getup.fps:g} fps, got "
                              f"{m.skeleton.num_joints} joints at {m.fps:g} fps")
    out = motion.concatenate(getup, align=True, drop_first=True)
    placed = nxt.aligned_to(out.ground()[-1], 0)
    n = min(placed.num_frames, int(round(blend_s * getup.fps)) + 1)
    if n > 1:
        held = out[-1:].replace(root_pos=np.repeat(out.root_pos[-1:], n, 0),
                                local_rot=np.repeat(out.local_rot[-1:], n, 0))
        head = _blend_into(held, placed[:n], ease_weights(n))
        placed = head.concatenate(placed[n:], align=False, drop_first=False) if placed.num_frames > n else head
    return out.concatenate(placed, align=False, drop_first=True).replace(name=f"{motion.name} -> {getup.name} -> "
                                                                                f"{nxt.name}")
