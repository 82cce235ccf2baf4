"""The harness's command-line front ends, one module per command, each with ``build_parser()``
and ``main(argv) -> int`` (named in :data:`arenabench.cli.COMMANDS`): ``eval``, ``check``,
``grade``, ``sweep``, ``bench``, ``demo``. They parse and check options, then call the rooms
that do the work; an exit status is one of :class:`arenabench.cliopts.ExitCode`.
"""
