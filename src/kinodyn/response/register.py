"""What the dynamic-response capability adds to kinodyn (read without importing the package)."""

COMMANDS = {"response": "kinodyn.response.command"}
BENCHMARKS = {"response": "kinodyn.response.bench"}
DEMO_PARTS = {"response": ("kinodyn.response.demo", 50)}
