"""One visual style for every picture kinodyn makes: the viewer, videos and plots share these colours.

Colours are hex strings (``"#4e79a7"``). Characters take :data:`PALETTE` colours in order; support phases
use :data:`PHASE_COLORS`, keyed by the labels of Multon et al. (support-phase synchronization, section 4:
``LS`` left support, ``RS`` right support, ``DS`` double support, ``FLIGHT`` no foot on the ground,
``ERR`` a conflict); they are :data:`kinodyn.phases.PHASE_COLORS` by name, so every picture agrees.
"""

from __future__ import annotations

import re

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.phases import PHASE_COLORS as _PHASE_COLORS_BY_CODE
from kinodyn.phases import phase_name

__all__ = [
    "CONTACT_COLOR",
    "GROUND_COLOR",
    "HIGHLIGHT_COLOR",
    "IMPACT_COLOR",
    "PALETTE",
    "PHASE_COLORS",
    "PHASE_LABELS",
    "STAGE_COLORS",
    "character_colors",
    "color",
    "rgb",
    "rgba",
]

#: Character colours (Tableau 10): distinct, colour-blind friendly, readable on a light ground.
PALETTE = ("#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7",
           "#9c755f", "#bab0ac")

#: Label of each support-phase code (:class:`kinodyn.phases.Phase`) in the bars coloured by :data:`PHASE_COLORS`.
PHASE_LABELS = {code: phase_name(code) for code in _PHASE_COLORS_BY_CODE}
#: Support-phase colours by label (:data:`kinodyn.phases.PHASE_COLORS`, keyed by :data:`PHASE_LABELS`).
PHASE_COLORS = {phase_name(code): col for code, col in _PHASE_COLORS_BY_CODE.items()}

#: Stage colours of a character's timeline (what drives it: the dynamic response fills these).
STAGE_COLORS = {"motion data": "#76b7b2", "simulation": "#b07aa1", "transition": "#edc948", "clip": "#9c755f"}

CONTACT_COLOR = "#f2b705"  #: foot-contact markers
IMPACT_COLOR = "#d62728"  #: impact points and impulse arrows
HIGHLIGHT_COLOR = "#e8112d"  #: highlighted segments (inside an obstacle)
GROUND_COLOR = "#f4f1ea"  #: the floor

_HEX = re.compile(r"^#?([0-9a-fA-F]{6})$")


def color(c) -> str:
    """Normalise a colour to ``"#rrggbb"``: a hex string, a matplotlib-style name known to the palette
    (``"C0"`` .. ``"C9"``), or an RGB triple of floats in [0, 1]."""
    if isinstance(c, str):
        m = _HEX.match(c.strip())
        if m:
            return "#" + m.group(1).lower()
        if re.fullmatch(r"C\d", c):
            return PALETTE[int(c[1:]) % len(PALETTE)]
        raise ParameterError(f"colour must be '#rrggbb', 'C0'..'C9' or an RGB triple, got {c!r}")
    a = np.asarray(c, dtype=np.float64).ravel()
    if a.shape not in ((3,), (4,)) or not np.all((a >= 0) & (a <= 1)):
        raise ParameterError(f"colour must be '#rrggbb', 'C0'..'C9' or an RGB triple in [0, 1], got {c!r}")
    return "#" + "".join(f"{round(v * 255):02x}" for v in a[:3])


def rgb(c) -> np.ndarray:
    """``(3,)`` float RGB in [0, 1] of a colour."""
    h = color(c)
    return np.array([int(h[i:i + 2], 16) / 255.0 for i in (1, 3, 5)])


def rgba(c, alpha: float = 1.0) -> np.ndarray:
    """``(4,)`` float32 RGBA in [0, 1] of a colour."""
    return np.append(rgb(c), alpha).astype(np.float32)


def character_colors(n: int, given=None) -> list[str]:
    """``n`` colours: ``given`` where set (a list, ``None`` entries take the palette), else the palette."""
    out = [PALETTE[i % len(PALETTE)] for i in range(n)]
    if given is not None:
        given = list(given)
        if len(given) != n:
            raise ParameterError(f"colors must have one entry per character ({n}), got {len(given)}")
        out = [out[i] if g is None else color(g) for i, g in enumerate(given)]
    return out
