"""The ``arenabench`` command: a thin dispatcher over sub-command modules.

Each sub-command lives in its own module exposing ``main(argv: list[str] | None) -> int``;
the module is imported only when its command runs, so ``arenabench detect`` never loads
the renderer and the pipeline package stays free of generator imports.
"""

from __future__ import annotations

import importlib
import sys

#: command name -> (module, one-line description)
COMMANDS: dict[str, tuple[str, str]] = {
    "detect": ("arenabench.detect", "run the detection pipeline on one image (competition I/O)"),
    "doctor": ("arenabench.doctor", "check Python, OpenCV/aruco, pyrender and off-screen OpenGL"),
    "generate": ("arenabench.generator.cli", "render a dataset of scenes with exact ground truth"),
    "presets": ("arenabench.generator.presets_cli", "list the scene presets"),
    "fit": ("arenabench.generator.fit_cli", "fit a scene file to a real arena image"),
    "render": ("arenabench.generator.render_cli", "render one scene file with its ground truth"),
    "contact-sheet": ("arenabench.generator.contact_sheet", "tile a preset's scenes in one image"),
    "eval": ("arenabench.eval.cli", "score a pipeline on a dataset (reports, JUnit, exit codes)"),
    "bench": ("arenabench.eval.bench_cli", "measure generation and scoring throughput here"),
    "sweep": ("arenabench.eval.sweep_cli", "vary scene parameters, score, find breakdown points"),
    "grade": ("arenabench.eval.grade_cli", "grade many teams' submissions, rank them (resumable)"),
    "demo": ("arenabench.eval.demo", "generate a small eyrc set, score the reference pipeline"),
}


def _usage() -> str:
    width = max(len(name) for name in COMMANDS)
    lines = ["usage: arenabench COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<{width}}  {desc}" for name, (_, desc) in COMMANDS.items()]
    lines += ["", "Run 'arenabench COMMAND --help' for a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``arenabench COMMAND ...`` to the command's module and return its exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in {"-h", "--help", "help"}:
        print(_usage())
        return 0
    if args[0] in {"-V", "--version"}:
        from arenabench import __version__

        print(f"arenabench {__version__}")
        return 0
    name, rest = args[0], args[1:]
    if name not in COMMANDS:
        print(f"arenabench: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    module = importlib.import_module(COMMANDS[name][0])
    return int(module.main(rest) or 0)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
