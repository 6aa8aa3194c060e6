"""What physics adds: the ``body`` command, the ``physics`` benchmark and demo part (see :mod:`kinodyn.registry`)."""

COMMANDS = {"body": "kinodyn.physics.command"}
BENCHMARKS = {"physics": "kinodyn.physics.bench"}
DEMO_PARTS = {"physics": ("kinodyn.physics.demo", 20)}
