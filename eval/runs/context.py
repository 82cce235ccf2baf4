"""The run context: what one evaluation, grade, check or sweep worker holds while it runs
external commands, and ends when it closes.

    with RunContext(slots=workers) as runs:
        pipe = CommandPipeline("python3 map.py --image {image}", settings=settings,
                               context=runs)
        ...                      # pipe.run(image) from several threads
    # closed: the warm servers are ended, the runs' folders removed

A context holds

- the run slots (:class:`~.slots.RunSlots`: at most ``slots`` commands at once, ``None``: as
  many as the callers' threads) and how many threads a caller should run for them
  (:meth:`threads`);
- the folder remover (:class:`~.remover.FolderRemover`);
- the warm servers of its commands (:class:`~.warm_client.WarmServers`): shared by every
  pipeline with the same command, settings, folder and dataset folder (``grade`` makes a
  pipeline per image), at most :data:`~.warm_client.MAX_IDLE_SERVERS` idle;
- what it learnt of the machine once: the pids-cgroup parent its runs' cgroups go under
  (:func:`~.sandbox.pids_cgroup_parent`, or ``cgroup_parent`` given).

Nothing of it is module-level state: two contexts in one process share no server, slot or
folder, and a context's end (:meth:`close`, or the end of its ``with`` block) ends everything
it started; a later run starts what it needs again. A :class:`~.pipeline.CommandPipeline`
made without a context makes one of its own, which its
:meth:`~.pipeline.CommandPipeline.close` closes.
"""

from __future__ import annotations

import threading
import weakref
from typing import TYPE_CHECKING

from .command import Command
from .remover import FolderRemover
from .sandbox import pids_cgroup_parent
from .slots import RunSlots, extra_thread
from .stale import sweep_stale_runs
from .warm_client import WarmServers

if TYPE_CHECKING:
    from .command import RunJob
    from .limits import RunSettings

#: ``cgroup_parent`` not given: probe the machine (:func:`.sandbox.pids_cgroup_parent`).
PROBE = "probe"
#: Commands a context keeps prepared (a grade's teams; beyond this the cache starts again).
MAX_PREPARED = 1024


class RunContext:
    """Run slots, the folder remover and the warm servers of one evaluation, grade, check or
    sweep worker (see the module docstring).

    Parameters
    ----------
    slots : int, optional, keyword-only
        Commands that may run at once (>= 1); ``None``: no limit beyond the callers' threads.
    cgroup_parent : str or None, keyword-only
        Where the runs' pids cgroups go; default: probed once per process
        (:func:`.sandbox.pids_cgroup_parent`); ``None``: no pids cgroup.

    Raises
    ------
    ValueError
        ``slots`` is not a positive integer.
    """

    def __init__(self, *, slots: int | None = None, cgroup_parent: str | None = PROBE) -> None:
        self.slots = None if slots is None else RunSlots(slots)
        self.cgroup_parent = pids_cgroup_parent() if cgroup_parent == PROBE else cgroup_parent
        sweep_stale_runs(cgroup_parent=self.cgroup_parent)  # what killed commands left, once
        self.remover = FolderRemover()
        self.servers = WarmServers(self)
        self._lock = threading.Lock()
        self._pipelines: weakref.WeakSet[RunJob] = weakref.WeakSet()
        self._prepared: dict[tuple, Command] = {}

    def prepared(self, template: str, *, settings: RunSettings, output: str,
                 base_dir: str) -> Command:
        """The :class:`~.command.Command` of a template, prepared once per context (``grade``
        makes a pipeline per image: the executable, the arguments and what the sandbox shows
        are found once per team).

        Raises
        ------
        ValueError
            As :meth:`.command.Command.prepare`.
        """
        key = (template, settings, output, base_dir)
        with self._lock:
            found = self._prepared.get(key)
        if found is None:
            found = Command.prepare(template, settings=settings, output=output,
                                    base_dir=base_dir, cgroup_parent=self.cgroup_parent)
            with self._lock:
                if len(self._prepared) >= MAX_PREPARED:
                    self._prepared.clear()
                self._prepared[key] = found
        return found

    def use_slots(self, n: int) -> None:
        """Hold this context's runs to ``n`` commands at once from now on (at the start of an
        evaluation by a pipeline of its own context: slots for its workers, replacing those
        of an earlier evaluation when none is in use)."""
        with self._lock:
            if self.slots is None or (self.slots.n != n and self.slots.free == self.slots.n
                                      and not self.slots.waiting):
                self.slots = RunSlots(n)

    def adopt(self, pipeline: RunJob) -> None:
        """Count ``pipeline`` among this context's (:meth:`stop` stops it)."""
        with self._lock:
            self._pipelines.add(pipeline)

    def threads(self, workers: int) -> int:
        """Threads a caller runs for ``workers`` images at once: one more than ``workers``
        under run slots (it prepares the next image meanwhile; :func:`.slots.extra_thread`)."""
        return workers + extra_thread(self.slots, workers)

    def stop(self) -> None:
        """Kill every run of every pipeline of this context; their later runs return at once."""
        with self._lock:
            pipelines = list(self._pipelines)
        for pipe in pipelines:
            pipe.stop()
        if self.slots is not None:
            self.slots.wake()

    def close(self) -> None:
        """End the warm servers (their runs are killed) once the folders of finished runs are
        removed; idempotent, and a later run starts what it needs again."""
        self.remover.close()
        self.servers.close()

    def __enter__(self) -> RunContext:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
