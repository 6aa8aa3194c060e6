"""The hold rule of support-phase synchronization: which actions hold their element so that a step is
never ``ERR`` (section 5.1, figure 9, and the construction of appendix A).

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization. From the highest priority down, the
first candidate element of type ``RS`` or ``LS`` that the previous step allows gives the constraint to
respect, and every action whose candidate is the other single support holds (:func:`resolve`).
Appendix A proves that holding the elements outside a maximal compatible set always works
(:func:`appendix_set`); the rule falls back on it, so a solution always exists and at least one action
advances. :func:`brute_force_holds` lists every solution (the tests' oracle). Pure functions of phase
codes; :mod:`kinodyn.blend.sync` keeps the state they are applied to.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations
from typing import NamedTuple

from kinodyn.errors import ParameterError
from kinodyn.phases import ERR, FLIGHT, LS, RS

__all__ = ["Resolution", "appendix_set", "brute_force_holds", "join_phases", "resolve", "step_phase"]


class Resolution(NamedTuple):
    """How one step was synchronized.

    Attributes:
        held: indices (into the inputs) of the actions that hold their last element.
        phase: the combined phase of the step.
        constraint: ``RS`` or ``LS`` when a single-support constraint was chosen, else ``None``.
        rule: ``"free"`` (no conflict), ``"priority"`` (the highest-priority compatible constraint),
            ``"other"`` (the other constraint), ``"appendix"`` (holding flight elements, appendix A).
    """

    held: tuple[int, ...]
    phase: int
    constraint: int | None
    rule: str


def join_phases(codes) -> int:
    """The phases ``codes`` combined by ``(+)`` (:data:`~kinodyn.phases.DS` for none)."""
    out = 0
    for c in codes:
        out |= c
    return out


def step_phase(old: Sequence[int], nxt: Sequence[int], held) -> int:
    """The step's combined phase when the actions ``held`` keep their ``old`` element and the others
    play their ``nxt`` one."""
    out = 0
    for i, (o, n) in enumerate(zip(old, nxt)):
        out |= o if i in held else n
    return out


def resolve(old: Sequence[int], nxt: Sequence[int], priorities: Sequence[float]) -> Resolution:
    """Choose the actions that hold their last synchronized element so that the next step is not ``ERR``.

    Args:
        old: ``(n,)`` phase codes of each action's element at the last synchronized step; their
            combination must not be ``ERR``. A starting action counts as ``DS`` (the neutral).
        nxt: ``(n,)`` phase codes of each action's next element.
        priorities: ``(n,)`` priorities, higher first; ties keep input order.

    Returns:
        A :class:`Resolution`. At least one action advances (is not held) whenever ``n > 0``, and the
        step's phase is never ``ERR``.

    Raises:
        ParameterError: ``old`` already combines to ``ERR`` or the lengths differ.
    """
    n = len(old)
    if len(nxt) != n or len(priorities) != n:
        raise ParameterError(f"old, nxt and priorities must have equal lengths, got {n}, {len(nxt)}, "
                             f"{len(priorities)}")
    prev = join_phases(old)
    if prev == ERR:
        raise ParameterError("the last synchronized step combines to ERR; it must be synchronized first")
    cand = join_phases(nxt)
    if cand != ERR:
        return Resolution((), cand, None, "free")
    # ERR: nxt holds both RS and LS and no FLIGHT. The constraint comes from the highest-priority
    # action whose next element is a single support allowed by the previous step.
    order = sorted(range(n), key=lambda i: -priorities[i])
    first = None
    for i in order:
        if nxt[i] in (RS, LS) and (nxt[i] | prev) != ERR:
            first = nxt[i]
            break
    # prev is DS, RS, LS or FLIGHT, and nxt contains both RS and LS, so `first` exists.
    tries = [(first, "priority"), (RS if first == LS else LS, "other")]
    for c, rule in tries:
        other = LS if c == RS else RS
        held = tuple(i for i in range(n) if nxt[i] == other)
        ph = step_phase(old, nxt, held)
        if ph != ERR and len(held) < n:
            return Resolution(held, ph, c, rule)
    # Appendix A: the previous step is a flight (else the first try succeeds); holding the absorbing
    # element(s) as well makes the step a flight, and some action with a candidate of type c advances.
    for c in (first, RS if first == LS else LS):
        other = LS if c == RS else RS
        held = tuple(i for i in range(n) if nxt[i] == other or old[i] == FLIGHT)
        ph = step_phase(old, nxt, held)
        if ph != ERR and len(held) < n:
            return Resolution(held, ph, c, "appendix")
    # Unreachable (see appendix_set): keep the literal construction of the proof as the last resort.
    keep = appendix_set(old, nxt)
    held = tuple(i for i in range(n) if i not in keep)
    return Resolution(held, step_phase(old, nxt, held), None, "appendix")


def appendix_set(old: Sequence[int], nxt: Sequence[int]) -> frozenset[int]:
    """The actions that advance in the proof of appendix A (the others hold their last element).

    When the previous step is a flight, holding one absorbing (flight) element is enough: every other
    action advances. Otherwise the set ``A`` is a maximal set of next elements compatible with the
    previous step's combination (equation 11), built greedily; holding the others synchronizes the
    step because held elements combine to at most the previous step's phase. ``A`` is never empty when
    the candidates conflict: they contain ``RS`` and ``LS`` and the previous step, not ``ERR``, is
    compatible with one of them.
    """
    prev = join_phases(old)
    if prev == FLIGHT:
        j = next(i for i, o in enumerate(old) if o == FLIGHT)
        return frozenset(i for i in range(len(old)) if i != j)
    keep = []
    acc = prev
    for i, c in enumerate(nxt):
        if (acc | c) != ERR:
            keep.append(i)
            acc |= c
    return frozenset(keep)


def brute_force_holds(old: Sequence[int], nxt: Sequence[int]) -> list[tuple[int, ...]]:
    """Every hold set that synchronizes the step with at least one action advancing (test oracle)."""
    n = len(old)
    out = []
    for r in range(n):
        for held in combinations(range(n), r):
            if step_phase(old, nxt, set(held)) != ERR:
                out.append(held)
    return out
