"""Plots and colours in one style, for every capability: a low layer any package may import.

- :mod:`kinodyn.plotting.style`: the colours every picture shares (viewer, videos, figures).
- :mod:`kinodyn.plotting.figures`: matplotlib building blocks (phase timelines, error surfaces, scatter
  maps, time series), figure writing (atomic PNG and SVG) and pyplot without a display.

matplotlib is imported inside the functions that draw (optional dependency ``kinodyn[viz]``).
"""

from kinodyn.plotting.figures import (
    PLOT_FORMATS,
    RC,
    error_surface,
    figure,
    phase_timeline,
    pyplot,
    save,
    scatter_map,
    support_bars,
    time_series,
    write_figure,
)
from kinodyn.plotting.style import (
    CONTACT_COLOR,
    GROUND_COLOR,
    IMPACT_COLOR,
    PALETTE,
    PHASE_COLORS,
    character_colors,
    color,
    rgb,
    rgba,
)

__all__ = [
    "CONTACT_COLOR",
    "GROUND_COLOR",
    "IMPACT_COLOR",
    "PALETTE",
    "PHASE_COLORS",
    "PLOT_FORMATS",
    "RC",
    "character_colors",
    "color",
    "error_surface",
    "figure",
    "phase_timeline",
    "pyplot",
    "rgb",
    "rgba",
    "save",
    "scatter_map",
    "support_bars",
    "time_series",
    "write_figure",
]
