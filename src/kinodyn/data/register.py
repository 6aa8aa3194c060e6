"""What the built-in data adds: the ``clips`` demo part (see :mod:`kinodyn.registry`)."""

DEMO_PARTS = {"clips": ("kinodyn.data.demo", 10)}
