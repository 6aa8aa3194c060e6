"""Props and impacts of a physics world for the viewer, recorded while it runs.

:class:`ObjectRecorder` records the balls of a :class:`kinodyn.physics.world.World` frame by frame through
its public API (the world records its characters, not its balls, for reading back) and hands them out as
:class:`~kinodyn.viz.objects.Prop` spheres with the world's impacts as viewer overlays. World convention:
Z up, metres, seconds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from kinodyn.viz.objects import Forces, Prop
from kinodyn.viz.world import Impact

__all__ = ["ObjectRecorder"]


@dataclass
class ObjectRecorder:
    """Records a physics world's balls while it runs (mutable: it appends a row per frame).

    Uses the public API of :class:`kinodyn.physics.world.World` only: ``projectiles`` (their
    ``position``, ``radius`` and ``active``), ``time``, ``step`` and ``impacts``. Step the world
    through :meth:`step` / :meth:`run`, or call :meth:`sample` after each of your own ``world.step()``.

    Example::

        rec = ObjectRecorder(world)
        rec.run(3.0)
        html.write("hit.html", walker.trajectory(), ["contacts", *rec.overlays(["walker"])])
    """

    world: object
    times: list = field(default_factory=list)
    rows: list = field(default_factory=list)

    def sample(self) -> None:
        """Record the current positions of the balls (inactive ones as NaN)."""
        self.times.append(float(self.world.time))
        self.rows.append([p.position if p.active else np.full(3, np.nan) for p in self.world.projectiles])

    def step(self, frames: int = 1) -> None:
        if not self.times:
            self.sample()
        for _ in range(int(frames)):
            self.world.step()
            self.sample()

    def run(self, seconds: float) -> None:
        self.step(round(seconds * self.world.config.fps))

    def props(self, color: str = "#8c6d4f") -> list[Prop]:
        """One sphere :class:`Prop` a ball, over the frames it was in play (after its launch)."""
        out = []
        if not self.times:
            return out
        fps = self.world.config.fps
        for k, p in enumerate(self.world.projectiles):
            track = np.array([row[k] if k < len(row) else np.full(3, np.nan) for row in self.rows])
            live = np.nonzero(np.all(np.isfinite(track), axis=1))[0]
            if len(live) == 0:
                continue
            a, b = live[0], live[-1] + 1
            seg = track[a:b]
            gaps = ~np.all(np.isfinite(seg), axis=1)
            if gaps.any():  # parked between two throws: hold the last position
                for i in np.nonzero(gaps)[0]:
                    seg[i] = seg[i - 1]
            out.append(Prop("sphere", seg, (float(p.radius),), fps=fps, start=self.times[a], color=color,
                            label=p.name, hide_outside=True))
        return out

    def overlays(self, characters: Sequence[str] = (), forces: bool = False) -> list:
        """Props of the balls plus the world's impacts as viewer overlays.

        Args:
            characters: names of the characters in the order they are given to the page, so that each
                impact is tied to its character's index.
            forces: also draw each impact's mean contact force as a :class:`Forces` arrow.
        """
        out: list = list(self.props())
        index = {n: i for i, n in enumerate(characters)}
        for imp in self.world.impacts:
            char = index.get(imp.character)
            out.append(Impact(imp.time, np.asarray(imp.point), np.asarray(imp.impulse), char,
                              f"{imp.source} -> {imp.body}"))
            if forces and imp.duration > 0:
                out.append(Forces([imp.time], [imp.point], [np.asarray(imp.impulse) / imp.duration],
                                  hold=max(imp.duration, 0.1), character=char, label=imp.body))
        return out
