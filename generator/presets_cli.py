"""``arenabench presets``: list the scene presets and their parameters."""

from __future__ import annotations

import sys

from arenabench.cliopts import CommandParser
from arenabench.generator.presets import PARAMETERS, PRESETS, format_value
from arenabench.suggest import did_you_mean


def build_parser() -> CommandParser:
    """The ``arenabench presets`` argument parser."""
    p = CommandParser(prog="arenabench presets",
                      description="List scene presets and their parameters.")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--show", metavar="NAME", help="print every parameter of preset NAME")
    g.add_argument("--params", action="store_true", help="list every parameter with its help")
    return p


def main(argv: list[str] | None = None) -> int:
    """List presets (default), show one (``--show NAME``) or list parameters (``--params``)."""
    args = build_parser().parse_args(argv)
    if args.show is not None:
        if args.show not in PRESETS:
            print(f"arenabench presets: error: unknown preset {args.show!r}"
                  f"{did_you_mean(args.show, PRESETS)} (known: {', '.join(PRESETS)})",
                  file=sys.stderr)
            return 2
        for key, value in PRESETS[args.show][1].items():
            print(f"{key}={format_value(value)}")
        return 0
    if args.params:
        width = max(len(k) for k in PARAMETERS)
        for key, spec in PARAMETERS.items():
            bounds = f"{spec.bounds.lo:.10g}..{spec.bounds.hi:.10g}" if spec.bounds else ""
            choices = f" (choices: {', '.join(spec.choices)})" if spec.choices else ""
            neutral = "" if spec.neutral is None else f" (neutral {format_value(spec.neutral)})"
            print(f"{key:<{width}}  {spec.kind:<5}  {bounds:<13}  {spec.help}{choices}{neutral}")
        return 0
    width = max(len(k) for k in PRESETS)
    for name, (desc, _) in PRESETS.items():
        print(f"{name:<{width}}  {desc}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
