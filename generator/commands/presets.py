"""``arenabench presets``: list the scene presets and their parameters; write one as a preset
file."""

from __future__ import annotations

import sys

from arenabench.cliopts import CommandParser, add_preset
from arenabench.exitcodes import ExitCode
from arenabench.generator.parameters.param_values import format_value
from arenabench.generator.parameters.params import PARAMETERS
from arenabench.generator.parameters.preset_files import preset_to_json, preset_to_toml, show_lines
from arenabench.generator.parameters.presets import PRESETS, preset_names, resolve_preset

#: ``--format`` of ``--show``: ``KEY=VALUE`` lines, or a preset file.
SHOW_FORMATS = ("text", "toml", "json")


def build_parser() -> CommandParser:
    """The ``arenabench presets`` argument parser."""
    p = CommandParser(prog="arenabench presets",
                      description="List scene presets and their parameters; --show NAME "
                                  "--format toml writes one as a preset file.")
    g = p.add_mutually_exclusive_group()
    add_preset(g, resolve=resolve_preset, default=None, names=preset_names(), flag="--show",
               help="print every parameter of this preset")
    g.add_argument("--params", action="store_true", help="list every parameter with its help")
    p.add_argument("--format", choices=SHOW_FORMATS, default=None,
                   help="with --show: KEY=VALUE lines (text, the default), or a preset file "
                        "in TOML or JSON that generates the same bytes as the preset")
    p.add_check(lambda ns: "--format needs --show NAME|FILE"
                if ns.format is not None and ns.show is None else None)
    return p


def main(argv: list[str] | None = None) -> int:
    """List presets (default), show one (``--show NAME``) or list parameters (``--params``)."""
    args = build_parser().parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, its line printed)
        return args
    if args.show is not None:
        preset = args.show
        if args.format in (None, "text"):
            print("\n".join(show_lines(preset)))
            return ExitCode.OK
        write = preset_to_toml if args.format == "toml" else preset_to_json
        sys.stdout.write(write(preset.params, name=preset.name,
                               description=preset.description, evidence=preset.evidence,
                               open=preset.open))
        return ExitCode.OK
    if args.params:
        width = max(len(k) for k in PARAMETERS)
        for key, spec in PARAMETERS.items():
            bounds = f"{spec.bounds.lo:.10g}..{spec.bounds.hi:.10g}" if spec.bounds else ""
            choices = f" (choices: {', '.join(spec.choices)})" if spec.choices else ""
            neutral = "" if spec.neutral is None else (
                f" (neutral {format_value(spec.neutral) or repr('')})")
            print(f"{key:<{width}}  {spec.kind:<5}  {bounds:<13}  {spec.help}{choices}{neutral}")
        return ExitCode.OK
    width = max(len(k) for k in PRESETS)
    for name, (desc, _) in PRESETS.items():
        print(f"{name:<{width}}  {desc}")
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
