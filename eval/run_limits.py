"""Limits and sandbox settings for external pipeline runs (``--cmd``), declared once.

``eval``, ``sweep`` and ``grade`` all run untrusted commands; their command-line options and
the values the runner enforces come from here, so a limit is declared in one place.

This module holds the *declaration* (dataclass, defaults, parsing, argparse options); the
enforcement lives in :mod:`arenabench.eval.external` (``CommandPipeline``), where a run that
hits the memory, process or file-size limit gets the failure category ``limit``.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Mapping
from dataclasses import dataclass, field

#: How external commands are contained: ``auto`` uses bubblewrap when it is installed and
#: works (else ``none``, with a warning), ``bwrap`` requires it, ``none`` runs without
#: namespaces (private directory, limits and process cleanup still apply).
SANDBOX_MODES: tuple[str, ...] = ("auto", "bwrap", "none")

_SIZE_RE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([kKmMgGtT]?)(?:i?[bB])?\s*$")
_SIZE_UNITS = {"": 1, "k": 1024, "m": 1024**2, "g": 1024**3, "t": 1024**4}


def parse_size(text: str, *, name: str) -> int:
    """Parse ``"2G"``, ``"64M"``, ``"512k"`` or a plain byte count into bytes.

    Parameters
    ----------
    text : str
        The size; suffixes k/M/G/T are powers of 1024, an optional trailing ``B``/``iB``.
    name : str
        Option name for the error message.

    Raises
    ------
    ValueError
        Naming ``name`` and the value, when it is not a positive size.
    """
    m = _SIZE_RE.match(str(text))
    if not m:
        raise ValueError(f"{name}: not a size: {text!r} (use e.g. 2G, 64M, 1048576)")
    value = int(float(m.group(1)) * _SIZE_UNITS[m.group(2).lower()])
    if value <= 0:
        raise ValueError(f"{name}: must be > 0, got {text!r}")
    return value


def format_size(value: int) -> str:
    """The shortest exact spelling :func:`parse_size` reads back (``2147483648`` -> ``"2G"``)."""
    for suffix, unit in (("T", 1024**4), ("G", 1024**3), ("M", 1024**2), ("k", 1024)):
        if value % unit == 0:
            return f"{value // unit}{suffix}"
    return str(value)


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
        system is writable, else ``RLIMIT_NPROC``, which does not bind root).
    max_file_size : int
        Largest file the run may write (``RLIMIT_FSIZE``).
    max_output : int
        Bytes of stdout and of stderr kept (the tail); more is discarded, not held in memory.
    """

    timeout_s: float = 60.0
    memory_bytes: int = 2 * 1024**3
    max_procs: int = 64
    max_file_size: int = 64 * 1024**2
    max_output: int = 1024**2

    def __post_init__(self) -> None:
        if not self.timeout_s > 0:  # also refuses NaN
            raise ValueError(f"timeout_s must be > 0, got {self.timeout_s!r}")
        for name in ("memory_bytes", "max_procs", "max_file_size", "max_output"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")


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
        :mod:`arenabench.eval.warm_client`); ``False`` (``--no-warm``): a new process per
        image. It does not change what a script computes, so it is not in :meth:`to_dict`.
    """

    limits: RunLimits = field(default_factory=RunLimits)
    sandbox: str = "auto"
    image_name: str | None = None
    env: Mapping[str, str] = field(default_factory=dict)
    warm: bool = True

    def __hash__(self) -> int:  # env is a dict: hash its items (settings key worker caches)
        return hash((self.limits, self.sandbox, self.image_name, tuple(sorted(self.env.items())),
                     self.warm))

    def to_dict(self) -> dict[str, object]:
        """JSON form (records of sweeps and gradings)."""
        return {
            "timeout_s": self.limits.timeout_s,
            "memory_bytes": self.limits.memory_bytes,
            "max_procs": self.limits.max_procs,
            "max_file_size": self.limits.max_file_size,
            "max_output": self.limits.max_output,
            "sandbox": self.sandbox,
            "image_name": self.image_name,
            "env": dict(self.env),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, object]) -> RunSettings:
        """Inverse of :meth:`to_dict` (missing keys take their defaults)."""
        names = ("timeout_s", "memory_bytes", "max_procs", "max_file_size", "max_output")
        limits = RunLimits(**{k: d[k] for k in names if k in d})  # type: ignore[arg-type]
        return cls(
            limits=limits,
            sandbox=str(d.get("sandbox", "auto")),
            image_name=d.get("image_name"),  # type: ignore[arg-type]
            env=dict(d.get("env") or {}),  # type: ignore[call-overload]
        )

    def __post_init__(self) -> None:
        if self.sandbox not in SANDBOX_MODES:
            raise ValueError(f"sandbox must be one of {SANDBOX_MODES}, got {self.sandbox!r}")
        if self.image_name is not None and (
            not self.image_name or "/" in self.image_name or self.image_name in (".", "..")
        ):
            raise ValueError(f"image_name must be a plain file name, got {self.image_name!r}")


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of external runs (``--timeout``, limits, sandbox, env) to ``parser``."""
    d = RunLimits()
    g = parser.add_argument_group("external command runs (--cmd)")
    g.add_argument(
        "--timeout", type=float, default=d.timeout_s,
        help="wall-clock seconds per image (default: %(default)s)",
    )
    g.add_argument(
        "--memory-limit", default=format_size(d.memory_bytes),
        help="address space per process, e.g. 2G, 512M (default: %(default)s)",
    )
    g.add_argument(
        "--max-procs", type=int, default=d.max_procs,
        help="processes a run may have at once (default: %(default)s)",
    )
    g.add_argument(
        "--max-file-size", default=format_size(d.max_file_size),
        help="largest file a run may write (default: %(default)s)",
    )
    g.add_argument(
        "--max-output", default=format_size(d.max_output),
        help="bytes of stdout and of stderr kept per run, the tail (default: %(default)s)",
    )
    g.add_argument(
        "--sandbox", choices=SANDBOX_MODES, default="auto",
        help="auto: bubblewrap when it works here (else a warning and none); bwrap: require "
        "it; none: no namespaces (default: %(default)s)",
    )
    g.add_argument(
        "--image-name", default=None,
        help="file name of the image copy the command sees (default: image + its extension)",
    )
    g.add_argument(
        "--env", action="append", default=[], metavar="K=V",
        help="environment variable for the command (repeatable); nothing else is passed on "
        "besides PATH, HOME, LANG, LC_ALL and TMPDIR",
    )
    g.add_argument(
        "--no-warm", dest="warm", action="store_false",
        help="start a new Python process per image for a Python script (default: one warm "
        "interpreter per command, which forks a fresh process per image; see "
        "docs/warm-interpreter.md)",
    )


def run_settings_from_args(args: argparse.Namespace) -> RunSettings:
    """Build :class:`RunSettings` from options added by :func:`add_run_arguments`.

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
    if args.max_procs is not None and args.max_procs < 1:
        raise ValueError(f"--max-procs must be >= 1, got {args.max_procs}")
    if not args.timeout > 0:
        raise ValueError(f"--timeout must be > 0, got {args.timeout}")
    limits = RunLimits(
        timeout_s=args.timeout,
        memory_bytes=parse_size(args.memory_limit, name="--memory-limit"),
        max_procs=args.max_procs,
        max_file_size=parse_size(args.max_file_size, name="--max-file-size"),
        max_output=parse_size(args.max_output, name="--max-output"),
    )
    return RunSettings(limits=limits, sandbox=args.sandbox, image_name=args.image_name, env=env,
                       warm=getattr(args, "warm", True))
