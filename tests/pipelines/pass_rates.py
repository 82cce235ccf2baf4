"""Pass rates of the built-in profiles and the seven competition-style pipelines on generated
scenes, against each area reference: the evidence behind the README's preset table.

Every scene is rendered once, in memory, encoded and decoded as ``arenabench generate`` writes
it (``output.format``: JPEG for ``eyrc``), and every pipeline runs on that same image; each
answer is scored against every reference. From the repository root::

    .venv/bin/python tests/pipelines/pass_rates.py --count 200 --seed 0
    .venv/bin/python tests/pipelines/pass_rates.py --preset eyrc --preset eyrc-hard --count 50

prints a Markdown table (one row per preset and pipeline: passes per reference, and the most
common failure category with its count) and, with ``--json PATH``, writes the numbers.
In Python: :func:`score_preset` and :func:`pass_rate_table`.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: This folder (a script's own folder is on its path; pytest puts it there for the tests).
HERE = Path(__file__).resolve().parent

#: The seven competition-style test pipelines (modules in this folder).
STYLES = ("style_detection_index", "style_blur127", "style_grey_band", "style_canny",
          "style_warp400", "style_otsu_every_contour", "style_blur11_warp1030")
#: Every pipeline the table covers: the built-in profiles, then the styles.
PIPELINES = ("reference", "seed", *(f"{s}:detect" for s in STYLES))
REFERENCES = ("visible", "contour")


@dataclass
class Tally:
    """One pipeline's outcome on one preset."""

    n: int = 0
    passed: dict[str, int] = field(default_factory=dict)
    failures: dict[str, Counter] = field(default_factory=dict)
    area_rel_err: dict[str, list[float]] = field(default_factory=dict)

    def rate(self, reference: str) -> float:
        """Pass rate against ``reference``."""
        return self.passed.get(reference, 0) / self.n if self.n else 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {"n": self.n, "passed": dict(self.passed),
                "failures": {k: dict(v) for k, v in self.failures.items()}}


def score_preset(
    preset: str,
    *,
    count: int,
    seed: int = 0,
    pipelines: tuple[str, ...] = PIPELINES,
    references: tuple[str, ...] = REFERENCES,
    tolerance: float = 0.05,
    overrides: dict[str, Any] | None = None,
) -> dict[str, Tally]:
    """Render scenes 0 .. count-1 of ``preset`` with ``seed`` once each and score every
    pipeline on them against every reference.

    Parameters
    ----------
    preset : str
        Preset name.
    count, seed : int, keyword-only
        Scenes and run seed (scene i is scene i of ``arenabench generate --seed SEED``).
    pipelines : tuple of str, keyword-only
        ``reference``, ``seed`` or ``module:function`` specs (this folder is on ``sys.path``).
    references : tuple of str, keyword-only
        Area references (``arenabench eval --area-reference``).
    tolerance : float, keyword-only
        Largest passing ``|area_rel_err|``.
    overrides : dict, keyword-only
        Parsed ``--set`` values.

    Returns
    -------
    dict
        Pipeline spec -> :class:`Tally`.
    """
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count!r}")
    from arenabench.eval.datasets.reader import DatasetItem
    from arenabench.eval.pipelines import make_pipeline
    from arenabench.eval.scoring.metrics import score_image
    from arenabench.generator import Renderer, make_sample
    from arenabench.generator.model.sampler import SamplingError
    from arenabench.generator.parameters.presets import resolve
    from arenabench.imageio import decode_image, encode_image

    pipes = {spec: make_pipeline(spec) for spec in pipelines}
    tallies = {spec: Tally() for spec in pipelines}
    params = resolve(preset, overrides or {})
    output = {"image_format": params["output.format"],
              "jpeg_quality": params["output.jpeg_quality"]}
    with Renderer() as renderer:
        for index in range(count):
            try:
                sample = make_sample(preset, seed=seed, index=index, overrides=overrides,
                                     renderer=renderer)
            except SamplingError:
                continue
            # the image as `arenabench generate` writes it (a JPEG round trip for `eyrc`)
            bgr = decode_image(encode_image(sample.bgr, **output))
            scored = DatasetItem(id=sample.id, image_path=Path(f"{sample.id}.png"),
                            gt_path=Path(f"{sample.id}.json"), gt=sample.gt)
            truths = {ref: scored.truth(area_reference=ref) for ref in references}
            for spec, pipe in pipes.items():
                pred = pipe.run_image(bgr)
                tally = tallies[spec]
                tally.n += 1
                for ref, truth in truths.items():
                    s = score_image(truth, pred, tolerance=tolerance)
                    tally.passed[ref] = tally.passed.get(ref, 0) + int(s.passed)
                    if s.category:
                        tally.failures.setdefault(ref, Counter())[s.category] += 1
                    if s.area_rel_err is not None and s.area_err_kind == "relative":
                        tally.area_rel_err.setdefault(ref, []).append(s.area_rel_err)
    return tallies


def score_phases(
    preset: Any,
    *,
    count: int,
    phases: int,
    seed: int = 0,
    pipelines: tuple[str, ...] = PIPELINES,
    reference: str = "visible",
    tolerance: float = 0.05,
) -> dict[str, float]:
    """Expected passes of each pipeline on scenes 0 .. count-1 of ``preset`` over the
    sub-pixel phase: each scene rendered at the phase check's ``phases`` offsets
    (:func:`arenabench.eval.phase_check.render_phases`: the whole scene moved, each box by its
    own offset), each run scored against that phase's own ground truth, and the scene counted
    as the share of its phases passed.

    A pipeline whose verdicts follow sub-pixel blends passes or fails the same scene at one
    phase by luck; its count at the unshifted phase moves by several scenes in 200 under a
    camera change of half a millimetre. Averaged over the phases it is the count a
    hidden-test set of the same scenes would give on average.

    Returns
    -------
    dict
        Pipeline spec -> expected passes (a float, at most the scenes drawn).
    """
    import tempfile

    from arenabench.eval.datasets.reader import DatasetItem
    from arenabench.eval.phase_check import render_phases
    from arenabench.eval.pipelines import make_pipeline
    from arenabench.eval.scoring.metrics import score_image
    from arenabench.generator import Renderer, make_sample
    from arenabench.generator.dataset.make import ImageFormat
    from arenabench.generator.model.sampler import SamplingError
    from arenabench.generator.parameters.presets import resolve
    from arenabench.imageio import decode_image

    if count < 1 or phases < 1:
        raise ValueError(f"count and phases must be >= 1, got {count!r}, {phases!r}")
    pipes = {spec: make_pipeline(spec) for spec in pipelines}
    expected = dict.fromkeys(pipelines, 0.0)
    output = ImageFormat.from_params(resolve(preset))
    with Renderer() as renderer, tempfile.TemporaryDirectory() as tmp:
        for index in range(count):
            try:
                sample = make_sample(preset, seed=seed, index=index, renderer=renderer)
            except SamplingError:
                continue
            for phase in render_phases(sample.record, phases=phases, folder=Path(tmp),
                                       output=output, renderer=renderer):
                bgr = decode_image(phase.path.read_bytes())
                item = DatasetItem(id=sample.id, image_path=phase.path, gt_path=phase.path,
                                   gt=phase.gt.to_dict())
                truth = item.truth(area_reference=reference)
                for spec, pipe in pipes.items():
                    passed = score_image(truth, pipe.run_image(bgr), tolerance=tolerance).passed
                    expected[spec] += passed / phases
    return expected


def pass_rate_table(results: dict[str, dict[str, Tally]],
                    references: tuple[str, ...] = REFERENCES) -> str:
    """Markdown table of :func:`score_preset` results keyed by preset."""
    head = ["preset", "pipeline", *(f"pass ({r})" for r in references),
            *(f"median area err ({r})" for r in references), "main failure (visible)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for preset, tallies in results.items():
        for spec, t in tallies.items():
            errs = [f"{statistics.median(t.area_rel_err[r]):+.2%}" if t.area_rel_err.get(r)
                    else "-" for r in references]
            fails = t.failures.get(references[0], Counter()).most_common(1)
            main_fail = f"{fails[0][0]} ({fails[0][1]})" if fails else "-"
            lines.append("| " + " | ".join([
                f"`{preset}`", f"`{spec.removesuffix(':detect')}`",
                *(f"{t.passed.get(r, 0)}/{t.n}" for r in references), *errs, main_fail,
            ]) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Command line: print the table (and write JSON with ``--json``)."""
    from arenabench.generator.parameters.presets import preset_names

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", action="append", default=None,
                   help="preset (repeatable; default: every preset)")
    p.add_argument("--count", type=int, default=200, help="scenes per preset (default 200)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    args = p.parse_args(argv)
    results = {}
    for preset in args.preset or preset_names():
        results[preset] = score_preset(preset, count=args.count, seed=args.seed)
        print(f"{preset}: done", file=sys.stderr)
    print(pass_rate_table(results), end="")
    if args.json:
        args.json.write_text(json.dumps(
            {pr: {sp: t.to_dict() for sp, t in ts.items()} for pr, ts in results.items()},
            indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
