"""Limits and sandbox settings for external pipeline runs (``--cmd``), declared once.

``eval``, ``sweep`` and ``grade`` all run untrusted commands; their command-line options and
the values the runner enforces come from here, so a limit is declared in one place.

This module holds the *declaration* (dataclasses, defaults); the options and their rules are
added by :func:`arenabench.cliopts.add_run_options`; the
enforcement lives in :mod:`arenabench.eval.runs.sandbox` (with the launcher), and
:mod:`arenabench.eval.runs.predictions` gives a run that hits the memory, process or file-size
limit the failure category ``limit``.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Mapping
from dataclasses import dataclass, field

from arenabench.cliopts import (
    BYTES_RULE,
    DEFAULT_SANDBOX,
    MAX_PROCS_RULE,
    SANDBOX_MODES,
    TIMEOUT_RULE,
    format_size,
    parse_size,
)
from arenabench.limits import (
    DEFAULT_MAX_DISK,
    DEFAULT_MAX_FILE_SIZE,
    DEFAULT_MAX_OUTPUT,
    DEFAULT_MAX_PROCS,
    DEFAULT_MEMORY_BYTES,
    DEFAULT_TIMEOUT_S,
)

__all__ = ["SANDBOX_MODES", "RunLimits", "RunSettings", "format_size", "parse_size",
           "run_settings_from_args"]



@dataclass(frozen=True)
class RunLimits:
    """Per-run limits on an external command.

    Parameters
    ----------
    timeout_s : float
        Wall-clock seconds per image; the run's processes are all killed on expiry.
    memory_bytes : int
        Address-space limit per process (``RLIMIT_AS``).
    max_procs : int
        Processes the run may have at once (a pids cgroup per run where the cgroup file
        system is writable, else ``RLIMIT_NPROC``, which does not bind root); 0: no process
        limit (``grade`` requires it where the limit cannot be enforced:
        :func:`arenabench.eval.grade.preflight.process_limit`).
    max_file_size : int
        Largest file the run may write (``RLIMIT_FSIZE``).
    max_output : int
        Bytes of stdout and of stderr kept (the tail); more is discarded, not held in memory.
    disk_bytes : int
        What a run may write in all (its working folder, ``/tmp`` and ``/dev/shm``: one tmpfs
        of this size, under bubblewrap; :func:`arenabench.eval.runs.proctools.mount_box`).
    """

    timeout_s: float = DEFAULT_TIMEOUT_S
    memory_bytes: int = DEFAULT_MEMORY_BYTES
    max_procs: int = DEFAULT_MAX_PROCS
    max_file_size: int = DEFAULT_MAX_FILE_SIZE
    max_output: int = DEFAULT_MAX_OUTPUT
    disk_bytes: int = DEFAULT_MAX_DISK

    def __post_init__(self) -> None:  # the rules of the command-line options
        TIMEOUT_RULE.check(self.timeout_s, name="timeout_s")
        MAX_PROCS_RULE.check(self.max_procs, name="max_procs")
        for name in ("memory_bytes", "max_file_size", "max_output", "disk_bytes", "max_procs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
            if name != "max_procs":
                BYTES_RULE.check(value, name=name)


@dataclass(frozen=True)
class RunSettings:
    """Everything about *how* an external command runs, besides its command line.

    Parameters
    ----------
    limits : RunLimits
    sandbox : {"auto", "bwrap", "none"}
    image_name : str, optional
        Name of the image copy in the run's private directory (default ``image`` plus the
        original extension).
    env : mapping
        Extra environment variables (``--env K=V``); the rest of the environment is not
        passed through.
    warm : bool
        Run a Python script through a warm interpreter of its command (a fork server, see
        :mod:`arenabench.eval.runs.warm_client`); ``False`` (``--no-warm``): a new process per
        image. It does not change what a script computes, so it is not in :meth:`to_dict`.
    workdir_from : str, optional
        A folder whose files are copied into every run's private working directory before the
        image (``arenabench check``: the script's own folder, so that the script finds the files
        it reads relative to its working directory, as when the competition ran it there, and
        writes ``obstacles.txt`` beside them without touching the original). At most
        :data:`~arenabench.limits.MAX_WORKDIR_COPY_BYTES` in
        :data:`~arenabench.limits.MAX_WORKDIR_COPY_FILES` files.
    """

    limits: RunLimits = field(default_factory=RunLimits)
    sandbox: str = DEFAULT_SANDBOX
    image_name: str | None = None
    env: Mapping[str, str] = field(default_factory=dict)
    warm: bool = True
    workdir_from: str | None = None

    def __hash__(self) -> int:  # env is a dict: hash its items (settings key worker caches)
        return hash((self.limits, self.sandbox, self.image_name, tuple(sorted(self.env.items())),
                     self.warm, self.workdir_from))

    def to_dict(self) -> dict[str, object]:
        """JSON form (records of sweeps and gradings)."""
        return {
            "timeout_s": self.limits.timeout_s,
            "memory_bytes": self.limits.memory_bytes,
            "max_procs": self.limits.max_procs,
            "max_file_size": self.limits.max_file_size,
            "max_output": self.limits.max_output,
            "disk_bytes": self.limits.disk_bytes,
            "sandbox": self.sandbox,
            "image_name": self.image_name,
            "env": dict(self.env),
        } | ({"workdir_from": self.workdir_from} if self.workdir_from is not None else {})

    @classmethod
    def from_dict(cls, d: Mapping[str, object]) -> RunSettings:
        """Inverse of :meth:`to_dict` (missing keys take their defaults)."""
        names = ("timeout_s", "memory_bytes", "max_procs", "max_file_size", "max_output",
                 "disk_bytes")
        limits = RunLimits(**{k: d[k] for k in names if k in d})  # type: ignore[arg-type]
        return cls(
            limits=limits,
            sandbox=str(d.get("sandbox", DEFAULT_SANDBOX)),
            image_name=d.get("image_name"),  # type: ignore[arg-type]
            env=dict(d.get("env") or {}),  # type: ignore[call-overload]
            workdir_from=d.get("workdir_from"),  # type: ignore[arg-type]
        )

    def __post_init__(self) -> None:
        if self.sandbox not in SANDBOX_MODES:
            raise ValueError(f"sandbox must be one of {SANDBOX_MODES}, got {self.sandbox!r}")
        if self.image_name is not None and (
            not self.image_name or "/" in self.image_name or self.image_name in (".", "..")
        ):
            raise ValueError(f"image_name must be a plain file name, got {self.image_name!r}")
        if self.workdir_from is not None:
            _check_workdir_from(self.workdir_from)


def _check_workdir_from(folder: str) -> None:
    """Refuse a ``workdir_from`` that is not a folder or is larger than the limits (walked
    without recursion, links not followed, stopping at the first limit passed)."""
    import os

    from arenabench.limits import MAX_WORKDIR_COPY_BYTES, MAX_WORKDIR_COPY_FILES

    if not os.path.isdir(folder):
        raise ValueError(f"workdir_from: {folder} is not a folder")
    files, size, stack = 0, 0, [folder]
    while stack:
        with os.scandir(stack.pop()) as entries:
            for entry in entries:
                if entry.name in ("__pycache__", ".git"):
                    continue
                if entry.is_dir(follow_symlinks=False):
                    stack.append(entry.path)
                    continue
                files += 1
                if entry.is_file(follow_symlinks=False):
                    size += entry.stat(follow_symlinks=False).st_size
                if files > MAX_WORKDIR_COPY_FILES or size > MAX_WORKDIR_COPY_BYTES:
                    raise ValueError(
                        f"{folder} is too large to copy into every run's folder (more than "
                        f"{MAX_WORKDIR_COPY_FILES} files or {MAX_WORKDIR_COPY_BYTES >> 20} MiB): "
                        "keep the script and the files it reads in a folder of their own")


def run_settings_from_args(args: argparse.Namespace) -> RunSettings:
    """Build :class:`RunSettings` from options added by
    :func:`arenabench.cliopts.add_run_options` (already checked by their rules).

    Raises
    ------
    ValueError
        With a message naming the option, for any bad value.
    """
    env: dict[str, str] = {}
    for item in args.env:
        key, sep, value = item.partition("=")
        if not sep or not key or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key):
            raise ValueError(f"--env: expected K=V with a valid variable name, got {item!r}")
        env[key] = value
    limits = RunLimits(
        timeout_s=args.timeout,
        memory_bytes=parse_size(args.memory_limit, name="--memory-limit"),
        max_procs=args.max_procs,
        max_file_size=parse_size(args.max_file_size, name="--max-file-size"),
        max_output=parse_size(args.max_output, name="--max-output"),
        disk_bytes=parse_size(args.max_disk, name="--max-disk"),
    )
    return RunSettings(limits=limits, sandbox=args.sandbox, image_name=args.image_name, env=env,
                       warm=getattr(args, "warm", True))
