"""The ``decrun`` command and its companions ``decrun-table`` and ``decrun-track``: the Hydra task
and the command line (:mod:`~decrun.runner.command.task`)."""
