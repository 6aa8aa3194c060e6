"""What kinodyn.contact adds to the ``kinodyn`` command, the benchmarks and the demo (plain literals)."""

COMMANDS = {"contact": "kinodyn.contact.command"}
BENCHMARKS = {"contact": "kinodyn.contact.bench"}
DEMO_PARTS = {"contact": ("kinodyn.contact.demo", 70)}
