"""Every command's parser and shared options, declared once.

A command builds its parser as :class:`CommandParser` (one help formatter, one line per usage
error, "did you mean" for mistyped options and choices, exit status 2) and adds the options
that several commands share with the ``add_*`` builders below; each builder takes its default
from the one declaration of that default and checks its value with one :class:`Rule`, so
``--timeout inf`` is refused with the same line by ``eval``, ``sweep`` and ``grade``::

    p = CommandParser(prog="arenabench mycmd", description="...")
    add_out(p, required=True)
    add_workers(p, help="local processes")
    add_scheduler(p)
    add_no_progress(p)
    args = p.parse_args(argv)      # usage error: one line on stderr, SystemExit(2)
    ...
    return p.fail("--thing: why")  # a usage error found after parsing: one line, returns 2

A command's ``main`` catches the ``SystemExit`` of :meth:`CommandParser.parse_args` and returns
its code (0 for ``--help``, 2 for a usage error, the line already printed). The exit statuses
every command shares are declared here; :func:`lock_out` holds an output folder's lock and
:func:`write_failure` words a failed write (``disk full: ...``).
Each builder tags the action it adds (``action.shared_option``), so a test can check that no
command re-declares a shared option by hand (``tests/core/test_cliopts.py``).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arenabench.clihelp import HelpFormatter
from arenabench.competition import DEFAULT_TOLERANCE
from arenabench.exitcodes import ExitCode
from arenabench.limits import (
    DEFAULT_MAX_DISK,
    DEFAULT_MAX_FILE_SIZE,
    DEFAULT_MAX_OUTPUT,
    DEFAULT_MAX_PROCS,
    DEFAULT_MEMORY_BYTES,
    DEFAULT_TIMEOUT_S,
    MAX_DATASET_SCENES,
    MAX_RUN_BYTES,
    MAX_RUN_PROCS,
    MAX_TIMEOUT_S,
    MAX_WORKERS,
    MIN_TIMEOUT_S,
)
from arenabench.plain_numbers import plain_number
from arenabench.suggest import did_you_mean

#: Options that more than one command has; each is added by the builder of the same name.
SHARED_OPTIONS: tuple[str, ...] = (
    "--out", "--workers", "--scheduler", "--no-progress", "--tolerance", "--area-reference",
    "--timeout", "--memory-limit", "--max-file-size", "--max-output", "--max-disk",
    "--max-procs", "--sandbox", "--count", "--seed", "--cmd", "--output", "--formats",
    "--preset", "--set",
)


# ------------------------------------------------------------------------------------ rules

@dataclass(frozen=True)
class Rule:
    """One validation rule of a number: its kind and closed (or left-open) bounds.

    Parameters
    ----------
    kind : {"int", "float"}
        ``float`` values must also be finite.
    lo, hi : float
        Bounds; ``hi`` is always included, ``lo`` unless ``lo_open``.
    lo_open : bool
        ``lo`` itself is refused (``--timeout`` must be > 0).
    """

    kind: str
    lo: float
    hi: float
    lo_open: bool = False

    def describe(self) -> str:
        """``"an integer in [1, 256]"`` / ``"a finite number in (0, 86400]"``."""
        what = "an integer" if self.kind == "int" else "a finite number"
        lo, hi = ((int(self.lo), int(self.hi)) if self.kind == "int"
                  else (f"{self.lo:g}", f"{self.hi:g}"))
        return f"{what} in {'(' if self.lo_open else '['}{lo}, {hi}]"

    def check(self, value: Any, *, name: str) -> int | float:
        """``value`` as an int or float when it keeps the rule.

        Raises
        ------
        ValueError
            ``"<name> must be <describe()>, got <value>"``.
        """
        try:
            if isinstance(value, bool):
                raise ValueError
            if isinstance(value, str):  # as typed: plain ASCII decimal only
                number: int | float = plain_number(value, self.kind)
            elif self.kind == "int":
                number = int(value) if isinstance(value, int) else int(str(value))
            else:
                number = float(value)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"{name} must be {self.describe()}, got {value!r}") from None
        ok = (math.isfinite(number) and (number > self.lo if self.lo_open else number >= self.lo)
              and number <= self.hi)
        if not ok:
            raise ValueError(f"{name} must be {self.describe()}, got {value!r}")
        return number

    def argtype(self, name: str) -> Callable[[str], int | float]:
        """The ``type=`` of an argparse option that keeps this rule."""

        def convert(text: str) -> int | float:
            try:
                return self.check(text, name=name)
            except ValueError:
                raise argparse.ArgumentTypeError(
                    f"must be {self.describe()}, got {text!r}") from None

        convert.__name__ = name.lstrip("-").replace("-", "_")
        return convert


#: ``--workers`` of every command.
WORKERS_RULE = Rule("int", 1, MAX_WORKERS)
#: ``--tolerance``: the largest passing ``|area_rel_err|``, a fraction.
TOLERANCE_RULE = Rule("float", 0.0, 1.0)
#: ``--timeout``: seconds per image of an external run.
TIMEOUT_RULE = Rule("float", MIN_TIMEOUT_S, MAX_TIMEOUT_S)
#: ``--max-procs``: processes one external run may have at once (0: no process limit).
MAX_PROCS_RULE = Rule("int", 0, MAX_RUN_PROCS)
#: ``grade --give-up-after N``: timeouts in a row after which a team's later images are not
#: run (0: never).
GIVE_UP_AFTER_RULE = Rule("int", 0, MAX_DATASET_SCENES)
#: Byte sizes of run limits (``--memory-limit``, ``--max-file-size``, ``--max-output``).
BYTES_RULE = Rule("int", 1, MAX_RUN_BYTES)

#: How external commands are contained: ``auto`` uses bubblewrap when it is installed and
#: works (else ``none``, with a warning), ``bwrap`` requires it, ``none`` runs without
#: namespaces (private directory, limits and process cleanup still apply).
SANDBOX_MODES: tuple[str, ...] = ("auto", "bwrap", "none")
DEFAULT_SANDBOX = "auto"

_SIZE_RE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([kKmMgGtTpP]?)(?:i?[bB])?\s*$", re.ASCII)
_SIZE_UNITS = {"": 1, "k": 1024, "m": 1024**2, "g": 1024**3, "t": 1024**4, "p": 1024**5}


def parse_size(text: str | int, *, name: str) -> int:
    """Parse ``"2G"``, ``"64M"``, ``"512k"`` or a plain byte count into bytes (at most
    :data:`~arenabench.limits.MAX_RUN_BYTES`).

    Parameters
    ----------
    text : str or int
        The size; suffixes k/M/G/T/P are powers of 1024, an optional trailing ``B``/``iB``.
    name : str, keyword-only
        Option name for the error message.

    Raises
    ------
    ValueError
        Naming ``name`` and the value, when it is not a size in [1 byte, 1P].
    """
    if isinstance(text, int) and not isinstance(text, bool):
        return int(BYTES_RULE.check(text, name=name))
    m = _SIZE_RE.match(str(text))
    if not m:
        raise ValueError(f"{name}: not a size: {text!r} (use e.g. 2G, 64M, 1048576)")
    value = int(float(m.group(1)) * _SIZE_UNITS[m.group(2).lower()])
    if not 1 <= value <= MAX_RUN_BYTES:
        raise ValueError(f"{name} must be a size in [1, 1P] bytes, got {text!r}")
    return value


def format_size(value: int) -> str:
    """The shortest exact spelling :func:`parse_size` reads back (``2147483648`` -> ``"2G"``)."""
    for suffix, unit in (("P", 1024**5), ("T", 1024**4), ("G", 1024**3), ("M", 1024**2),
                         ("k", 1024)):
        if value % unit == 0:
            return f"{value // unit}{suffix}"
    return str(value)


def _size_type(name: str) -> Callable[[str], int]:
    def convert(text: str) -> int:
        try:
            return parse_size(text, name=name)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix(f"{name}: ")
                                             .removeprefix(f"{name} ")) from None

    convert.__name__ = "size"
    return convert


# ----------------------------------------------------------------------------------- parser


def _plain_int(text: str) -> int:
    return int(plain_number(text, "int"))


def _plain_float(text: str) -> float:
    return float(plain_number(text, "float"))


_plain_int.__name__, _plain_float.__name__ = "int", "float"  # argparse: "invalid int value"


class CommandParser(argparse.ArgumentParser):
    """The argument parser of every ``arenabench`` command.

    The same help formatter (:class:`~arenabench.clihelp.HelpFormatter`); a usage error is one
    line on stderr, ``<prog>: error: <message>``, with a "did you mean" hint for a mistyped
    option or choice, and exit status 2 (``SystemExit(2)`` from :meth:`parse_args`; after
    parsing, :meth:`fail` prints the same line and returns 2). Checks that span options run
    after parsing (:meth:`add_check`): ``--workers`` with ``--scheduler`` is refused, and
    ``--workers`` not given becomes the usable cores unless a ``--scheduler`` is given.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)
        self._checks: list[Callable[[argparse.Namespace], str | None]] = []
        # ``type=int`` / ``type=float`` read plain ASCII decimal only (:func:`plain_number`)
        self.register("type", int, _plain_int)
        self.register("type", float, _plain_float)

    def add_check(self, check: Callable[[argparse.Namespace], str | None]) -> None:
        """Run ``check(namespace)`` after parsing; a string it returns is a usage error."""
        self._checks.append(check)

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        self._refuse_mistyped(sys.argv[1:] if args is None else list(args))
        namespace, extras = super().parse_known_args(args, namespace)
        for check in self._checks:
            problem = check(namespace)
            if problem:
                self.error(problem)
        return namespace, extras

    def parse_or_status(self, args: list[str] | None = None) -> argparse.Namespace | int:
        """:meth:`parse_args`, with ``--help`` (0) and a usage error (2, its line printed)
        returned as the command's exit status instead of raised as ``SystemExit``."""
        try:
            return self.parse_args(args)
        except SystemExit as exc:
            return int(exc.code or 0)

    def error(self, message: str) -> None:  # type: ignore[override]
        """Print one line naming the problem (with a hint) and exit with status 2."""
        self.fail(message + self._hint(message))
        raise SystemExit(ExitCode.USAGE)

    def fail(self, message: str) -> int:
        """Print ``<prog>: error: <message>`` (one line) on stderr; return 2."""
        return usage_error(self.prog, message)

    def _refuse_mistyped(self, words: list[str]) -> None:
        """A mistyped option (``--imge``) is the error, with its hint, even when argparse
        would first complain of a required option it then lacks (``--image``)."""
        known = self._options()
        for word in words:
            if word == "--":
                return
            name = word.split("=", 1)[0]
            if (name.startswith("--") and len(name) > 2
                    and not any(k.startswith(name) for k in known)
                    and did_you_mean(name, known)):
                self.error(f"unrecognized arguments: {word}")

    def _options(self) -> list[str]:
        return [s for a in self._actions for s in a.option_strings if s.startswith("--")]

    def _hint(self, message: str) -> str:
        m = re.match(r"unrecognized arguments: (.*)$", message)
        if m:
            for word in m.group(1).split():
                if word.startswith("--"):
                    hint = did_you_mean(word.split("=", 1)[0], self._options())
                    if hint:
                        return hint
            return ""
        m = re.match(r"argument (\S+?)(?:/\S+)?: invalid choice: '(.*)' \(choose from", message)
        if m:
            for action in self._actions:
                if m.group(1) in action.option_strings or m.group(1) == action.dest:
                    return did_you_mean(m.group(2), [str(c) for c in action.choices or ()])
        return ""


@contextmanager
def lock_out(out: str | Path | None, *, option: str = "--out") -> Iterator[None]:
    """Hold the exclusive lock of the output folder ``out`` (the one ``generate`` takes,
    :func:`arenabench.fileio.lock_folder`, ``.arenabench.lock``) while the body writes into
    it; ``None``: nothing to lock. A folder this creates and leaves empty is removed.

    Raises
    ------
    arenabench.fileio.FolderLockedError
        At once when another run holds it: ``"--out D: D is being written by another run
        (pid ..., command); wait for it to finish or use another --out"``.
    """
    import shlex

    from arenabench.fileio import FolderLockedError, lock_folder

    if out is None:
        yield
        return
    root = Path(out)
    created = not root.exists()
    try:
        try:
            held = lock_folder(root, command=shlex.join(sys.argv)[:300])
            held.__enter__()
        except FolderLockedError as exc:
            raise FolderLockedError(f"{option} {root}: {exc}; wait for it to finish or use "
                                    f"another {option}") from None
        try:
            yield
        finally:
            held.__exit__(None, None, None)
    finally:
        try:
            if created and not any(root.iterdir()):
                root.rmdir()
        except OSError:
            pass


def write_failure(exc: OSError, where: str | Path) -> str:
    """The one line for an output that could not be written: ``"disk full: FILE: No space
    left on device (free some space or use another --out)"`` for ENOSPC / EDQUOT, else
    ``"cannot write FILE: why"`` (the command then exits with status 1)."""
    import errno

    name = exc.filename or where
    why = exc.strerror or str(exc)
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"disk full: {name}: {why} (free some space or use another --out)"
    return f"cannot write {name}: {why}"


def _tag(action: argparse.Action, builder: str) -> argparse.Action:
    action.shared_option = builder  # type: ignore[attr-defined]
    return action


# --------------------------------------------------------------------------------- builders


def add_out(parser: argparse.ArgumentParser, *, required: bool = False,
            default: str | Path | None = None, help: str = "output folder") -> argparse.Action:
    """``--out PATH`` (a :class:`~pathlib.Path`)."""
    kwargs: dict[str, Any] = {"required": True} if required else {
        "default": None if default is None else Path(default)}
    return _tag(parser.add_argument("--out", type=Path, help=help, **kwargs), "add_out")


def add_workers(parser: CommandParser, *, help: str = "parallel workers") -> argparse.Action:
    """``--workers N``: an integer in [1, MAX_WORKERS]; not given, the usable cores
    (:func:`arenabench.workers.usable_cores`), or ``None`` when ``--scheduler`` is given."""
    from arenabench.workers import usable_cores

    action = parser.add_argument(
        "--workers", type=WORKERS_RULE.argtype("--workers"), default=None, metavar="N",
        help=f"{help} (default: the usable cores, {usable_cores()}; at most {MAX_WORKERS})",
    )

    def fill(ns: argparse.Namespace) -> str | None:
        if ns.workers is None and getattr(ns, "scheduler", None) is None:
            ns.workers = usable_cores()
        return None

    parser.add_check(fill)
    return _tag(action, "add_workers")


def add_scheduler(parser: CommandParser, *, help: str = "run on an existing Dask cluster "
                  "(see docs/scale-out.md)") -> argparse.Action:
    """``--scheduler tcp://HOST:PORT``; with ``--workers`` a usage error (the cluster's
    workers do the work). Add it before :func:`add_workers`."""
    action = parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                                 help=help)

    def exclusive(ns: argparse.Namespace) -> str | None:
        if ns.scheduler is not None and getattr(ns, "workers", None) is not None:
            return ("--workers and --scheduler exclude each other (the cluster's workers do "
                    "the work)")
        return None

    parser.add_check(exclusive)
    return _tag(action, "add_scheduler")


def add_no_progress(parser: argparse.ArgumentParser, *,
                    help: str = "no progress output") -> argparse.Action:
    """``--no-progress``."""
    return _tag(parser.add_argument("--no-progress", action="store_true", help=help),
                "add_no_progress")


def add_tolerance(parser: argparse.ArgumentParser) -> argparse.Action:
    """``--tolerance X``: largest passing ``|area_rel_err|``, finite, in [0, 1]; default
    :data:`arenabench.competition.DEFAULT_TOLERANCE`."""
    return _tag(parser.add_argument(
        "--tolerance", type=TOLERANCE_RULE.argtype("--tolerance"), default=DEFAULT_TOLERANCE,
        help="max |area_rel_err| to pass"), "add_tolerance")


def add_area_reference(parser: argparse.ArgumentParser) -> argparse.Action:
    """``--area-reference {visible,footprint,contour}``."""
    from arenabench.gtrecord import AREA_REFERENCES, DEFAULT_AREA_REFERENCE  # imports NumPy

    return _tag(parser.add_argument(
        "--area-reference", choices=tuple(AREA_REFERENCES), default=DEFAULT_AREA_REFERENCE,
        help="GT area the answer is compared with: visible (the silhouettes a camera-side "
        "segmentation sees), footprint (the boxes' floor area) or contour (what "
        "cv2.contourArea of the pixelated silhouettes gives, about half a perimeter less)"),
        "add_area_reference")


def count_rule(maximum: int, *, minimum: int = 1) -> Rule:
    """The rule of a count option: an integer in [minimum, maximum]."""
    return Rule("int", minimum, maximum)


def add_count(parser: argparse.ArgumentParser, flag: str = "--count", *,
              maximum: int = MAX_DATASET_SCENES, minimum: int = 1, default: int | None = None,
              required: bool = False, help: str = "number of scenes") -> argparse.Action:
    """A count option (``--count``, ``--rss-renders``, ``--refine-rounds``...): an integer in
    [minimum, maximum]."""
    kwargs: dict[str, Any] = {"required": True} if required else {"default": default}
    return _tag(parser.add_argument(flag, type=count_rule(maximum, minimum=minimum).argtype(flag),
                                    metavar="N", help=help, **kwargs), "add_count")


def add_seed(parser: argparse.ArgumentParser, *, random: bool = False,
             help: str = "seed") -> argparse.Action:
    """``--seed N``: an integer in [0, :data:`arenabench.seeds.MAX_SEED`] in plain decimal,
    default 0; with ``random``, also the word ``random`` (kept as the text ``"random"``: the
    command draws the seed, :func:`arenabench.seeds.random_seed`, and says which)."""
    from arenabench.seeds import RANDOM_SEED_BITS, parse_seed

    def seed(text: str) -> int | str:
        if random and text.strip().lower() == "random":
            return "random"
        try:  # "random" is taken above: here it only words the error
            return parse_seed(text, allow_random=random)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(
                str(exc).removeprefix("--seed: ").removeprefix("--seed ")) from None

    also = (", or 'random': 128 bits from the operating system, printed and recorded"
            if random else "")
    return _tag(parser.add_argument(
        "--seed", type=seed, default=0, metavar="N",
        help=f"{help}: an integer in [0, 2**{RANDOM_SEED_BITS} - 1]{also} (default: 0)"),
        "add_seed")


def add_cmd(parser: argparse.ArgumentParser, *, default: str | None = None,
            help: str = "external command per image, e.g. 'python3 map.py --image {image}'",
            **kwargs: Any) -> argparse.Action:
    """``--cmd TEMPLATE``: a command line per image (:mod:`arenabench.cmdtemplate`; checked
    with the run options, :func:`cmd_template_problem`). ``kwargs`` go to ``add_argument``
    (``sweep`` collects ``--cmd`` and ``--pipeline`` in order with an action of its own)."""
    if default is not None:
        help = f"{help} (default: %(default)r)"
    return _tag(parser.add_argument("--cmd", default=default, metavar="TEMPLATE", help=help,
                                    **kwargs), "add_cmd")


def add_output_mode(parser: argparse.ArgumentParser, modes: Sequence[str]) -> argparse.Action:
    """``--output MODE``: how a ``--cmd`` answers, one of ``modes``
    (:data:`arenabench.eval.runs.OUTPUT_MODES`), the first by default."""
    return _tag(parser.add_argument(
        "--output", choices=tuple(modes), default=modes[0],
        help="how --cmd answers: obstacles.txt in its cwd (default) or a JSON line on stdout"),
        "add_output_mode")


def formats_problem(names: Sequence[str], known: Sequence[str]) -> str | None:
    """Why ``names`` is no choice of report formats among ``known`` (none named, or one
    unknown, with a "did you mean"), or ``None``: the one rule of ``--formats``
    (:func:`formats_rule`) and of the harness's ``formats=`` arguments."""
    if not names:
        return f"no format named (known: {', '.join(known)})"
    bad = [f for f in names if f not in known]
    if bad:
        return (f"unknown {', '.join(map(repr, bad))}{did_you_mean(bad[0], known)} "
                f"(known: {', '.join(known)})")
    return None


def formats_rule(known: Sequence[str]) -> Callable[[str], tuple[str, ...]]:
    """The ``type=`` of ``--formats``: a comma-separated, non-empty list of ``known`` names
    (:func:`formats_problem`), as a tuple in the order given (a name given twice counts
    once)."""
    def formats(text: str) -> tuple[str, ...]:
        names = tuple(dict.fromkeys(f.strip() for f in text.split(",") if f.strip()))
        problem = formats_problem(names, known)
        if problem:
            raise argparse.ArgumentTypeError(problem if names else f"{text!r}: {problem}")
        return names

    return formats


def add_formats(parser: argparse.ArgumentParser, known: Sequence[str], *,
                help: str = "report files to write") -> argparse.Action:
    """``--formats a,b``: which of the ``known`` report files to write (all by default),
    parsed by :func:`formats_rule`."""
    return _tag(parser.add_argument(
        "--formats", type=formats_rule(known), default=tuple(known), metavar="LIST",
        help=f"{help}, comma-separated, of {','.join(known)} (default: all)"), "add_formats")


def add_preset(parser: Any, *, resolve: Callable[[str], Any], default: str | None,
               names: Sequence[str] = (), flag: str = "--preset",
               help: str = "scene preset") -> argparse.Action:
    """``--preset NAME|FILE``: a built-in preset's name or a preset file (TOML or JSON,
    docs/formats.md "Preset files"), turned into the preset by ``resolve`` when parsed (the
    generator's :func:`arenabench.generator.parameters.presets.resolve_preset`: a value naming an
    existing file is a preset file, anything else a name). Its refusal (an unknown name with
    "did you mean", a missing file, a file's bad key or value) is the usage error's one line.

    Parameters
    ----------
    parser : argparse.ArgumentParser or argument group
        Where the option goes (a mutually exclusive group too).
    resolve : callable, keyword-only
        ``str -> preset``; raises ``ValueError`` with the one line.
    default : str or None, keyword-only
        The default preset's name (resolved too when the option is not given), or ``None``.
    names : sequence of str, keyword-only
        The built-in presets' names, for the help.
    flag : str, keyword-only
        The option (``presets --show`` takes a preset the same way).
    """
    def convert(text: str) -> Any:
        try:
            return resolve(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(" ".join(str(exc).split())) from None

    convert.__name__ = "preset"
    known = f"a built-in preset ({', '.join(names)}) or " if names else ""
    return _tag(parser.add_argument(
        flag, type=convert, default=default, metavar="NAME|FILE",
        help=f"{help}: {known}a preset file (.toml or .json; docs/formats.md)"
        + (f" (default: {default})" if default else "")), "add_preset")


def add_set(parser: argparse.ArgumentParser, *,
            help: str = "override a preset parameter") -> argparse.Action:
    """``--set KEY=VALUE`` (repeatable) into ``overrides``: the raw texts, parsed and checked
    by the generator against each parameter's declaration
    (:func:`arenabench.generator.parameters.param_values.parse_overrides`)."""
    return _tag(parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help=f"{help} (repeatable; 'arenabench presets --params' lists them)"), "add_set")


def add_timeout(parser: Any, *, default: float = DEFAULT_TIMEOUT_S,
                help: str = "wall-clock seconds per image") -> argparse.Action:
    """``--timeout SECONDS``: a plain decimal number in the range of
    :data:`TIMEOUT_RULE` (at most :data:`arenabench.limits.MAX_TIMEOUT_S`); ``parser`` may be
    an argument group."""
    return _tag(parser.add_argument(
        "--timeout", type=TIMEOUT_RULE.argtype("--timeout"), default=default,
        help=f"{help}, at most {MAX_TIMEOUT_S:g} (default: %(default)s)"), "add_timeout")


def _cmd_templates(ns: argparse.Namespace) -> list[str]:
    cmd = getattr(ns, "cmd", None)
    pipes = getattr(ns, "pipes", None) or ()  # sweep: (kind, value) in the order given
    return ([cmd] if isinstance(cmd, str) else []) + [v for k, v in pipes if k == "cmd"]


def cmd_template_problem(ns: argparse.Namespace, *,
                         placeholders: Collection[str] | None = None,
                         refused: Mapping[str, str] | None = None) -> str | None:
    """A ``--cmd`` template with a placeholder the command does not accept (``placeholders``,
    default :data:`arenabench.cmdtemplate.RUN_PLACEHOLDERS`; ``refused``: name -> why) or
    without ``{image}`` (every image would fail the same way) is a usage error; ``{image}``
    may be left out when ``--image-name`` names the file the command opens by itself
    (:mod:`arenabench.cmdtemplate`)."""
    import shlex

    from arenabench.cmdtemplate import IMAGE, RUN_PLACEHOLDERS, template_problem
    from arenabench.cmdtemplate import placeholders as names_in

    for template in _cmd_templates(ns):
        problem = template_problem(template, placeholders or RUN_PLACEHOLDERS,
                                   refused=refused)
        if problem:
            return f"--cmd {template!r}: {problem}"
        if getattr(ns, "image_name", None):
            continue
        try:
            args = shlex.split(template)
        except ValueError:  # unbalanced quotes: the runner's own one-line error says so
            continue
        if not any(IMAGE in names_in(a) for a in args):
            return (f"--cmd {template!r}: the template has no {{{IMAGE}}} (the image's path; "
                    "or give --image-name for a command that opens a fixed name)")
    return None


def add_run_options(parser: CommandParser, *, placeholders: Collection[str] | None = None,
                    refused: Mapping[str, str] | None = None) -> None:
    """The options of external runs (``--timeout``, the limits, ``--sandbox``, ``--env``);
    :func:`arenabench.eval.runs.limits.run_settings_from_args` reads them. A ``--cmd``
    template may hold only the command's ``placeholders`` (default
    :data:`arenabench.cmdtemplate.RUN_PLACEHOLDERS`) and must hold ``{image}``
    (:func:`cmd_template_problem`)."""
    parser.add_check(lambda ns: cmd_template_problem(ns, placeholders=placeholders,
                                                     refused=refused))
    g = parser.add_argument_group("external command runs (--cmd)")
    add_timeout(g)
    _tag(g.add_argument("--memory-limit", type=_size_type("--memory-limit"),
                        default=format_size(DEFAULT_MEMORY_BYTES),
                        help="address space per process, e.g. 2G, 512M (default: %(default)s)"),
         "add_run_options")
    _tag(g.add_argument("--max-procs", type=MAX_PROCS_RULE.argtype("--max-procs"),
                        default=DEFAULT_MAX_PROCS,
                        help="processes a run may have at once; 0 = no process limit "
                        "(default: %(default)s)"),
         "add_run_options")
    _tag(g.add_argument("--max-file-size", type=_size_type("--max-file-size"),
                        default=format_size(DEFAULT_MAX_FILE_SIZE),
                        help="largest file a run may write (default: %(default)s)"),
         "add_run_options")
    _tag(g.add_argument("--max-output", type=_size_type("--max-output"),
                        default=format_size(DEFAULT_MAX_OUTPUT),
                        help="bytes of stdout and of stderr kept per run, the tail "
                        "(default: %(default)s)"), "add_run_options")
    _tag(g.add_argument("--max-disk", type=_size_type("--max-disk"),
                        default=format_size(DEFAULT_MAX_DISK),
                        help="what a run may write in all, in its folder, /tmp and /dev/shm "
                        "(a tmpfs of this size under bubblewrap; default: %(default)s)"),
         "add_run_options")
    _tag(g.add_argument("--sandbox", choices=SANDBOX_MODES, default=DEFAULT_SANDBOX,
                        help="auto: bubblewrap when it works here (else a warning and none); "
                        "bwrap: require it; none: no namespaces (default: %(default)s)"),
         "add_run_options")
    g.add_argument("--image-name", default=None,
                   help="file name of the image copy the command sees (default: image + its "
                   "extension)")
    g.add_argument("--env", action="append", default=[], metavar="K=V",
                   help="environment variable for the command (repeatable); nothing else is "
                   "passed on besides PATH, HOME, LANG, LC_ALL and TMPDIR")
    g.add_argument("--no-warm", dest="warm", action="store_false",
                   help="start a new Python process per image for a Python script (default: "
                   "one warm interpreter per command, which forks a fresh process per image; "
                   "see docs/warm-interpreter.md)")


# ----------------------------------------------------------------------------- usage errors


def usage_error(prog: str, message: str) -> int:
    """Print ``<prog>: error: <message>`` on stderr, as one line (white space folded); return
    2. Every command's usage error after parsing (and :meth:`CommandParser.fail`) says it so.
    """
    print(f"{prog}: error: {' '.join(str(message).split())}", file=sys.stderr)
    return ExitCode.USAGE


def output_problem(path: str | Path, *, option: str = "--out", file: bool = False,
                   allow_special: bool = False, own: Collection[str] | None = None,
                   what: str = "", inputs: Sequence[tuple[str, str | Path]] = ()) -> str | None:
    """Why ``path`` cannot be written, as the usage error's message (``--out OUT: why``), or
    ``None`` when it can: a folder (:func:`arenabench.fileio.check_output_dir`: never ``/``
    nor a folder directly in it) or, with ``file``, a file
    (:func:`arenabench.fileio.check_output_file`, ``allow_special`` for ``/dev/stdout`` and
    the like). With ``own`` (the names a command writes into its folder, ``what`` them in
    words) and ``inputs`` (``("DATASET", path)``: folders the command reads), the folder of a
    command's reports (:func:`arenabench.fileio.check_report_dir`): not an input nor inside
    one, and new, empty or holding an earlier output of the command."""
    from arenabench.fileio import (
        OutputPathError,
        check_output_dir,
        check_output_file,
        check_report_dir,
    )

    try:
        if file:
            check_output_file(path, allow_special=allow_special)
        elif own is not None:
            check_report_dir(path, own=own, what=what, inputs=inputs)
        else:
            check_output_dir(path)
    except OutputPathError as exc:
        return f"{option} {path}: {exc}"
    return None
