"""What the viewer adds: the ``view`` and ``render`` commands, the ``viz`` benchmark and the ``viewer`` demo
part (see :mod:`kinodyn.registry`). The two commands live in :mod:`kinodyn.commands` beside the input
options they share; the viewer demo part runs last, as it shows what the earlier parts wrote."""

COMMANDS = {"view": "kinodyn.commands.view", "render": "kinodyn.commands.render"}
BENCHMARKS = {"viz": "kinodyn.viz.bench"}
DEMO_PARTS = {"viewer": ("kinodyn.viz.demo", 90)}
