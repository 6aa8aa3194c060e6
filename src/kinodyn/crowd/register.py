"""What the crowd package adds to kinodyn: a command, a benchmark and a demo part (plain literals)."""

COMMANDS = {"crowd": "kinodyn.crowd.command"}
BENCHMARKS = {"crowd": "kinodyn.crowd.bench"}
DEMO_PARTS = {"crowd": ("kinodyn.crowd.demo", 60)}
