"""One line for each preset of a run that is a twin whose fit is poor
(:attr:`~arenabench.generator.parameters.preset_files.ResolvedPreset.poor_fit`): ``check``,
``eval``, ``sweep`` and ``grade`` say it first, so a score on such a twin's scenes is never
read as a score on the arena."""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any


def poor_fit_lines(presets: Iterable[Any]) -> list[str]:
    """The warnings of the presets that are poor twins (a preset named only, or a built-in
    one, is none)."""
    out = []
    for preset in presets:
        line = getattr(preset, "poor_fit", None)
        if line and line not in out:
            out.append(line)
    return out


def say_poor_fits(prog: str, presets: Iterable[Any]) -> list[str]:
    """Print :func:`poor_fit_lines` on stderr, each as ``PROG: warning: ...``; the lines."""
    lines = poor_fit_lines(presets)
    for line in lines:
        print(f"{prog}: {line}", file=sys.stderr)
    return lines
