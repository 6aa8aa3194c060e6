"""Explain plots of a response: the error surface greys the rows no search may choose; the timeline's
stage colours are the viewer's."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.plotting import style
from kinodyn.response import plots

pytest.importorskip("matplotlib")


def test_error_surface_greys_the_rows_inside_the_shortest_transition(tmp_path):
    from PIL import Image

    z = np.zeros((30, 60))  # uniform: every row the same dark colour

    def greyish_rows(path):
        """Rows of the plot's middle column that are neither dark (the surface) nor white (margins)."""
        col = np.asarray(Image.open(path).convert("L"), dtype=float)
        col = col[:, col.shape[1] // 2 - 40]
        return np.flatnonzero((col > 130) & (col < 220)), len(col)

    plain, _ = greyish_rows(plots.error_surface(z, tmp_path / "a.png"))
    grey, h = greyish_rows(plots.error_surface(z, tmp_path / "b.png", searched_from=15))
    assert len(plain) < 10 and len(grey) > len(plain) + 60, (len(plain), len(grey))
    assert np.median(grey) > 0.4 * h, "the greyed band is the lower part of the plot (rows from 0 on)"


def test_timeline_uses_the_viewer_s_stage_colours():
    assert plots.STAGE_COLORS == tuple(style.STAGE_COLORS[n] for n in plots.STAGE_NAMES)
