"""Dynamic response (dynamic-response paper): a hit character's simulated reaction is matched to a clip of
a reaction library and returns to it.

Built so far: the reaction library (:mod:`kinodyn.response.library`), the exhaustive windowed search
(:mod:`kinodyn.response.search`) and the fast sparse-sampling + BFGS alignment (:mod:`kinodyn.response.align`).
"""

from kinodyn.response.align import AlignConfig, AlignResult, AlignStatus, fast_align
from kinodyn.response.library import ReactionLibrary, builtin, from_folder, from_motions
from kinodyn.response.search import SearchConfig, SearchResult, Windows, body_tracks, exhaustive, windows

__all__ = ["AlignConfig", "AlignResult", "AlignStatus", "ReactionLibrary", "SearchConfig", "SearchResult",
           "Windows", "body_tracks", "builtin", "exhaustive", "fast_align", "from_folder", "from_motions",
           "windows"]
