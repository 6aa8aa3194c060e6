"""Capability commands of the ``kinodyn`` CLI, one module each (listed in :data:`kinodyn.cli.COMMANDS`).

A module defines ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.
"""
