"""Seeing results: a self-contained HTML viewer, videos, plots and exports other tools open.

- :mod:`kinodyn.viz.html`: ``write(path, motions, overlays=...)``, one offline HTML page (three.js).
- :mod:`kinodyn.viz.render`: MP4/GIF/PNG rendered offscreen on the CPU with MuJoCo (OSMesa).
- :mod:`kinodyn.viz.gltf`: glTF 2.0 export of a skeleton animation.
- :mod:`kinodyn.viz.world`: what a page or a video shows (characters and overlays), shared by both.
- :mod:`kinodyn.viz.labels`: the frame counter and name labels of videos, placed apart.

Plots and the colours every picture shares live lower, in :mod:`kinodyn.plotting`, so every capability
may draw its figures without depending on the viewer.

Submodules are imported on demand (``from kinodyn.viz import html``); nothing here imports matplotlib,
MuJoCo or pygltflib at import time.
"""

from kinodyn.viz.world import Actor, Contacts, Impact, Phases, Trajectory

__all__ = ["Actor", "Contacts", "Impact", "Phases", "Trajectory"]
