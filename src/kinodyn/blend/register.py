"""What blending adds: the ``blend`` command, benchmark and demo part (see :mod:`kinodyn.registry`)."""

COMMANDS = {"blend": "kinodyn.blend.command"}
BENCHMARKS = {"blend": "kinodyn.blend.bench"}
DEMO_PARTS = {"blend": ("kinodyn.blend.demo", 30)}
