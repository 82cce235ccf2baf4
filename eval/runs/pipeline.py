"""External pipelines (``--cmd``): each run contained, limited, cleaned up and categorised.

Interface (used by ``eval``, ``sweep``, ``grade`` and ``check``)::

    with RunContext(slots=workers) as runs:         # .context: slots, remover, warm servers
        pipe = CommandPipeline(template, settings=RunSettings(...), output="obstacles",
                               name="", base_dir=os.getcwd(), context=runs)
        pipe.run(image_path) -> Prediction          # never raises for the command's failures
        pipe.stop()                                 # kill running runs, refuse new ones
    # the context's end: its warm servers ended, its runs' folders removed

A :class:`CommandPipeline` made without a context makes one of its own, which its
:meth:`~CommandPipeline.close` closes. The command is prepared once (:class:`Command`: the
template split, the executable found, what the sandbox shows), then every image runs through
the pipeline's runners, each a :class:`~.command.Runner`: the warm one for a Python script
(:class:`~.warm_client.WarmServers`, the context's), then the cold one
(:class:`~.cold.ColdRunner`), which always answers.

``settings`` (:class:`~arenabench.eval.runs.limits.RunSettings`) holds the limits
(``limits.timeout_s``, ``memory_bytes``, ``max_procs``, ``max_file_size``, ``max_output``),
the sandbox mode, the image's name and extra environment variables. Construction raises
``ValueError`` (one line) for a template that cannot be split, an executable that does not
exist, ``output`` not in :data:`~arenabench.eval.runs.predictions.OUTPUT_MODES`, or
``sandbox="bwrap"`` where bubblewrap is missing or does not work.

How one image runs: :mod:`.command`.
"""

from __future__ import annotations

import os
import threading
import weakref
from pathlib import Path

from arenabench.eval.scoring.results import HarnessError, Prediction

from .cold import ColdRunner
from .command import Command, Runner
from .context import RunContext
from .limits import RunLimits, RunSettings
from .predictions import STARVED_RETRIES


class CommandPipeline:
    """An external command, run once per image the way competition scripts are graded.

    Parameters
    ----------
    template : str
        Command line, split with :func:`shlex.split` (no shell). In every argument
        ``{image}`` becomes the path of the image's private copy and ``{python}`` the running
        Python interpreter; substitution is per argument, so paths with spaces survive.
        Arguments naming an existing file or folder relative to ``base_dir`` are made
        absolute (their folders are the submission's, visible read-only in the sandbox).
    settings : RunSettings, keyword-only
        Limits (``settings.limits.timeout_s`` is the per-image timeout), sandbox mode,
        image name and extra environment.
    output : {"obstacles", "json"}, keyword-only
        Read ``obstacles.txt`` from the working directory, or the last JSON object line on
        stdout.
    name : str, keyword-only
        Name in reports (default: the template).
    base_dir : str, keyword-only
        Folder that relative paths in the template are relative to (default: the current
        directory when the pipeline is created).
    context : RunContext, optional, keyword-only
        The run slots, folder remover and warm servers it shares with the other pipelines of
        an evaluation, grade or check (:mod:`.context`); default: one of its own, closed by
        :meth:`close`.

    Raises
    ------
    ValueError
        One line naming the problem: bad template or ``output``, an executable that does not
        exist, ``sandbox="bwrap"`` without a working bubblewrap.

    Notes
    -----
    Exit status 0 means "answer written"; 3 means markers not found; any other non-zero
    exit is a ``crash`` (or ``limit``, see the module docstring).
    """

    in_process = False

    def __init__(self, template: str, *, settings: RunSettings | None = None,
                 output: str = "obstacles", name: str = "", base_dir: str | None = None,
                 context: RunContext | None = None) -> None:
        self.owns_context = context is None
        self.context = RunContext() if context is None else context
        try:
            self.command = self.context.prepared(
                template, settings=settings if settings is not None else RunSettings(),
                output=output, base_dir=base_dir if base_dir is not None else os.getcwd())
        except BaseException:
            if self.owns_context:
                self.context.close()
            raise
        if self.owns_context:  # forgotten, it still ends what it started once collected
            weakref.finalize(self, self.context.close)
        self.name = name or template
        runners: list[Runner] = [ColdRunner(self.context)]
        if self.command.warm is not None:  # a Python script: its warm server first
            runners.insert(0, self.context.servers)
        self.runners: tuple[Runner, ...] = tuple(runners)
        self._lock = threading.Lock()
        self._stopped = False
        self.context.adopt(self)

    @property
    def template(self) -> str:
        """The command line as given."""
        return self.command.template

    @property
    def settings(self) -> RunSettings:
        """How it runs (:attr:`Command.settings`)."""
        return self.command.settings

    @property
    def output(self) -> str:
        """How it answers."""
        return self.command.output

    @property
    def base_dir(self) -> str:
        """What relative paths in the template are relative to."""
        return self.command.base_dir

    @property
    def sandbox(self) -> str:
        """The sandbox its runs get: ``"bwrap"`` or ``"none"``."""
        return self.command.sandbox

    @property
    def limits(self) -> RunLimits:
        """The run limits (``settings.limits``)."""
        return self.command.limits

    @property
    def stopped(self) -> bool:
        """Whether :meth:`stop` was called (later runs return at once)."""
        return self._stopped

    def argv(self, image_path: Path, *, image_dir: str | None = None) -> list[str]:
        """The command's argument list for one image (:meth:`Command.argv_for`)."""
        return self.command.argv_for(image_path, image_dir=image_dir)

    def threads(self, workers: int) -> int:
        """Threads a caller should run for ``workers`` images at once: a pipeline with a
        context of its own takes ``workers`` run slots for them (one more thread prepares the
        next image meanwhile, :mod:`.slots`); a shared context's slots are its owner's."""
        if self.owns_context:
            self.context.use_slots(workers)
        return self.context.threads(workers)

    def run(self, image_path: Path) -> Prediction:
        """Run the command on one image in a fresh private directory (never raises for the
        command's own failures). A run that timed out starved (it waited for a CPU most of
        the time: :data:`.predictions.STARVED_SHARE`) is run again, up to
        :data:`.predictions.STARVED_RETRIES` times; when every run starved, the machine
        failed the image, not the command: :class:`HarnessError`.

        Raises
        ------
        HarnessError
            When the harness cannot run the image (no space for the run's folder, the image
            cannot be copied, the launcher fails, every run of it starved of CPU): the
            harness's failure, never scored.
        """
        pred = self._run_once(Path(image_path))
        for _ in range(STARVED_RETRIES):
            if not pred.starved or self._stopped:
                break
            pred = self._run_once(Path(image_path))
        if pred.starved and not self._stopped:
            raise HarnessError(
                f"{self.name} starved of CPU on {Path(image_path).name} in each of "
                f"{1 + STARVED_RETRIES} runs (the last {pred.message}): the machine is too "
                f"busy to time it fairly, and a starved run is never the command's timeout; "
                f"run it on a quieter machine or with fewer --workers")
        return pred

    def _run_once(self, image_path: Path) -> Prediction:
        for runner in self.runners:
            if self._stopped:
                return Prediction(status="crash", message="interrupted")
            pred = runner.run(self, image_path)
            if pred is not None:
                return pred
        raise AssertionError("the cold runner always answers")  # pragma: no cover

    def stop(self) -> None:
        """Kill every running run (their launchers or managers clean up) and make later runs
        return at once as ``crash`` with message ``interrupted``."""
        with self._lock:
            self._stopped = True
        for runner in self.runners:
            runner.stop(self)
        if self.context.slots is not None:
            self.context.slots.wake()

    def close(self) -> None:
        """The end of its use: its own context is closed (warm servers ended, folders
        removed; also when a pipeline that was never closed is garbage collected, or at the
        interpreter's exit); in a shared context its command's idle warm servers end and the
        folders of finished runs are removed (a later run starts a server again)."""
        if self.owns_context:
            self.context.close()
            return
        self.context.remover.wait()
        if self.command.warm is not None:
            self.context.servers.close_idle(self.command)

    def __enter__(self) -> CommandPipeline:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"CommandPipeline({self.template!r}, name={self.name!r})"


__all__ = ["Command", "CommandPipeline", "Runner"]


def check_command(template: str, *, settings: RunSettings, output: str = "obstacles",
                  base_dir: str | None = None) -> None:
    """Check a command before any work: ``ValueError`` (one line) for a bad placeholder or
    ``output``, a missing executable, bubblewrap asked for and missing. The harness's own
    Python stands for ``{competition_python}`` here: the competition's environment is made
    only once everything else holds. Nothing is kept (no warm server starts)."""
    from .competition_env import OWN_PYTHON_PLACEHOLDER, substitute_competition_python

    CommandPipeline(substitute_competition_python(template, OWN_PYTHON_PLACEHOLDER),
                    settings=settings, output=output, base_dir=base_dir).close()
