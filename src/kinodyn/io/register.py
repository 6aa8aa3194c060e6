"""What the file readers add: the ``io`` benchmark (see :mod:`kinodyn.registry`)."""

BENCHMARKS = {"io": "kinodyn.io.bench"}
