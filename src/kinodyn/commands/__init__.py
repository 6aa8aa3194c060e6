"""The CLI's shared parts and the viewer's commands.

:mod:`kinodyn.commands.inputs` reads motions from the command line the same way for every command (the
``--scale``, ``--up``, ``--asf`` options, files or built-in clips). ``view`` and ``render`` live here
beside their shared input options and are registered by ``kinodyn/viz/register.py``; a capability's own
command is its package's ``command.py`` (see :mod:`kinodyn.registry`). A command module defines
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.
"""
