"""A prepared external command (``--cmd``) and the runners that run it on one image.

:class:`Command` is a template prepared once (split, its executable found, what the sandbox
shows, the warm target of a Python script); :meth:`Command.argv_for`, :meth:`Command.env`,
:meth:`Command.fill_workdir` and :meth:`Command.launch_config` give one run's argument list,
environment, private directory and the launcher's configuration; :meth:`Command.interpret`
reads a finished run into a :class:`~arenabench.eval.scoring.results.Prediction`.

A :class:`Runner` runs one image of a :class:`~.pipeline.CommandPipeline`: the warm one
(:class:`~.warm_client.WarmServers`) for a Python script, then the cold one
(:class:`~.cold.ColdRunner`), which always answers.

How one image runs
------------------
- A run directory ``$TMPDIR/arenabench-run-XXXX`` holds ``work/`` (the command's private
  directory: its cwd and ``HOME``, holding only a copy of the image named
  ``settings.image_name`` or ``image`` + the original extension) and ``tmp/`` (its
  ``TMPDIR``). ``{image}`` in the template is the copy; the dataset's path never appears in
  the command's arguments or environment. The run directory is removed afterwards.
- Environment: only ``PATH``, ``HOME``, ``LANG``/``LC_ALL`` (``C.UTF-8``), ``TMPDIR`` and
  ``settings.env``; under bubblewrap ``PATH`` is the executable's folder, then
  ``/usr/local/bin:/usr/bin:/bin`` (no host folder), and the command runs as PID 1 of its
  PID namespace (no process there shows bubblewrap's arguments).
- A launcher process (:mod:`arenabench.eval.runs.launcher`) owns the run: child subreaper, so no
  process the command starts outlives the run however it detaches; killed with its
  processes (and the run directory removed) when the harness dies, even by SIGKILL.
  stdout/stderr go through it and only their last ``max_output`` bytes are kept. The run
  ends when the command's main process exits (or at the timeout); then every remaining
  process of the run is killed.
- Sandbox (``settings.sandbox``: ``bwrap``, ``none`` or ``auto``) and limits (memory, file
  size, processes, the timeout): :mod:`arenabench.eval.runs.sandbox`.
- Outcome (:class:`~arenabench.eval.scoring.results.Prediction` status ``ok``,
  ``markers_not_found``, ``timeout``, ``limit``, ``crash`` or ``bad_output``): the run's files
  and output are read by :func:`arenabench.eval.runs.predictions.prediction_from_run`.
"""

from __future__ import annotations

import os
import shlex
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from arenabench.cmdtemplate import fill, placeholders
from arenabench.competition import OBSTACLES_FILE
from arenabench.eval.scoring.results import Prediction

from .limits import RunLimits, RunSettings
from .predictions import OUTPUT_MODES, prediction_from_run
from .proctools import BOX_DIRS, LaunchConfig, RunRecord, WarmLaunch
from .sandbox import (
    SANDBOX_DIR,
    bwrap_argv,
    resolve_sandbox,
    sandbox_path,
    visible_paths,
    warn_if_procs_unlimited,
)
from .warm_target import WarmTarget, warm_target

if TYPE_CHECKING:
    from .remover import FolderRemover
    from .slots import RunSlots


def _resolve_executable(exe: str, base_dir: str) -> str | None:
    """The path of the template's program (``None`` for a placeholder other than
    ``{python}``).

    Raises
    ------
    ValueError
        One line: the executable does not exist or is not executable.
    """
    if "{" in exe:
        return None if "{python}" != exe else sys.executable
    if "/" in exe:
        path = Path(base_dir, exe)
        if not path.is_file() or not os.access(path, os.X_OK):
            why = "does not exist" if not path.exists() else "is not an executable file"
            raise ValueError(f"--cmd: executable {exe!r} {why} (relative to {base_dir})")
        return os.path.abspath(path)  # not resolved: a venv's python is a symlink
    found = shutil.which(exe)
    if found is None:
        raise ValueError(f"--cmd: executable {exe!r} not found on PATH")
    return found


def _resolved_args(argv: tuple[str, ...], base_dir: str) -> tuple[str, ...]:
    """The template's arguments with each literal one naming an existing file or folder
    relative to ``base_dir`` made absolute (a placeholder's argument is filled per run)."""
    out = []
    for arg in argv:
        if placeholders(arg):  # filled per run (Command.argv_for)
            out.append(arg)
            continue
        arg = fill(arg, {})  # literal text: '{{' is a brace
        if arg and not arg.startswith("-") and not os.path.isabs(arg):
            candidate = Path(base_dir, arg)  # '' is an argument, never the folder
            try:
                exists = candidate.exists()
            except OSError:  # e.g. longer than a file name may be: an argument, not a path
                exists = False
            if exists:
                arg = os.path.abspath(candidate)
        out.append(arg)
    return tuple(out)


@dataclass(frozen=True)
class Command:
    """A command template prepared once: what every run of it needs, cold or warm.

    Made by :meth:`prepare`; immutable, so the pipelines of one context share it.

    Attributes
    ----------
    template : str
        The command line as given.
    settings : RunSettings
        Limits, sandbox mode, image name, extra environment.
    output : {"obstacles", "json"}
        How the command answers.
    base_dir : str
        What relative paths in the template are relative to.
    argv : tuple of str
        The template split into arguments (placeholders unfilled).
    args : tuple of str
        The same with literal paths made absolute (:func:`_resolved_args`).
    executable : str or None
        The program's path (``None`` for an unresolved placeholder).
    sandbox : {"bwrap", "none"}
        The sandbox runs get (:func:`.sandbox.resolve_sandbox`).
    cgroup_parent : str or None
        Where the runs' pids cgroups go.
    visible : tuple of str
        The read-only folders of the sandbox besides /usr (:func:`.sandbox.visible_paths`).
    warm : WarmTarget or None
        What a warm run executes, when the command runs a Python script and
        ``settings.warm`` (:func:`.warm_client.warm_target`).
    """

    template: str
    settings: RunSettings
    output: str
    base_dir: str
    argv: tuple[str, ...]
    args: tuple[str, ...]
    executable: str | None
    sandbox: str
    cgroup_parent: str | None
    visible: tuple[str, ...]
    warm: WarmTarget | None = field(default=None, compare=False)

    @classmethod
    def prepare(cls, template: str, *, settings: RunSettings, output: str, base_dir: str,
                cgroup_parent: str | None) -> Command:
        """Split, check and resolve ``template`` once.

        Raises
        ------
        ValueError
            One line: bad template or ``output``, an executable that does not exist,
            ``sandbox="bwrap"`` without a working bubblewrap.
        """

        if not isinstance(settings, RunSettings):
            raise ValueError(f"settings must be a RunSettings, got {settings!r}")
        if output not in OUTPUT_MODES:
            raise ValueError(f"output must be one of {OUTPUT_MODES}, got {output!r}")
        try:
            argv = tuple(shlex.split(template))
        except ValueError as exc:
            raise ValueError(f"template cannot be split into arguments: {exc}") from None
        if not argv:
            raise ValueError(f"template must not be empty, got {template!r}")
        executable = _resolve_executable(argv[0], base_dir)
        sandbox = resolve_sandbox(settings.sandbox)
        warn_if_procs_unlimited(cgroup_parent, max_procs=settings.limits.max_procs)
        args = _resolved_args(argv, base_dir)
        visible = tuple(visible_paths(executable, list(args),
                                      python=any("{python}" in a for a in argv)))
        return cls(template=template, settings=settings, output=output, base_dir=base_dir,
                   argv=argv, args=args, executable=executable, sandbox=sandbox,
                   cgroup_parent=cgroup_parent, visible=visible,
                   warm=warm_target(list(args)) if settings.warm else None)

    @property
    def limits(self) -> RunLimits:
        """The run limits (``settings.limits``)."""
        return self.settings.limits

    @property
    def sandboxed(self) -> bool:
        """Runs go under bubblewrap."""
        return self.sandbox == "bwrap"

    def image_name(self, image_path: Path) -> str:
        """File name of the image's copy in the private directory."""
        return self.settings.image_name or "image" + Path(image_path).suffix

    def argv_for(self, image_path: Path, *, image_dir: str | None = None) -> list[str]:
        """The command's argument list for one image (without any sandbox prefix).

        ``{image}`` is ``image_dir`` (default: :data:`SANDBOX_DIR` under bubblewrap, else the
        image's own folder) joined with :meth:`image_name`.
        """
        if image_dir is None:
            image_dir = SANDBOX_DIR if self.sandboxed else str(Path(image_path).parent)
        image = os.path.join(image_dir, self.image_name(image_path))
        values = {"image": image, "python": sys.executable}
        # one pass per template argument (arenabench.cmdtemplate.fill): a value, or a path
        # resolved from a literal argument, is never searched for placeholders
        return [fill(t, values) if placeholders(t) else a
                for t, a in zip(self.argv, self.args, strict=True)]

    def bwrap_argv(self, folder: str, image_path: Path) -> list[str]:
        """bubblewrap's arguments for a run (or a warm server) whose folders ``work``, ``tmp``
        and ``shm`` are in ``folder``."""
        work, tmp, shm = (os.path.join(folder, name) for name in BOX_DIRS)
        return bwrap_argv(work, tmp, shm, image_path, list(self.visible))

    def env(self, home: str, tmp: str) -> dict[str, str]:
        """The command's whole environment (cold runs, warm servers and warm runs alike);
        under bubblewrap ``PATH`` names no host folder (:func:`.sandbox.sandbox_path`)."""
        env = {
            "PATH": (sandbox_path(self.executable) if self.sandboxed
                     else os.environ.get("PATH", os.defpath)),
            "HOME": home,
            "LANG": "C.UTF-8",
            "LC_ALL": "C.UTF-8",
            "TMPDIR": tmp,
        }
        env.update(self.settings.env)
        return env

    def fill_workdir(self, work: str, image_path: Path) -> str | None:
        """Fill a run's private working directory ``work`` (cold and warm runs alike): the files
        of ``settings.workdir_from``, if any, then the image's copy. Returns ``None``, or why
        it failed (one line)."""
        try:
            if self.settings.workdir_from:
                shutil.copytree(self.settings.workdir_from, work, symlinks=True,
                                dirs_exist_ok=True, ignore=shutil.ignore_patterns(
                                    "__pycache__", ".git", OBSTACLES_FILE))
        except (OSError, shutil.Error) as exc:
            return f"cannot copy {self.settings.workdir_from} into the run's folder: {exc}"
        try:
            shutil.copyfile(image_path, os.path.join(work, self.image_name(image_path)))
        except OSError as exc:
            return f"cannot copy the image: {exc}"
        return None

    def launch_config(self, *, exe: str, argv: list[str], env: dict[str, str], cwd: str,
                      rundir: str, image_path: Path, cgroup_parent: str | None,
                      extra_procs: int, parent_pid: int,
                      warm: WarmLaunch | None = None) -> LaunchConfig:
        """The one launch configuration of a run, cold or warm: its limits, its cgroup
        (``extra_procs``: processes of the run beyond the command's: bubblewrap's, a warm run's
        keeper), its box under bubblewrap."""
        lim = self.limits
        return LaunchConfig(
            exe=exe, argv=argv, env=env, cwd=cwd, rundir=rundir, timeout_s=lim.timeout_s,
            memory_bytes=lim.memory_bytes, max_file_size=lim.max_file_size,
            max_output=lim.max_output, max_procs=lim.max_procs,
            pids_max=lim.max_procs + extra_procs, cgroup_parent=cgroup_parent,
            sandboxed=self.sandboxed,
            nproc_rlimit=cgroup_parent is None and os.getuid() != 0, parent_pid=parent_pid,
            box_bytes=lim.disk_bytes if self.sandboxed else None,
            image_name=self.image_name(image_path), warm=warm)

    def interpret(self, result: RunRecord, stdout: str, stderr: str, workdir: str) -> Prediction:
        """A finished run's :class:`Prediction` (:func:`.predictions.prediction_from_run`)."""
        return prediction_from_run(result, stdout, stderr, workdir, output=self.output,
                                   limits=self.limits,
                                   pids_cgroup=self.cgroup_parent is not None)


class RunJob(Protocol):
    """What a runner needs of the pipeline whose image it runs (a
    :class:`~.pipeline.CommandPipeline` is one): its prepared command, whether it was
    stopped, and its name (in messages)."""

    @property
    def command(self) -> Command:
        """The prepared command."""
        ...

    @property
    def stopped(self) -> bool:
        """A stop was asked: runs under way are killed, later ones return at once."""
        ...

    @property
    def name(self) -> str:
        """The pipeline's name."""
        ...

    def stop(self) -> None:
        """Kill the runs under way; later ones return at once."""
        ...


class RunPlace(Protocol):
    """What a runner uses of the run context it serves (a
    :class:`~.context.RunContext` is one): its run slots and its remover of finished runs'
    folders."""

    @property
    def slots(self) -> RunSlots | None:
        """The run slots bounding the runs at once (``None``: unbounded)."""
        ...

    @property
    def remover(self) -> FolderRemover:
        """Removes finished runs' folders off the callers' threads."""
        ...


class Runner(Protocol):
    """One way of running a command on an image: the warm servers of a context, or cold
    launchers. The pipeline tries its runners in order; a runner that cannot take the image
    answers ``None`` and the next one runs it."""

    def run(self, pipe: RunJob, image_path: Path) -> Prediction | None:
        """Run ``pipe``'s command on one image; ``None``: not here (never for the last runner).

        Raises
        ------
        HarnessError
            When the harness cannot run the image.
        """
        ...

    def stop(self, pipe: RunJob) -> None:
        """Kill ``pipe``'s runs under way here."""
        ...
