"""Chronological organization of support phases: the synchronization of section 5.1 and appendix A.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 5.1. Every active action's
sequence is referred to one global step index ``k`` (the change of variable of figure 7): at step
``k`` action ``i`` plays element ``e_i(k)`` of its extended sequence, and ``e_i`` grows by one element
per step, or by none when the element is *enlarged* (held for one more step). Steps up to the
frontier ``k + nk`` are synchronized: the combination ``(+)_i S_i(e_i(s))`` is never ``ERR``. Each time
the animation enters a new step, one more step is synchronized; when the candidate elements are
incompatible, some actions hold their last synchronized element. Which ones is decided by priority:
from the highest priority down, the first candidate element of type ``RS`` or ``LS`` that the previous
step allows gives the constraint to respect, and every action whose candidate is the other single
support holds (figure 9). Appendix A proves that holding the elements outside a maximal compatible
set always works; the rule below falls back on it, so a solution always exists and at least one
action advances.

A new action first tries to fit its elements ``0 .. nk-1`` into the steps ``k .. k + nk - 1`` as they
are; when one of them is incompatible, its start waits for the next step (the paper). After
``max_start_delay`` such waits it joins the frontier like a running action whose current element is
``DS`` (the neutral pose's phase), so the appendix guarantee covers starts too and no start waits
forever unless it can never be satisfied by the rule (it then keeps waiting, reported in the log).
An element much longer than the others' is also held for tempo (:attr:`SyncConfig.tempo_hold`).

The hold rule itself (pure functions of phase codes) is :mod:`kinodyn.blend.holds`. The synchronizer is
the one mutable object of this module (it is real-time state): it knows only the elements' own durations
(for tempo holds), not real time; :mod:`kinodyn.blend.timewarp` gives steps their durations. Steps are
integers; element indices are integers of the extended sequences (:meth:`PhaseSequence.element`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from kinodyn.blend.holds import Resolution, join_phases, resolve
from kinodyn.errors import ParameterError
from kinodyn.phases import DS, ERR, FLIGHT, LS, RS, PhaseSequence, phase_name

#: Steps of nominal durations kept behind the current one (elements held longer see only these).
NOMINAL_KEPT = 256

__all__ = ["SyncConfig", "SyncEvent", "Synchronizer", "Track"]


@dataclass(frozen=True)
class SyncConfig:
    """Parameters of the synchronization.

    Attributes:
        nk: number of elements synchronized ahead of the current one (the paper's default, 5, covers
            more than a locomotion cycle).
        max_start_delay: steps a new action waits for a direct fit before it joins at the frontier
            through the hold rule (which always finds a solution).
        phase_match: a *cyclic* action may start at any element of its cycle: the one whose next
            ``nk`` elements best match the running steps (the same single support, or double support /
            flight against double support / flight) among those that fit. The paper starts every action
            at its first element; with compatibility alone a run may start with its flight over a
            walk's single support (FLIGHT absorbs), which blends a planted foot with a swinging one.
        tempo_hold: an element whose own duration is over this many times the *nominal* time its
            steps have lasted so far is held for one more step (enlarged) when holding it conflicts
            with no other action's next element, so that one element of a slow cycle spans several of
            a fast one (a walk's single support over a run's support and flight) instead of both being
            warped to one step, at 0.26x and 2.7x (0: never). A step's nominal duration: the least time
            an action has left in its element (at its speed); the warp splits held elements by it.
            Between cyclic actions, or of a standing non-cyclic action (its double support, as a walk
            starts over a kick's end; the kick's start takes the walk out, see the mixer's closing step).
    """

    nk: int = 5
    max_start_delay: int = 4
    phase_match: bool = True
    tempo_hold: float = 2.5

    def __post_init__(self):
        if not isinstance(self.nk, int) or self.nk < 1:
            raise ParameterError(f"nk must be an integer >= 1, got {self.nk!r}")
        if not isinstance(self.max_start_delay, int) or self.max_start_delay < 0:
            raise ParameterError(f"max_start_delay must be an integer >= 0, got {self.max_start_delay!r}")
        if not (self.tempo_hold == 0 or (self.tempo_hold >= 1 and self.tempo_hold < float("inf"))):
            raise ParameterError(f"tempo_hold must be 0 (off) or a finite ratio >= 1, got {self.tempo_hold!r}")


# ----------------------------------------------------------------------------------------- the state


@dataclass(eq=False)
class Track:
    """An action as the synchronizer sees it (mutable).

    Attributes:
        key: the caller's identifier.
        seq: the action's (adapted) support-phase sequence.
        priority: higher wins.
        first: step at which ``elems[0]`` is played; ``None`` while the start is pending.
        elems: element index at steps ``first, first + 1, ...`` up to the frontier.
        end: first step the action no longer takes part in (``None``: not scheduled).
        waited, forced: steps the start has waited so far; it joins at the frontier by the hold rule.
        leaving: removal asked for; the action leaves at the first frontier step that allows it.
        not_before: the start is not tried before this step (``None``: from the next one on).
    """

    key: object
    seq: PhaseSequence
    priority: float
    first: int | None = None
    elems: list[int] = field(default_factory=list)
    end: int | None = None
    waited: int = 0
    forced: bool = False
    leaving: bool = False
    not_before: int | None = None

    def __post_init__(self):
        self._codes = [int(x) for x in self.seq.phases]
        self._n = len(self._codes)
        self._cyclic = self.seq.cyclic
        self._bounds = [float(x) for x in self.seq.bounds]
        self._period = self.seq.total
        self._dlast = float(self.seq.durations[-1])

    def span(self, e: int) -> tuple[float, float]:
        """Extended-sequence times ``(t0, t1)`` of element ``e`` (fast :meth:`PhaseSequence.element`)."""
        n = self._n
        b = self._bounds
        if self._cyclic:
            c, i = divmod(e, n)
            off = c * self._period
            return b[i] + off, b[i + 1] + off
        if e < n:
            return b[e], b[e + 1]
        t0 = b[n] + (e - n) * self._dlast
        return t0, t0 + self._dlast

    def code(self, e: int) -> int:
        """Phase code of extended element ``e`` (-1: the virtual DS before the start)."""
        if e < 0:
            return DS
        if self._cyclic:
            return self._codes[e % self._n]
        return self._codes[e if e < self._n else self._n - 1]

    def elem(self, step: int) -> int | None:
        """Element played at ``step``, or ``None`` when the action is not in that step."""
        if self.first is None or step < self.first or (self.end is not None and step >= self.end):
            return None
        j = step - self.first
        return self.elems[j] if j < len(self.elems) else None

    @property
    def last(self) -> int | None:
        """Last synchronized step of this action."""
        return None if self.first is None or not self.elems else self.first + len(self.elems) - 1


class SyncEvent(NamedTuple):
    """A log entry: ``kind`` in ``start``, ``wait``, ``force``, ``hold``, ``remove``, ``leaving``."""

    step: int
    kind: str
    key: object
    detail: str


class Synchronizer:
    """The real-time state of section 5.1 for one character (mutable; the caller drives it).

    Usage: :meth:`request` a start (it is tried when the next step is entered, or at once when nothing
    plays), :meth:`enter_next` whenever the animation crosses a step boundary, :meth:`remove` an
    action that has finished fading out. :attr:`phases`: each synchronized step's combined phase;
    :attr:`current`: the step played; :attr:`frontier`: the last synchronized one; :attr:`nominal`:
    each step's nominal duration (s of action time, see :attr:`SyncConfig.tempo_hold`).
    """

    def __init__(self, config: SyncConfig = SyncConfig(), log: bool = True):
        self.config = config
        self.current = 0
        self.frontier = -1
        self.tracks: list[Track] = []
        self.pending: list[Track] = []
        self.phases: dict[int, int] = {}
        self.nominal: dict[int, float] = {}
        self.events: list[SyncEvent] = []
        self.resolutions: list[tuple[int, Resolution, tuple]] = []
        self.dirty: int | None = None  # earliest step whose elements changed since the timing was planned
        self._log = log

    # ------------------------------------------------------------------ queries
    @property
    def idle(self) -> bool:
        """Nothing is planned: the next request starts at once."""
        return not self.tracks

    def active(self, step: int | None = None) -> list[Track]:
        """Tracks taking part in ``step`` (default: the current step)."""
        return [t for t in self.tracks if t.elem(self.current if step is None else step) is not None]

    def phase(self, step: int) -> int:
        return self.phases.get(step, DS)

    # ------------------------------------------------------------------ commands
    def request(self, key, seq: PhaseSequence, priority: float = 0.0, not_before: int | None = None) -> Track:
        """Ask for an action to start (while others play, not before step ``not_before`` when given);
        returns its :class:`Track` (``first`` is set once it starts)."""
        if any(t.key == key for t in self.tracks + self.pending):
            raise ParameterError(f"an action with key {key!r} is already known to the synchronizer")
        t = Track(key, seq, float(priority), not_before=not_before)
        if self.idle and not self.pending:  # nothing plays: a fresh step starts now with this action
            self.current += 1
            self._start_at(t, self.current, reset=True)
            self._sync_frontier()
        else:
            self.pending.append(t)
        return t

    def split(self, played: float) -> bool:
        """End the current step now, ``played`` s of action time into it, when one action plays alone:
        it holds its element into a new next step (its later steps move one on, the frontier stays),
        so that a start need not wait for the end of a long element. Returns whether it did."""
        k, t = self.current, self.tracks[0] if len(self.tracks) == 1 else None
        if t is None or t.end is not None or t.leaving or t.elem(k) is None or self.frontier <= k:
            return False
        t.elems.insert(k - t.first + 1, t.elem(k))
        t.elems.pop()
        for s in range(self.frontier - 1, k - 1, -1):
            self.phases[s + 1] = self.phases[s]
        self.nominal[k] = played
        for s in range(k + 1, self.frontier + 1):
            self.nominal[s] = self._nominal_at(s)
        self._mark(k + 1)
        return True

    def cancel(self, key) -> bool:
        """Drop a pending start; True when one was dropped."""
        n = len(self.pending)
        self.pending = [t for t in self.pending if t.key != key]
        return len(self.pending) != n

    def remove(self, key, from_step: int | None = None) -> int | None:
        """The action stops taking part from ``from_step`` on (default: the next step; at the earliest the
        current one). Returns the step it leaves at.

        Removing an action relaxes its own constraints, but a flight element absorbs conflicts between
        the others (FLIGHT (+) ERR = FLIGHT): the removal is put off to the first step from which every
        synchronized step stays free of ``ERR`` without it. When there is none, the action is marked
        *leaving*: from the frontier on its candidate element is ``DS`` (the neutral) and it leaves at
        the first frontier step where the hold rule does not hold it (returns ``None`` then).
        """
        if self.cancel(key):  # a pending start
            return None
        s0 = self.current + 1 if from_step is None else max(int(from_step), self.current)
        t = next((x for x in self.tracks if x.key == key), None)
        if t is None:
            raise ParameterError(f"no action with key {key!r} in the synchronizer")
        if t.end is not None and t.end <= s0:
            return t.end
        others = [x for x in self.tracks if x is not t]
        without = {step: join_phases(x.code(x.elem(step)) for x in others if x.elem(step) is not None)
                   for step in range(s0, self.frontier + 1)}
        s = s0
        while s <= self.frontier and any(without[j] == ERR for j in range(s, self.frontier + 1)):
            s += 1
        if s > self.frontier:  # the frontier sync lets it go as soon as the others allow
            t.leaving = True
            self._note(s, "leaving", key, f"a flight element hides a conflict from step {s0} on")
            return None
        t.end = s
        self._mark(s)
        del t.elems[max(0, s - t.first):]
        for step in range(s, self.frontier + 1):
            self.phases[step] = without[step]
            self.nominal[step] = self._nominal_at(step)
        self._note(s, "remove", key, "" if s == s0 else f"put off from step {s0} (a flight hid a conflict)")
        return s

    def enter_next(self) -> None:
        """The animation enters step ``current + 1``: try pending starts, then synchronize one more step."""
        self.current = k = self.current + 1
        self.tracks = [t for t in self.tracks if t.end is None or t.end > k]
        for s in [s for s in self.phases if s < k - 1]:
            del self.phases[s]
        if len(self.nominal) > NOMINAL_KEPT:
            for s in [s for s in self.nominal if s < k - NOMINAL_KEPT // 2]:
                del self.nominal[s]
        if not self.tracks:
            self.frontier = max(self.frontier, k - 1)
            if self.pending:  # nothing plays: the first pending action starts at once
                t = self.pending.pop(0)
                t.forced = False
                self._start_at(t, k, reset=True)
        self._try_starts(k)
        if self.tracks or self.pending:
            self._sync_frontier()

    # ------------------------------------------------------------------ internals
    def _mark(self, step: int) -> None:
        self.dirty = step if self.dirty is None else min(self.dirty, step)

    def _note(self, step: int, kind: str, key, detail: str) -> None:
        if self._log:
            self.events.append(SyncEvent(step, kind, key, detail))

    def _start_at(self, t: Track, k: int, reset: bool = False, first_elem: int = 0) -> None:
        """Lay elements ``e0 .. e0+nk-1`` at steps ``k .. k+nk-1`` (the frontier sync adds step ``k+nk``).

        A cyclic action joining cyclic ones or standing ones (non-cyclic, double supports from ``k``
        on), ``reset`` False, has only ``e0`` laid at ``k``: the steps after it are synchronized again
        one by one (:meth:`_sync_frontier`), so that tempo holds can spread a long element over the
        others'. Otherwise (or while an action is being removed, or one joined at a later step) the
        newcomer's elements are laid straight.
        """
        nk = self.config.nk
        t.first = k
        self._mark(k)
        self.tracks.append(t)
        self._note(k, "start", t.key, f"after {t.waited} waits")
        others = [x for x in self.tracks if x is not t]
        if (reset or self.config.tempo_hold <= 0 or not t.seq.cyclic
                or not all(x.seq.cyclic or {x.code(e) for e in x.elems[k - x.first:]} == {DS} for x in others)
                or any(x.end is not None or x.leaving or x.first > k for x in others)):
            t.elems = list(range(first_elem, first_elem + nk))
            if reset:
                self.frontier = k + nk - 1
            for j in range(nk):
                self.phases[k + j] = (DS if reset else self.phases.get(k + j, DS)) | t.code(first_elem + j)
            for s in range(k, self.frontier + 1):
                self.nominal[s] = self._nominal_at(s)
            return
        t.elems = [first_elem]
        target = self.frontier
        for x in others:
            del x.elems[k - x.first + 1:]
        for s in [s for s in self.phases if s > k]:
            del self.phases[s]
        self.phases[k] = self.phases.get(k, DS) | t.code(first_elem)
        self.nominal[k] = self._nominal_at(k)
        self.frontier = k
        while self.frontier < target:
            self._sync_frontier()

    def _left_in(self, t: Track, step: int) -> float:
        """Action time ``t`` has left in its element at the start of ``step`` (nominally)."""
        j = step - t.first
        e = t.elems[j]
        t0, t1 = t.span(e)
        left = t1 - t0
        while (j := j - 1) >= 0 and t.elems[j] == e:
            left -= self.nominal.get(t.first + j, 0.0)
        return left

    def _nominal_at(self, step: int) -> float:
        """Nominal duration of ``step``: the least time left to an action there (else the least element)."""
        best = spans = float("inf")
        for t in self.tracks:
            e = t.elem(step)
            if e is None:
                continue
            if (left := self._left_in(t, step)) > 1e-9:
                best = min(best, left)
            spans = min(spans, t.span(e)[1] - t.span(e)[0])
        return max(best if best < float("inf") else (spans if spans < float("inf") else 0.0), 1e-9)

    def _tempo_holds(self, movers, joiners, old_e, nxt) -> set[int]:
        """Movers that hold their element for tempo (:attr:`SyncConfig.tempo_hold`): every action of
        the step is cyclic or stands (a non-cyclic action's double support; then only that is held),
        the element's duration is over ``tempo_hold`` times the nominal time its steps have lasted, and
        holding it meets no other action's next single support of the other foot. ``nxt`` is updated
        in place."""
        ratio = self.config.tempo_hold
        stand = [not t.seq.cyclic for t in movers]
        if (ratio <= 0 or len(nxt) < 2 or all(stand) or not all(t.seq.cyclic for t in joiners)
                or any(s and t.code(e) != DS for s, t, e in zip(stand, movers, old_e))):
            return set()
        f = self.frontier
        want = []
        for i, t in enumerate(movers):
            if t.leaving or (any(stand) and not stand[i]):
                continue
            t0, t1 = t.span(old_e[i])
            spent = (t1 - t0) - self._left_in(t, f) + self.nominal.get(f, 0.0)
            if t1 - t0 > ratio * max(spent, 1e-9):
                want.append(((t1 - t0) / max(spent, 1e-9), i))
        held: set[int] = set()
        for _, i in sorted(want, reverse=True):
            c = movers[i].code(old_e[i])
            others = [nxt[j] for j in range(len(nxt)) if j != i]
            if (join_phases(others) | c) == ERR or len(held) + 1 >= len(nxt):
                continue
            held.add(i)
            nxt[i] = c
        return held

    def _try_starts(self, k: int) -> None:
        nk = self.config.nk
        for t in list(self.pending):
            if t.forced or (t.not_before is not None and k < t.not_before):
                continue
            e0 = self._best_start(t, k)
            if e0 is not None:
                self.pending.remove(t)
                self._start_at(t, k, first_elem=e0)  # the frontier sync below extends its plan
                continue
            t.waited += 1
            if t.waited > self.config.max_start_delay:
                t.forced = True
                self._note(k, "force", t.key, "joins at the frontier through the hold rule")
            else:
                self._note(k, "wait", t.key, f"incompatible with steps {k}..{k + nk - 1}")

    def _best_start(self, t: Track, k: int) -> int | None:
        """First element for ``t`` starting at step ``k`` (``None``: no element fits; see phase_match)."""
        nk = self.config.nk
        cands = range(len(t.seq)) if (t.seq.cyclic and self.config.phase_match) else (0,)
        best, best_score = None, -1
        for e0 in cands:
            score = 0
            for j in range(nk):
                p = self.phases.get(k + j, DS)
                c = t.code(e0 + j)
                if (p | c) == ERR:
                    score = -1
                    break
                if p == c and c in (RS, LS):
                    score += 2
                elif p in (DS, FLIGHT) and c in (DS, FLIGHT):
                    score += 1
            if score > best_score:
                best, best_score = e0, score
        return best

    def _sync_frontier(self) -> None:
        f = self.frontier + 1
        prev = f - 1
        movers, old_e = [], []
        for t in self.tracks:
            if t.first is None or (t.end is not None and t.end <= f):
                continue
            j = prev - t.first
            if 0 <= j < len(t.elems):
                movers.append(t)
                old_e.append(t.elems[j])
        joiners = [t for t in self.pending if t.forced]
        tracks = movers + joiners
        if not tracks:
            self.phases[f] = DS
            self.frontier = f
            return
        old_e += [-1] * len(joiners)
        old = [t.code(e) for t, e in zip(tracks, old_e)]
        nxt = [DS if t.leaving else t.code(e + 1) for t, e in zip(tracks, old_e)]
        tempo = self._tempo_holds(movers, joiners, old_e, nxt)
        res = resolve(old, nxt, [t.priority for t in tracks])
        held = set(res.held) | tempo
        for i, t in enumerate(movers):
            if t.leaving and i not in held:
                t.end = f
                self._note(f, "remove", t.key, "left at the frontier")
                continue
            if i in held:  # the enlarged element's whole run is re-split in time
                j = len(t.elems) - 1
                while j > 0 and t.elems[j - 1] == old_e[i]:
                    j -= 1
                self._mark(t.first + j)
                t.elems.append(old_e[i])
            else:
                t.elems.append(old_e[i] + 1)
        for j, t in enumerate(joiners):
            if len(movers) + j in held:
                t.waited += 1
                continue
            self.pending.remove(t)
            t.first = f
            t.elems = [0]
            self._mark(f)
            self.tracks.append(t)
            self._note(f, "start", t.key, f"forced after {t.waited} waits")
        self.phases[f] = res.phase
        self.frontier = f
        self.nominal[f] = self._nominal_at(f)
        if tempo:
            self._note(f, "hold", tuple(tracks[i].key for i in sorted(tempo)), "tempo")
        if res.held:
            self.resolutions.append((f, res, tuple(t.key for t in tracks)))
            self._note(f, "hold", tuple(tracks[i].key for i in res.held),
                       f"{phase_name(res.constraint) if res.constraint is not None else '-'} kept ({res.rule})")
