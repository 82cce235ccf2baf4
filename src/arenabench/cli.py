"""The ``arenabench`` command: a thin dispatcher over sub-command modules.

Each sub-command lives in its own module exposing ``main(argv: list[str] | None) -> int``;
the module is imported only when its command runs, so ``arenabench detect`` never loads
the renderer and the pipeline package stays free of generator imports.

Every command exits quietly when whoever reads its output goes away
(``arenabench detect --json ... | head -1``): see :func:`run`.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Callable

from arenabench.exitcodes import ExitCode
from arenabench.suggest import did_you_mean

#: command name -> (module, one-line description)
COMMANDS: dict[str, tuple[str, str]] = {
    "detect": ("arenabench.detect", "run the detection pipeline on one image (competition I/O)"),
    "doctor": ("arenabench.doctor", "check Python, OpenCV/aruco, pyrender and off-screen OpenGL"),
    "generate": ("arenabench.generator.commands.generate",
                 "render a dataset of scenes with exact ground truth"),
    "presets": ("arenabench.generator.commands.presets", "list the scene presets"),
    "fit": ("arenabench.generator.commands.fit", "fit a scene file to a real arena image"),
    "twin": ("arenabench.generator.commands.twin",
             "a twin of an arena from one real image: preset, fitted scene, pinned/open report"),
    "render": ("arenabench.generator.commands.render",
               "render one scene file with its ground truth"),
    "contact-sheet": ("arenabench.generator.commands.contact_sheet",
                      "tile a preset's scenes in one image"),
    "eval": ("arenabench.eval.commands.eval",
             "score a pipeline on a dataset (reports, JUnit, exit codes)"),
    "bench": ("arenabench.eval.commands.bench", "measure generation and scoring throughput here"),
    "sweep": ("arenabench.eval.commands.sweep",
              "vary scene parameters, score, find breakdown points"),
    "grade": ("arenabench.eval.commands.grade",
              "grade many teams' submissions, rank them (resumable)"),
    "check": ("arenabench.eval.commands.check",
              "know before you submit: a script on the twin, verdict"),
    "demo": ("arenabench.eval.commands.demo",
             "generate a small eyrc set, score the reference pipeline"),
}



def _usage() -> str:
    width = max(len(name) for name in COMMANDS)
    lines = ["usage: arenabench [--version] [--help] COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<{width}}  {desc}" for name, (_, desc) in COMMANDS.items()]
    lines += [
        "",
        "options:",
        "  -h, --help     this list ('arenabench help COMMAND' = 'arenabench COMMAND --help')",
        "  -V, --version  print the version and exit",
        "",
        "Run 'arenabench COMMAND --help' for a command's options.",
    ]
    return "\n".join(lines)


def _unknown(name: str) -> int:
    hint = did_you_mean(name, COMMANDS)
    print(f"arenabench: error: unknown command {name!r}{hint} (commands: "
          f"{', '.join(COMMANDS)}; 'arenabench --help' says what each does)", file=sys.stderr)
    return ExitCode.USAGE


def _dispatch(args: list[str]) -> int:
    if not args:
        print(_usage(), file=sys.stderr)
        return ExitCode.USAGE
    if args[0] in {"-h", "--help"}:
        print(_usage())
        return ExitCode.OK
    if args[0] == "help":
        if len(args) == 1:
            print(_usage())
            return ExitCode.OK
        if args[1] not in COMMANDS:
            return _unknown(args[1])
        args = [args[1], "--help"]
    if args[0] in {"-V", "--version"}:
        from arenabench import __version__

        print(f"arenabench {__version__}")
        return ExitCode.OK
    name, rest = args[0], args[1:]
    if name not in COMMANDS:
        return _unknown(name)
    module = importlib.import_module(COMMANDS[name][0])
    return int(module.main(rest) or 0)


def run(entry: Callable[[], int | None]) -> int:
    """Call a command's ``entry()`` and return its exit status, quietly giving up when the
    reader of stdout has gone away (a closed pipe): no traceback, exit status 141. A command
    that returns 0 after a stop signal (:func:`arenabench.interrupts.received`) exits with
    that signal's status.

    Parameters
    ----------
    entry : callable
        The command, called with no arguments.

    Returns
    -------
    int
    """
    # only a command that imported arenabench.interrupts can have received a stop (a
    # command such as detect, run once per image, does not pay for importing it)
    if (interrupts := sys.modules.get("arenabench.interrupts")) is not None:
        interrupts.forget_received()
    try:
        rc = int(entry() or 0)
        sys.stdout.flush()
        interrupts = sys.modules.get("arenabench.interrupts")
        if rc == 0 and interrupts is not None and (signum := interrupts.received()) is not None:
            # the stop reached no checkpoint before the work ended: its outputs are whole,
            # but a stopped command does not exit 0
            print(f"arenabench: {interrupts.signal_name(signum)} arrived as the command "
                  "finished; its outputs are complete", file=sys.stderr)
            return interrupts.exit_code(signum)
        return rc
    except KeyboardInterrupt:  # Ctrl-C outside a command's own handling (or after it)
        import signal

        from arenabench.interrupts import exit_code

        return exit_code(signal.SIGINT)
    except BrokenPipeError:
        # Python flushes stdout again at exit: point it at /dev/null so that flush is silent.
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return ExitCode.BROKEN_PIPE


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``arenabench COMMAND ...`` to the command's module and return its exit status.

    No command prints the usage on stderr and returns 2; ``help COMMAND`` is
    ``COMMAND --help``; an unknown command gets a "did you mean" hint.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    rc = run(lambda: _dispatch(args))
    if argv is None:  # the process's entry point: the status is decided, the process ends
        _ignore_late_stop_signals()
    return rc


def _ignore_late_stop_signals() -> None:
    """A Ctrl-C or SIGTERM after the command has returned (while the interpreter shuts down:
    its pools, OpenGL) must not turn the decided status into a traceback or death by signal
    (a second Ctrl-C 50 ms after the first)."""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            signal.signal(sig, signal.SIG_IGN)
        except (OSError, ValueError):  # not the main thread
            pass


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
