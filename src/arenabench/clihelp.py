"""One ``--help`` style for every command: defaults shown, text wrapped to the terminal.

Pass :class:`HelpFormatter` as ``formatter_class`` of a command's parser. Descriptions and
epilogs are re-wrapped paragraph by paragraph; indented lines (examples, lists) and short lines
ending in a colon (headings) are kept as written. An option whose help does not already say
its default gets ``(default: X)`` appended.
"""

from __future__ import annotations

import argparse
import textwrap


class HelpFormatter(argparse.HelpFormatter):
    """``argparse`` formatter: wraps prose, keeps examples, shows defaults."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        out: list[str] = []
        prose: list[str] = []

        def flush() -> None:
            if prose:
                out.append(textwrap.fill(" ".join(prose), width, initial_indent=indent,
                                         subsequent_indent=indent))
                prose.clear()

        for line in textwrap.dedent(text).splitlines():
            stripped = line.strip()
            if not stripped:
                flush()
                out.append("")
            elif line[:1].isspace() or (not prose and stripped.endswith(":")
                                        and len(stripped) < 40):
                flush()
                out.append(indent + line)
            else:
                prose.append(stripped)
        flush()
        return "\n".join(out)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        shown = (
            default is not None
            and default is not argparse.SUPPRESS
            and default is not False
            and default != []
            and not isinstance(action, (argparse._HelpAction, argparse._VersionAction))
            and (action.option_strings or action.nargs in ("?", "*"))
        )
        if shown and "default" not in text:
            text = f"{text} (default: %(default)s)".strip()
        return text
