"""Exit statuses of every ``arenabench`` command, declared once (docs/commands.md, "Exit
status"). A command's ``main`` returns one of them; ``tests/core/test_exit_codes.py`` checks that no
command module returns a bare number."""

from __future__ import annotations

import enum

from arenabench.competition import EXIT_MARKERS_NOT_FOUND


@enum.unique
class ExitCode(enum.IntEnum):
    """What a command's exit status says. Each number has one meaning, whatever the command.

    A stop signal ends a command with 128 + the signal's number
    (:func:`arenabench.interrupts.exit_code`: :attr:`INTERRUPTED` for SIGINT,
    :attr:`TERMINATED` for SIGTERM).
    """

    #: The command did what it was asked, and every gate passed.
    OK = 0
    #: The command ran, and what it measured failed: a ``--fail-under`` gate, a ``check``
    #: verdict, a ``doctor`` check, a team the grader could not finish.
    FAILED = 1
    #: Bad input or usage: one line naming the problem, before any work.
    USAGE = 2
    #: ``detect`` (as a competition script): the four markers were not found.
    MARKERS_NOT_FOUND = EXIT_MARKERS_NOT_FOUND
    #: The harness itself could not run an image (no space for a run's folder, the image
    #: cannot be copied, a launcher fails): the command stopped, nothing of it was scored.
    HARNESS = 4
    #: ``grade``: most teams fail alike (one missing module, one wrong path): the set-up, not
    #: the teams, is likely wrong; the leaderboard is written.
    SYSTEMIC = 5
    #: ``twin``: the twin's render of the image is outside the bounds the blind round trips
    #: hold (its verdict ``poor``, naming what is off and why); the twin is written, and
    #: ``--accept-poor-fit`` makes this 0.
    POOR_FIT = 6
    #: Stopped by SIGINT (Ctrl-C): 128 + 2.
    INTERRUPTED = 130
    #: The reader of its output went away (``... | head -1``): 128 + SIGPIPE.
    BROKEN_PIPE = 141
    #: Stopped by SIGTERM: 128 + 15.
    TERMINATED = 143
