"""The per-character state of the mixer: actions, synchronizer, warp planner and slot arrays.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, sections 3 and 5. Every character
runs its own :class:`~kinodyn.blend.sync.Synchronizer` and :class:`~kinodyn.blend.timewarp.WarpPlanner`
(with synchronization): actions start at a step boundary, their support phases are organized so that
no step mixes a left and a right single support, and each action's time is warped to the common steps.
An action stopped while another waits for its synchronized start hands over: it plays on until the
newcomer starts, then fades out. Without synchronization actions start when asked and play at their
own speed.

The mixer evaluates all characters at once from :class:`Slots`, arrays ``(N, S, ...)`` over ``N``
characters and ``S`` action slots; each :class:`Character` writes its own row, in Python, only when one
of its steps ends or on a command.
"""

from __future__ import annotations

import math

import numpy as np

from kinodyn.blend.actions import ActionState
from kinodyn.blend.sync import Synchronizer
from kinodyn.blend.timewarp import WarpPlanner
from kinodyn.errors import ParameterError, UnknownNameError
from kinodyn.phases import DS

__all__ = ["CLOSING_DELAY", "Character", "Slots"]

#: Seconds an action fading into the neutral pose may play on so that it ends with a closing step.
CLOSING_DELAY = 1.0
#: Candidate moments (1/60 s of action time apart) searched for a closing step.
CLOSING_SAMPLES = 240


class Slots:
    """The slot arrays of ``N`` characters with ``S`` action slots each (mutable; row ``n`` belongs to
    character ``n``).

    Attributes:
        clip, speed, prio: ``(N, S)`` clip index, time scaling and priority of each slot's action.
        ramp: ``(N, S, 4)`` ``(t_on, ramp_in, t_off, ramp_out)``; ``inf`` when not started / stopped.
        seg: ``(N, S, 6)`` the current warp segment ``(t0, t1, c0..c3)`` (see
            :func:`kinodyn.blend.weights.mix_weights`).
        prev_tau, prev_g, prev_cyc: ``(N, S)``, ``(N, S, 3)``, ``(N, S)`` clip time, ground transform
            and loops played at the previous frame (the root motion is their difference).
        fresh: ``(N, S)`` the slot's action is new (no previous frame).
        keys: per character, the action key of each slot (``None``: empty).
        count: ``(N,)`` occupied slots; ``next``: ``(N,)`` time of each character's next step entry.
    """

    def __init__(self, n_characters: int, n_slots: int):
        N, S = n_characters, n_slots
        self.n_slots = S
        self.clip = np.zeros((N, S), dtype=np.int64)
        self.speed = np.ones((N, S))
        self.prio = np.zeros((N, S))
        self.ramp = np.tile(np.array([math.inf, 0.0, math.inf, 0.0]), (N, S, 1))
        self.seg = np.tile(np.array([0.0, math.inf, 0.0, 0.0, 0.0, 0.0]), (N, S, 1))
        self.prev_tau = np.zeros((N, S))
        self.prev_g = np.zeros((N, S, 3))
        self.prev_cyc = np.zeros((N, S), dtype=np.int64)
        self.count = np.zeros(N, dtype=np.int64)
        self.fresh = np.ones((N, S), dtype=bool)
        self.keys = [[None] * S for _ in range(N)]
        self.next = np.full(N, math.inf)


class Character:
    """The state of one character of a mixer: its actions, synchronizer, warp planner and slot arrays
    (mutable; the mixer drives it).

    Args:
        index: the character's row in ``slots``.
        slots: the mixer's :class:`Slots`; the character owns row ``index`` of every array (views), the
            mixer reads them all at once every frame.
        store: the :class:`~kinodyn.clips.ClipStore` its actions play from.
        sequences: each clip's :class:`~kinodyn.phases.PhaseSequence`.
        config: the mixer's :class:`~kinodyn.blend.mixer.BlendConfig`.
        keep_log: keep the synchronizer's events and the planner's warp history (for analysis).
    """

    def __init__(self, index: int, slots: Slots, store, sequences, config, keep_log: bool = False):
        self.index = index
        self.store = store
        self.sequences = sequences
        self.config = cfg = config
        self.n_slots = slots.n_slots
        n = index
        # this character's rows of the slot arrays (views: writes are seen by the batched evaluation)
        self.clip, self.speed, self.prio = slots.clip[n], slots.speed[n], slots.prio[n]
        self.ramp, self.seg = slots.ramp[n], slots.seg[n]
        self.prev_tau, self.prev_g, self.prev_cyc = slots.prev_tau[n], slots.prev_g[n], slots.prev_cyc[n]
        self.fresh, self.keys = slots.fresh[n], slots.keys[n]
        self.count, self.next = slots.count[n:n + 1], slots.next[n:n + 1]
        self.actions: dict[object, ActionState] = {}
        self.order: list[object] = []           # slot order: priority desc, then start order
        self.sync = Synchronizer(cfg.sync, log=keep_log) if cfg.synchronize else None
        self.planner = (WarpPlanner(self.sync, self.weights_at, cfg.warp, keep_history=keep_log)
                        if cfg.synchronize else None)
        self.counter = 0
        self.weights_valid_until = math.inf
        self._wcache = None
        self.history: dict[object, ActionState] = {}   # every action ever started (for analysis)
        self.neutral_feet = None  # (2, 2) the neutral pose's feet (set by the mixer; closing steps)
        self.closing: dict[object, object] = {}  # the cycle an in-place action closes (_closing_start)

    # ------------------------------------------------------------------ weights (scalar, for planning)
    def weights_at(self, t: float) -> dict:
        """Leg weights ``P_i`` of equation 6 at time ``t``: the share of the legs each action would have
        by its priority if it were fully active, given the others' activations at ``t``.

        Higher priority levels take their (capped) summed activation first; within its level an action
        counts itself as fully active. So actions of one priority share equally, an action overridden
        by a fully active higher level does not set the tempo, and a new action of higher priority
        imposes its timing from its first step (weighting by its ramped blend weight instead would
        squeeze its first elements into the running action's timing while it fades in). Pure Python:
        it runs once per planned step.
        """
        state = [(a.t_on, a.t_off) for a in self.actions.values()]
        c = self._wcache
        if c is not None and c[0] == state and (c[1] <= t < c[2] or t == c[1]):
            self.weights_valid_until = c[2]
            return c[3]
        out = self._weights(t)
        self._wcache = (state, t, self.weights_valid_until, out)
        return out

    def _weights(self, t: float) -> dict:
        acts = [a for a in self.actions.values() if a.t_on is not None and a.t_on <= t + 1e-9 and not a.gone(t)]
        # the weights stay the same until the next ramp event (a start, the end of a ramp, a stop)
        until = math.inf
        for a in self.actions.values():
            on, ri, off, ro = a.weight_params()
            if on < t < on + ri or off < t < off + ro:  # mid-ramp: the weights change continuously
                until = t
                break
            for e in (on, on + ri, off, off + ro):
                if t + 1e-9 < e < until:
                    until = e
        self.weights_valid_until = until
        if not acts:
            return {}
        if len(acts) == 1:
            return {acts[0].key: 1.0}
        level: dict[float, float] = {}
        act = {}
        for a in acts:
            on, ri, off, ro = a.weight_params()
            x = 1.0 if ri <= 0 else min(max((t - on) / ri, 0.0), 1.0)
            up = x * x * (3.0 - 2.0 * x)
            y = 0.0 if off == math.inf else (1.0 if ro <= 0 else min(max((t - off) / ro, 0.0), 1.0))
            act[a.key] = up * (1.0 - y * y * (3.0 - 2.0 * y))
            level[a.priority] = level.get(a.priority, 0.0) + act[a.key]
        out = {}
        for a in acts:
            free = 1.0
            for p, s in level.items():
                if p > a.priority:
                    free *= max(0.0, 1.0 - min(1.0, s))
            out[a.key] = free / (1.0 + level[a.priority] - act[a.key])
        return out

    # ------------------------------------------------------------------ commands
    def start(self, key, clip: int, speed: float, priority: float, ramp_in: float, ramp_out: float,
              auto_stop: bool, now: float):
        if key in self.actions:
            raise ParameterError(f"character {self.index} already has an action {key!r}")
        if len(self.actions) >= self.config.max_actions:
            raise ParameterError(f"character {self.index} already plays {len(self.actions)} actions "
                                 f"(max_actions={self.config.max_actions}); stop one first")
        seq = self.sequences[clip].time_scaled(speed)
        cyclic = bool(self.store.is_cyclic[clip])
        a = ActionState(key, clip, seq, speed, priority, ramp_in, ramp_out, now, auto_stop=auto_stop and not cyclic,
                        h0=seq.element(0)[1], end_h=(self.store.duration(clip) / speed) if not cyclic else math.inf)
        a.order = self.counter
        self.counter += 1
        self.actions[key] = a
        self.history[key] = a
        if self.sync is None:
            a.t_on = now
            if a.auto_stop:
                a.t_off = max(now, now + (a.end_h - a.h0) - a.ramp_out)
        else:
            was_idle = self.sync.idle and not self.sync.pending
            self.sync.request(key, seq, priority, not_before=None if was_idle else self._closing_start(a, now))
            if was_idle:
                a.t_on = now
                self.planner.start(now)
                self._auto_stops(now)
            elif len(self.sync.tracks) == 1:  # a lone action stands to its end: start at the next frame
                tr = self.sync.tracks[0]
                if not tr.seq.cyclic and {tr.code(e) for e in tr.elems[self.sync.current - tr.first:]} == {DS}:
                    self.planner.split(now)
        self._layout()

    def stop(self, key, now: float):
        a = self.actions.get(key)
        if a is None:
            raise UnknownNameError(f"character {self.index} has no action {key!r}; it has: "
                                   f"{', '.join(map(str, self.actions)) or 'none'}")
        if a.t_on is None:  # still waiting for synchronization: never started
            self.sync.cancel(key)
            del self.actions[key]
            if not self.sync.pending:
                for b in list(self.actions.values()):
                    if b.handover:
                        self.stop(b.key, now)
            self._layout()
            return
        if self.sync is not None and a.t_off is None and self.sync.pending and not a.handover:
            a.handover = True   # fades out when the waiting action starts (see ActionState.handover)
            return
        if a.t_off is None or a.t_off > now:
            a.t_off = self._closing_stop(a, now)
            a.handover = False
            if self.planner is not None:
                self.planner.replan()
            self._write_segments()

    def _closing_stop(self, a: ActionState, now: float) -> float:
        """When ``a`` fades into the neutral pose (no other action keeps playing), the time its fade-out
        begins: delayed (up to :data:`CLOSING_DELAY` seconds) so that its weight passes one half when its
        feet stand where the neutral pose's do, relative to the root (:meth:`_feet_of`): the neutral pose
        (both feet down) then plants them there, a closing step, rather than holding them where the
        action left them (:attr:`~kinodyn.blend.mixer.BlendConfig.closing_step`). ``now`` when that is
        off, without synchronization, while another action plays, or beyond the planned steps."""
        if (self.planner is None or self.sync.pending or not self.config.closing_step
                or self.neutral_feet is None):
            return now
        if any(b is not a and (b.t_on is None or b.t_off is None or b.t_off > now) for b in self.actions.values()):
            return now  # another action waits or plays on (an auto-stopped one until its planned stop)
        half = 0.5 * a.ramp_out
        hs, ts = self._planned(a, now, CLOSING_DELAY + half)
        ok = ts - half >= now
        if not ok.any():
            return now
        feet = self._feet_of(a, hs[ok])
        best = int(np.argmin(np.linalg.norm(feet - self.neutral_feet, axis=-1).sum(axis=-1)))
        return float(ts[ok][best] - half)

    def _closing_start(self, new: ActionState, now: float) -> int | None:
        """The first step at which ``new``, an in-place action (non-cyclic, its first element a double
        support lasting half its ramp-in or more: a jump's crouch, a kick's stance), may start while a
        locomotion cycle of no higher priority plays (``None``: the next one, as any start): the one of
        the planned steps within :data:`CLOSING_DELAY` from which, over ``new``'s ramp-in (a quarter,
        half and three quarters into it, both at their own speed), the cycle's feet best match
        ``new``'s first frames, relative to the root. The cycle plays on at its own speed until then;
        at the start it leaves the synchronizer and plays on, at its speed, while it fades
        (:meth:`_closed`), so its stride closes there (the swing foot lands beside the stance foot) as
        in a stop's closing step (:meth:`_closing_stop`), and ``new`` plays at its own speed from its
        first frame."""
        seq = new.seq
        if (not self.config.closing_step or self.neutral_feet is None or seq.cyclic
                or int(seq.phases[0]) != DS or float(seq.durations[0]) < 0.5 * new.ramp_in):
            return None
        runs = [b for b in self.actions.values() if b is not new and b.t_on is not None and b.t_off is None
                and self.store.is_cyclic[b.clip] and b.priority <= new.priority]
        if not runs:
            return None
        weights = self.weights_at(now)
        run = max(runs, key=lambda b: weights.get(b.key, 0.0))
        half = 0.5 * new.ramp_in
        hs, ts = self._planned(run, now, CLOSING_DELAY + half)
        T = self.planner.T
        steps = [k for k in range(self.sync.current + 1, self.sync.frontier + 1)
                 if k in T and len(ts) > 1 and ts[0] <= T[k] and T[k] + 1.5 * half <= ts[-1]
                 and T[k] <= now + CLOSING_DELAY]
        if not steps:
            return None
        us = np.array([0.5, 1.0, 1.5]) * half  # a quarter, half and three quarters into the fade
        feet = self._feet_of(run, np.interp([T[k] + u for k in steps for u in us], ts, hs))
        feet = feet.reshape(len(steps), len(us), 2, 2)
        goal = self._feet_of(new, new.h0 + us)
        self.closing[new.key] = run.key
        return steps[int(np.argmin(np.linalg.norm(feet - goal, axis=-1).sum(axis=(-1, -2))))]

    def _closed(self, new: ActionState, tk: float) -> None:
        """``new`` started at ``tk`` at a closing step (:meth:`_closing_start`): the cycle it closes
        leaves the synchronizer (from the current step) and plays on at its own speed from its action
        time at ``tk`` (:attr:`ActionState.free`) while it fades out, from ``tk`` (a hand-over's stop
        sets that in :meth:`advance`; a cycle stopped before ``tk`` keeps its earlier stop)."""
        run = self.actions.get(self.closing.pop(new.key, None))
        tm = None if run is None else self.planner.timing.get(run.key)
        if tm is None or tm.current is None or run.free is not None:
            return
        seg = tm.current
        u = min(max(tk - seg.t0, 0.0), seg.t1 - seg.t0)
        c = seg.coef
        run.free = (tk, ((c[3] * u + c[2]) * u + c[1]) * u + c[0])
        if not run.handover:  # a hand-over fades out from tk (below, in advance)
            run.t_off = min(tk, math.inf if run.t_off is None else run.t_off)
        self.sync.remove(run.key, self.sync.current)

    def _planned(self, a: ActionState, now: float, within: float) -> tuple[np.ndarray, np.ndarray]:
        """``(hs, ts)``: action times of ``a`` every 1/60 s from ``now`` on, and the planned real times
        it reaches them, as far as the plan reaches within ``within`` seconds (empty: not playing)."""
        tm = self.planner.timing.get(a.key)
        seg = None if tm is None else tm.current
        if seg is None or not seg.t0 <= now <= seg.t1:
            return np.zeros(0), np.zeros(0)
        c = seg.coef
        u = now - seg.t0
        h_now = ((c[3] * u + c[2]) * u + c[1]) * u + c[0]
        hs = h_now + np.arange(1, int(CLOSING_SAMPLES)) / 60.0
        ts = []
        for h in hs:
            t = self.planner.time_of(a.key, float(h))
            if t is None or t > now + within:
                break
            ts.append(t)
        return hs[:len(ts)], np.array(ts)

    def _feet_of(self, a: ActionState, hs) -> np.ndarray:
        """``(M, 2, 2)`` horizontal positions of the lowest points of the left and right foot of action
        ``a`` at action times ``hs (M,)``, in its facing frame with the root at the origin."""
        from kinodyn import contacts
        from kinodyn.motion import Motion

        clip = np.full(len(hs), a.clip)
        rot, z = self.store.sample(clip, np.asarray(hs) * a.speed)[:2]
        root = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)
        pts = contacts.foot_points(Motion(self.store.skeleton, root, rot, 60.0))
        low = [p[np.arange(len(p)), p[..., 2].argmin(axis=1), :2] for p in (pts["left"], pts["right"])]
        return np.stack(low, axis=1)

    # ------------------------------------------------------------------ time
    def next_event(self) -> float:
        if self.sync is None:
            ends = [a.t_off + a.ramp_out for a in self.actions.values() if a.t_off is not None]
            return min(ends) if ends else math.inf
        gone = min((a.t_off + a.ramp_out for a in self.actions.values() if a.free is not None), default=math.inf)
        if self.sync.idle:
            return gone
        return min(gone, self.planner.T.get(self.sync.current + 1, math.inf))

    def advance(self, t: float):
        """Enter every step that begins at or before ``t``."""
        if self.sync is None:
            for k in [k for k, a in self.actions.items() if a.gone(t)]:
                del self.actions[k]
            self._layout()
            return
        guard = 0
        sync = self.sync
        planner = self.planner
        actions = self.actions
        done = [key for key, a in actions.items() if a.free is not None and a.gone(t)]
        for key in done:  # a freed cycle has faded out
            del actions[key]
        changed = bool(done)
        while sync.tracks and planner.T.get(sync.current + 1, math.inf) <= t:
            guard += 1
            if guard > 10_000:
                raise ParameterError("time warp produced degenerate steps")
            tk = planner.T[sync.current + 1]
            gone = [key for key, a in actions.items()
                    if a.t_on is not None and a.t_off is not None and tk >= a.t_off + a.ramp_out and a.free is None]
            for key in gone:
                sync.remove(key, sync.current + 1)
            sync.enter_next()
            k = sync.current
            if len(sync.tracks) + len(sync.pending) != len(actions):
                live = {tr.key for tr in sync.tracks}
                for key in [key for key, a in actions.items()
                            if a.t_on is not None and key not in live and (a.free is None or a.gone(tk))]:
                    del actions[key]
                    changed = True
            if not sync.tracks:
                break
            started = handed = False
            for tr in sync.tracks:
                if tr.first == k:
                    a = actions[tr.key]
                    if a.t_on is None:
                        a.t_on = tk
                        changed = started = True
                        if tr.key in self.closing:
                            self._closed(a, tk)
            if started and not sync.pending:
                for a in actions.values():
                    if a.handover:
                        a.handover = False
                        if a.t_off is None:
                            a.t_off = tk
                            handed = True
            planner.enter()
            if handed:
                planner.replan()
            changed |= self._auto_stops(tk)
        if changed or self.sync.idle:
            self._layout()
        else:
            self._write_steps()

    def _auto_stops(self, now: float) -> bool:
        changed = False
        for a in self.actions.values():
            if a.auto_stop and a.t_off is None and a.t_on is not None:
                te = self.planner.time_of(a.key, a.end_h)
                if te is not None:
                    a.t_off = max(now, te - a.ramp_out)
                    self.planner.replan()
                    changed = True
        return changed

    # ------------------------------------------------------------------ slot arrays
    def _layout(self):
        self.order = sorted(self.actions, key=lambda k: (-self.actions[k].priority, self.actions[k].order))
        self._write_segments()

    def _write_steps(self):
        """After a step entry with the same actions: only the warp segments and the next boundary change."""
        planner = self.planner
        k = self.sync.current
        T = planner.T
        tk = T.get(k)
        timing = planner.timing
        order = self.order
        on = self.ramp[:len(order), 0].tolist()
        rows = []
        for s, key in enumerate(order):
            tm = timing.get(key)
            seg = None if tm is None or self.actions[key].free is not None else tm.current
            if seg is not None and seg.t1 > seg.t0 and on[s] != math.inf and seg.t0 == tk:
                rows.append((seg.t0, seg.t1) + seg.coef)
            else:
                self._write_segments()
                return
        if rows:
            self.seg[:len(rows)] = rows
        self.next[0] = T.get(k + 1, math.inf)  # next_event() while the synchronizer plays

    def _write_segments(self):
        """Write every slot of this character (after its actions or their order changed)."""
        S = self.n_slots
        sync = self.sync
        k = None if sync is None else sync.current
        tracks = None if sync is None else {x.key: x for x in sync.tracks}
        order = self.order
        L = len(order)
        clip, speed, prio, seg, ramp = [], [], [], [], []
        for key in order:
            a = self.actions[key]
            clip.append(a.clip)
            speed.append(a.speed)
            prio.append(a.priority)
            on, ri, off, ro = a.weight_params()
            if sync is None or a.free is not None:
                t0, h0 = (a.t_on, a.h0) if a.free is None else a.free
                seg.append((t0, math.inf, h0, 1.0, 0.0, 0.0))
            else:
                tr = tracks.get(a.key)
                if tr is None or tr.elem(k) is None:
                    on = math.inf  # waiting: no weight
                    seg.append((0.0, math.inf, a.h0, 0.0, 0.0, 0.0))
                else:
                    sg = self.planner.segment(a.key)
                    seg.append((sg.t0, sg.t1) + sg.coef)
            ramp.append((on, ri, off, ro))
        keys = self.keys
        new_keys = [self.actions[key].key for key in order] + [None] * (S - L)
        if keys != new_keys:  # slots changed hands: carry each action's sampling state to its new slot
            prev = {keys[s]: (self.prev_tau[s], self.prev_g[s].copy(), self.prev_cyc[s], self.fresh[s])
                    for s in range(S) if keys[s] is not None}
            for s in range(S):
                key = new_keys[s]
                if key is None:
                    keys[s] = None
                elif keys[s] != key:
                    keys[s] = key
                    if key in prev:
                        self.prev_tau[s], self.prev_g[s], self.prev_cyc[s], self.fresh[s] = prev[key]
                    else:
                        self.fresh[s] = True
        self.count[0] = L
        if L:
            self.clip[:L] = clip
            self.speed[:L] = speed
            self.prio[:L] = prio
            self.seg[:L] = seg
            self.ramp[:L] = ramp
        if L < S:
            self.ramp[L:] = (math.inf, 0.0, math.inf, 0.0)
            self.seg[L:] = (0.0, math.inf, 0.0, 0.0, 0.0, 0.0)
        self.next[0] = self.next_event()

