"""``arenabench check map.py``: know before you submit.

Checks the interpreter first (the preflight's probe: Python, numpy, OpenCV with aruco, through
the same run settings as the script), generates (or reuses, from the user cache) a set of
hidden-test twin scenes, runs the script on each as the competition did (``python3 map.py
--image PATH`` with the competition's numpy and OpenCV: :mod:`arenabench.eval.runs.competition_env`;
``obstacles.txt`` in the working directory; sandboxed where bubblewrap works: the ``eval --cmd``
machinery), phase-checks the failures, and prints a short verdict with the versions that ran the
script and the report's path (docs/phase-check.md).

Exit status: 0 the pass rate reaches ``--min-pass-rate``; 1 it does not; 2 bad input (before any
work); 130/143 stopped by SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import sys
from pathlib import Path
from typing import Any

from arenabench.cliopts import (
    CommandParser,
    add_count,
    add_no_progress,
    add_out,
    add_preset,
    add_run_options,
    add_seed,
    add_workers,
    output_problem,
    usage_error,
    write_failure,
)
from arenabench.cmdtemplate import IMAGE, RUN_PLACEHOLDERS, escape, template_problem
from arenabench.eval.commands.check_probe import PROBE_PRESET, PROBE_SCENES, run_probe
from arenabench.eval.phase_check import add_phase_check_argument
from arenabench.eval.runs import COMPETITION_PLACEHOLDER, OWN_PYTHON_PLACEHOLDER
from arenabench.eval.scoring.metric_registry import METRIC
from arenabench.exitcodes import ExitCode
from arenabench.generator.parameters.presets import (
    DEFAULT_PRESET,
    preset_key,
    preset_names,
    resolve_preset,
)
from arenabench.usercache import cache_dir

PROG = "arenabench check"
#: Twin scenes a check runs on by default.
DEFAULT_COUNT = 200
#: Pass rate a script must reach (``--min-pass-rate``).
DEFAULT_MIN_PASS_RATE = 0.95
#: Largest ``--count``.
MAX_COUNT = 10000

EPILOG = """\
examples:
  arenabench check map.py                       # 200 eyrc twin scenes, threshold 95 %
  arenabench check map.py --count 50 --min-pass-rate 0.9
  arenabench check src/map.py --preset eyrc-jitter --seed 3 --out check-report/
  arenabench check map.py --python ~/teams-venv/bin/python

The interpreter: {competition_python} (the default) is the competition's environment (numpy and
OpenCV at the competition's versions), made once from the package index into the cache
(envs/) and reused; where it cannot be made, one line says so and arenabench's own Python runs
the script. --python {python} runs it with arenabench's own Python, --python PATH with another.
Before any scene is rendered the interpreter is probed (Python, numpy, OpenCV with aruco)
through the same sandbox and limits; one that lacks them is refused (exit 2). The versions
that ran the script are printed and recorded in the reports.

The twin set is generated once per (preset, seed, count, generator version) into the cache
(ARENABENCH_CACHE_DIR, else $XDG_CACHE_HOME/arenabench, else ~/.cache/arenabench: sets/) and
reused; a smaller --count takes the first scenes of a larger cached set (the same scenes).
Reports go to reports/SCRIPT-PRESET-sSEED-nCOUNT-HASH/ in the cache (HASH: the script's path
and content, the interpreter and the run options: each version of a script keeps its own
report, so a check before and after a fix can be compared), or --out.

The script's conventions, as the competition ran it: 'PYTHON SCRIPT --image IMAGE' with its
own folder visible read-only and, as its working directory, a private copy of that folder
(what the competition's run in the script's folder amounts to, without letting one run see
another's obstacles.txt); it writes obstacles.txt there; its own exit status 0 means an answer,
3 means markers not found, any other status a crash.

arenabench's exit status: 0 pass rate >= --min-pass-rate, 1 below it, 2 bad input (before any
work), 130/143 interrupted.
"""


class _OldFailUnder(argparse.Action):
    """``--fail-under RATE``: the gate's former name, kept working; says the new one once."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        print(f"{PROG}: --fail-under is now --min-pass-rate (the same pass rate)",
              file=sys.stderr)
        setattr(namespace, self.dest, values)


def build_parser() -> CommandParser:
    """The argument parser of ``arenabench check``."""
    p = CommandParser(
        prog=PROG,
        description="Know before you submit: run a competition script on hidden-test twin "
        "scenes, tell robust failures from luck, and name the strongest cause.",
        epilog=EPILOG,
    )
    p.add_argument("script", help="the competition script (map.py)")
    add_count(p, maximum=MAX_COUNT, default=DEFAULT_COUNT,
              help=f"twin scenes (default: {DEFAULT_COUNT})")
    add_seed(p, help="scene seed")
    add_preset(p, resolve=resolve_preset, default=DEFAULT_PRESET, names=preset_names(),
               help="scene preset (default: the hidden-test twin)")
    p.add_argument("--min-pass-rate", default=str(DEFAULT_MIN_PASS_RATE), metavar="RATE",
                   help="pass rate needed for exit status 0, a fraction in [0, 1] "
                   "(default: %(default)s)")
    # the name this gate had before (it read like eval's --fail-under METRIC=VALUE, which it
    # is not): still taken, as a rate or pass_rate=RATE, with one line saying the new name
    p.add_argument("--fail-under", dest="min_pass_rate", action=_OldFailUnder,
                   metavar="RATE", help=argparse.SUPPRESS)
    p.add_argument("--python", default=COMPETITION_PLACEHOLDER, metavar="PYTHON",
                   help=f"interpreter that runs the script: {COMPETITION_PLACEHOLDER} (the "
                   f"competition's numpy and OpenCV, made once into the cache), "
                   f"{OWN_PYTHON_PLACEHOLDER} (the one running arenabench) or a path "
                   "(default: %(default)s)")
    add_out(p, help="folder for the report files (default: the cache's reports/ folder)")
    add_workers(p, help="scripts run at once")
    p.add_argument("--no-probe", dest="probe", action="store_false",
                   help=f"after a PASS on {DEFAULT_PRESET}, do not run the script on "
                        f"{PROBE_SCENES} {PROBE_PRESET} scenes (camera, light and greys jittered) "
                        f"for a line of robustness advice")
    add_no_progress(p)
    add_phase_check_argument(p)
    add_run_options(p)
    return p


def twin_set_dir(*, preset: str, seed: int, count: int) -> Path:
    """Cache folder of the twin set ``<preset>-<seed>-<count>-<generator version>``."""
    from arenabench.generator.dataset.make import GENERATOR_VERSION

    return cache_dir() / "sets" / f"{preset}-{seed}-{count}-v{GENERATOR_VERSION}"


def larger_twin_set(*, preset: str, seed: int, count: int,
                    name: str | None = None) -> tuple[Path, int] | None:
    """The smallest complete cached twin set of ``preset`` and ``seed`` (this generator
    version, no ``--set``) with more than ``count`` scenes, and its size; ``None`` when there
    is none. ``preset`` is the preset's key (its folders' names,
    :func:`arenabench.generator.parameters.presets.preset_key`), ``name`` the name its
    ``dataset.json`` records (default: ``preset``).

    Its first ``count`` scenes are the scenes of a ``count``-scene set: scene ``i`` draws
    only from the streams of ``(seed, i)`` (:func:`arenabench.generator.model.sampler.stream_rng`),
    whatever the set's size.
    """
    import json
    import re

    from arenabench.generator.dataset.make import GENERATOR_VERSION

    pattern = re.compile(rf"{re.escape(preset)}-{seed}-(\d+)-v{re.escape(str(GENERATOR_VERSION))}")
    found: list[tuple[int, Path]] = []
    folder = cache_dir() / "sets"
    try:
        names = [p for p in folder.iterdir() if (m := pattern.fullmatch(p.name))
                 and int(m.group(1)) > count]
    except OSError:
        return None
    for path in names:
        meta_path = path / "dataset.json"
        try:
            if not meta_path.is_file():  # never open a FIFO
                continue
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        args = meta.get("args") if isinstance(meta, dict) else None
        n = int(pattern.fullmatch(path.name).group(1))  # type: ignore[union-attr]
        if (isinstance(args, dict) and meta.get("complete") is True
                and args == {"preset": name or preset, "count": n, "seed": seed,
                             "overrides": {},
                             "generator_version": GENERATOR_VERSION}):
            found.append((n, path))
    if not found:
        return None
    n, path = min(found)
    return path, n


def report_dir(script: Path, *, preset: str, seed: int, count: int, interpreter: str,
               settings: dict[str, object], phases: int) -> Path:
    """The default report folder: ``reports/<script>-<preset>-s<seed>-n<count>-<hash>`` in the
    cache, the hash over everything else that changes the result (the script's path and
    content, the interpreter, the run settings, the phase check): a check of the script after
    an edit writes a folder of its own, and the report of the version before stays."""
    from arenabench.fileio import dumps_json, sha256_file

    key = dumps_json({"script": str(script), "content": sha256_file(script),
                      "interpreter": interpreter, "settings": settings, "phases": phases})
    digest = hashlib.sha256(key.encode()).hexdigest()[:10]
    return cache_dir() / "reports" / f"{script.stem}-{preset}-s{seed}-n{count}-{digest}"


def _error(message: str) -> int:
    return usage_error(PROG, message)


def _python_problem(python: str) -> str | None:
    """Why ``--python`` cannot be run, as one line (placeholders are resolved later)."""
    if python in (COMPETITION_PLACEHOLDER, OWN_PYTHON_PLACEHOLDER):
        return None
    if "{" in python:
        return (f"--python {python}: not an interpreter (give {COMPETITION_PLACEHOLDER}, "
                f"{OWN_PYTHON_PLACEHOLDER} or a path)")
    if "/" not in python:
        return None if shutil.which(python) else f"--python {python}: not found on PATH"
    if not os.path.exists(python):
        return f"--python {python}: no such file"
    if not (os.path.isfile(python) and os.access(python, os.X_OK)):
        return f"--python {python}: not an executable file"
    return None


def _validate(args: argparse.Namespace) -> str | None:
    """The first bad input, as one line; ``None`` when all is well."""
    script = Path(args.script)
    if not script.exists():
        return f"{args.script}: no such file"
    if not script.is_file():
        return f"{args.script}: not a file"
    if not os.access(script, os.R_OK):
        return f"{args.script}: not readable"
    problem = template_problem(args.python, RUN_PLACEHOLDERS)
    if problem:
        return f"--python {args.python!r}: {problem}"
    try:  # the pass rate's range, as eval's --fail-under pass_rate=RATE
        args.min_pass_rate = METRIC["pass_rate"].check_limit(
            str(args.min_pass_rate).removeprefix("pass_rate="), option="--min-pass-rate",
            named=False)
    except ValueError as exc:
        return str(exc)
    return _python_problem(args.python)


def verdict_lines(report, *, min_pass_rate: float, phases: int) -> list[str]:
    """The verdict: pass rate, robust and phase-dependent failures, the strongest cause
    (:func:`arenabench.eval.scoring.breakdown.strongest_cause_text`), a systematic error of the
    answers (:func:`arenabench.eval.scoring.breakdown.systematic_text`)."""
    from arenabench.eval.phase_check import unchecked_text
    from arenabench.eval.reports.summary_rows import first_failure_line
    from arenabench.eval.scoring.breakdown import strongest_cause_text, systematic_text
    from arenabench.eval.scoring.phase_summary import (
        PHASE_DEPENDENT_MEANING,
        rate_text,
        verdict_words,
    )

    s = report.summary
    ok = s.pass_rate >= min_pass_rate
    lines = [f"{'PASS' if ok else 'FAIL'}: pass rate {rate_text(s.pass_rate)} "
             f"({s.n_passed}/{s.n}; needed {rate_text(min_pass_rate)})"]
    n_fail = s.n - s.n_passed
    if n_fail:
        fails = ", ".join(f"{c} {v}" for c, v in s.failures.items() if v)
        lines.append(f"  failures: {n_fail} ({fails})")
        pc = s.phase_check
        if pc is not None:
            lines.append(f"  robust failures: {pc['robust']} ({rate_text(s.robust_failure_rate)})"
                         ": fail at every sub-pixel position: the method is wrong there")
            lines.append(f"  phase-dependent failures: {pc['phase_dependent']} "
                         f"({rate_text(s.phase_dependent_failure_rate)}): "
                         f"{PHASE_DEPENDENT_MEANING.split(': ', 1)[1]}")
            lines += [f"  {text}" for text in verdict_words(pc)]
        unchecked = pc["unchecked"] if pc is not None else n_fail
        if phases and unchecked:
            lines.append(f"  not phase-checked ({unchecked_text()}): {unchecked}")
        if (text := systematic_text(report.systematic)) is not None:
            lines.append(f"  {text[0].lower()}{text[1:]}")
        if report.causes:
            text = strongest_cause_text(report.causes)
            lines.append(f"  {text[0].lower()}{text[1:]}")
        lines.append(f"  {first_failure_line(report)}")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``arenabench check``; returns the exit status."""
    from arenabench.eval.scoring.results import HarnessError
    from arenabench.interrupts import Interrupted, stop_on_signals

    with stop_on_signals():
        try:
            return _main(argv)
        except HarnessError as exc:  # before any image (the interpreter's probe): nothing ran
            print(f"{PROG}: error: the harness could not run the script: {exc}",
                  file=sys.stderr)
            return ExitCode.HARNESS
        except Interrupted as exc:
            print(f"{PROG}: interrupted ({exc}); nothing more written", file=sys.stderr)
            return exc.exit_code


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    problem = _validate(args)
    if problem:
        return _error(problem)
    return _Check(args).main()


class _Check:
    """One ``arenabench check`` in steps: the run settings (options checked, nothing run),
    the interpreter (probed) and the pipeline, the report folder, the twin set (made or
    reused), the evaluation and its reports, the verdict."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.script = Path(args.script).resolve()
        self.preset = args.preset  # a ResolvedPreset: sets and reports are named by its key
        self.twin = twin_set_dir(preset=preset_key(self.preset), seed=args.seed,
                                 count=args.count)
        self.larger: tuple[Path, int] | None = None
        self.settings: Any = None
        self.progress = not args.no_progress

    def main(self) -> int:
        from arenabench.eval.commands.poor_fit import say_poor_fits
        from arenabench.eval.phase_check import resolve_phases

        args = self.args
        if args.out is not None and (problem := self.out_problem(args.out)):
            return _error(problem)
        say_poor_fits(PROG, [self.preset])
        try:
            self._configure()
        except ValueError as exc:
            return _error(str(exc))
        self.phases = resolve_phases(args.phase_check, [self.preset])
        made = self._interpreter_and_pipeline()
        if made is not None:
            return made
        out = args.out if args.out is not None else report_dir(
            self.script, preset=preset_key(self.preset), seed=args.seed, count=args.count,
            interpreter=self.interpreter.executable, settings=self.settings.to_dict(),
            phases=self.phases)
        if problem := self.out_problem(out):
            return _error(problem)
        print(f"interpreter: {self.interpreter.describe()}")
        what = self._twin_set()
        if isinstance(what, int):
            return what
        return self._evaluate(out, what)

    def out_problem(self, out: Path) -> str | None:
        from arenabench.eval.reports import FORMATS

        return output_problem(out, own=FORMATS.values(), what="'arenabench check' report",
                              inputs=[("the twin set", self.twin)])

    def make_pipeline(self, template: str, base: str, *, warm: bool = True):
        """A command pipeline of ``template`` under the check's settings."""
        from dataclasses import replace

        from arenabench.eval.runs import CommandPipeline

        settings = self.settings
        return CommandPipeline(template, settings=replace(settings, warm=settings.warm and warm),
                               name=self.script.name, base_dir=base)

    def _configure(self) -> None:
        """The run settings, and the options checked by making the pipeline (no run)."""
        from dataclasses import replace

        from arenabench.eval.runs import run_settings_from_args

        # the working directory holds a copy of the script's folder, as when the competition
        # ran the script there: relative reads work, obstacles.txt lands in the copy
        base = run_settings_from_args(self.args)
        self.settings = replace(base, workdir_from=str(self.script.parent),  # no __pycache__
                                env={"PYTHONDONTWRITEBYTECODE": "1", **base.env})
        self.make_pipeline(_template(OWN_PYTHON_PLACEHOLDER, self.script),
                           str(self.script.parent)).close()

    def _interpreter_and_pipeline(self) -> int | None:
        """The interpreter (made where it is the competition's, then probed) and the
        pipeline; an exit status when either is refused."""
        python = self.args.python
        if python not in (COMPETITION_PLACEHOLDER, OWN_PYTHON_PLACEHOLDER) and "/" in python:
            python = os.path.abspath(python)  # from where the command runs, not the script's
        interpreter = _interpreter(python, progress=self.progress)
        template = _template(
            interpreter.executable if python == COMPETITION_PLACEHOLDER else python,
            self.script)
        try:
            self.pipeline = self.make_pipeline(template, str(self.script.parent))
        except ValueError as exc:
            return _error(str(exc))
        try:
            self.interpreter = _probe(interpreter, template, self.script, self.make_pipeline,
                                      self.settings, mode=self.pipeline.sandbox)
        except ValueError as exc:  # PreflightError: the interpreter lacks numpy, cv2 or aruco
            self.pipeline.close()
            return _error(str(exc))
        return None

    def _twin_set(self) -> str | int:
        """Make the twin set (or reuse it, or a larger one's first scenes); what was done, or
        an exit status."""
        from arenabench.generator.dataset.dataset_writer import GenerateError, generate_dataset

        args, preset = self.args, self.preset
        if not self.twin.exists():
            self.larger = larger_twin_set(preset=preset_key(preset), seed=args.seed,
                                          count=args.count, name=preset.name)
        try:
            if self.larger is not None:  # its first scenes are this set's: nothing to render
                self.twin = self.larger[0]
                return (f"reused twin set {self.twin} (its first {args.count} of "
                        f"{self.larger[1]} scenes")
            made = generate_dataset(self.twin, preset=preset, count=args.count,
                                    seed=args.seed, workers=min(args.workers or _cores(), 8),
                                    progress=self.progress)
        except (GenerateError, ValueError) as exc:
            return _error(f"twin set {self.twin}: {exc}")
        if made.interrupted is not None:
            from arenabench.interrupts import exit_code

            print(f"{PROG}: {made.summary()}", file=sys.stderr)
            return exit_code(made.interrupted)
        return (("reused" if made.rendered == 0 else f"generated {made.rendered} scenes of")
                + f" twin set {self.twin} ({args.count} scenes")

    def _evaluate(self, out: Path, what: str) -> int:
        """Evaluate the script on the set and write the reports (partial ones after a stop);
        the verdict's lines and exit status."""
        from dataclasses import replace

        from arenabench.cliopts import lock_out
        from arenabench.eval.datasets.reader import DatasetError, load_dataset
        from arenabench.eval.evaluation import (
            EvaluationFailed,
            EvaluationInterrupted,
            evaluate,
        )
        from arenabench.eval.reports import write_reports
        from arenabench.fileio import FolderLockedError
        from arenabench.interrupts import Interrupted, deferred_stops

        args = self.args
        # the set is made: a stop from now on writes the partial (perhaps empty) reports
        self.dataset = None
        try:
            with lock_out(out):  # one run at a time writes into the report folder
                try:
                    try:
                        self.dataset = load_dataset(self.twin,
                                                    limit=args.count if self.larger else None)
                    except (DatasetError, ValueError) as exc:
                        return _error(f"twin set {self.twin}: {exc}")
                    print(f"{PROG}: {what} of {self.preset.name}, seed {args.seed}); report "
                          f"folder {out}")
                    report = evaluate(self.pipeline, self.dataset, workers=args.workers,
                                      progress=self.progress, phases=self.phases,
                                      open_from=self.preset)
                except (EvaluationInterrupted, EvaluationFailed, Interrupted) as exc:
                    return self._stopped(exc, out)
                report = replace(report, interpreter=self.interpreter.to_dict())
                written: dict = {}
                try:
                    with deferred_stops():  # every image ran: a stop cuts no report off
                        written = write_reports(report, out, dataset=self.dataset)
                except Interrupted:  # raised once they are written: the exit status says so
                    pass
        except FolderLockedError as exc:
            return _error(str(exc))
        except OSError as exc:  # ENOSPC: one line, no traceback (as eval and grade)
            print(f"{PROG}: error: {write_failure(exc, out)}", file=sys.stderr)
            return ExitCode.FAILED
        return self._verdict(report, written)

    def _stopped(self, exc, out: Path) -> int:
        """Partial reports, marked INCOMPLETE, after a stop or a harness failure."""
        from dataclasses import replace

        from arenabench.eval.evaluation import (
            EvaluationFailed,
            EvaluationInterrupted,
            empty_report,
        )
        from arenabench.eval.reports import write_reports
        from arenabench.interrupts import deferred_stops

        dataset = self.dataset
        partial = (exc.report if isinstance(exc, (EvaluationInterrupted, EvaluationFailed))
                   else empty_report(pipeline=self.pipeline.name, dataset=str(self.twin),
                                     n_total=None if dataset is None else len(dataset.samples)))
        partial = replace(partial, interpreter=self.interpreter.to_dict())
        try:
            with deferred_stops():  # a second stop does not cut the writing short
                write_reports(partial, out, dataset=dataset)
        except OSError as err:
            print(f"{PROG}: error: {write_failure(err, out)}", file=sys.stderr)
        if isinstance(exc, EvaluationFailed):
            print(f"{PROG}: error: {exc}; nothing of it scored; partial report in "
                  f"{out}", file=sys.stderr)
            return ExitCode.HARNESS
        print(f"{PROG}: interrupted after {partial.images_done} images; running "
              f"scripts killed; partial report in {out}", file=sys.stderr)
        return exc.exit_code

    def _verdict(self, report, written: dict) -> int:
        args = self.args
        for line in verdict_lines(report, min_pass_rate=args.min_pass_rate, phases=self.phases):
            print(line)
        if written:
            print(f"  report: {written.get('html', next(iter(written.values()))).resolve()}")
        passed = report.summary.pass_rate >= args.min_pass_rate
        if passed and args.probe and preset_key(self.preset) == DEFAULT_PRESET:  # built-in twin
            _probe_robustness(self.pipeline, args, self.script,
                              twin_rate=report.summary.pass_rate)
        return ExitCode.OK if passed else ExitCode.FAILED


def _probe_robustness(pipeline, args: argparse.Namespace, script: Path, *,
                      twin_rate: float) -> None:
    """A PASS on the twin: the probe's line of advice, when it has one (never the exit
    status); a set that cannot be made says so in a line and the check stays a PASS."""
    from arenabench.generator.dataset.dataset_writer import GenerateError

    folder = twin_set_dir(preset=PROBE_PRESET, seed=args.seed, count=PROBE_SCENES)
    try:
        probe = run_probe(pipeline, seed=args.seed, workers=args.workers or _cores(),
                          folder=folder)
    except (GenerateError, ValueError, OSError) as exc:
        print(f"{PROG}: robustness probe skipped: {exc}", file=sys.stderr)
        return
    advice = probe.advice(twin_rate=twin_rate, script=str(script))
    if advice:
        print(advice)


def _template(python: str, script: Path) -> str:
    """The command that runs ``script`` with ``python`` (a path or :data:`OWN_PYTHON_PLACEHOLDER`);
    paths are literal text in the template (a folder may be named ``x{image}y``)."""
    import shlex

    py = python if python == OWN_PYTHON_PLACEHOLDER else escape(python)
    return f"{shlex.quote(py)} {shlex.quote(escape(str(script)))} --image {{{IMAGE}}}"


def _interpreter(python: str, *, progress: bool):
    """The :class:`~arenabench.eval.runs.competition_env.Interpreter` that ``--python`` names (the
    competition's environment is made here when it is missing)."""
    from arenabench.eval.runs import Interpreter, competition_python

    if python == COMPETITION_PLACEHOLDER:
        return competition_python(progress=progress, prog=PROG)
    if python == OWN_PYTHON_PLACEHOLDER:
        return Interpreter(sys.executable, "own")
    return Interpreter(shutil.which(python) or python, "given")


def _probe(interpreter, template: str, script: Path, make_pipeline, settings, *, mode: str):
    """``interpreter`` with the versions the preflight's probe saw, run as ``template`` runs
    the script (same sandbox, limits and working directory; one cold run on a stand-in image).

    Raises
    ------
    PreflightError
        One line: the interpreter cannot run, or lacks numpy, OpenCV or aruco.
    """
    import shlex
    import tempfile

    import cv2
    import numpy as np

    from arenabench.eval.grade.preflight import PreflightRecord, probe_interpreter

    argv = shlex.split(template)
    probe_template = shlex.join([argv[0], "{submission}/" + script.name, *argv[2:]])
    with tempfile.TemporaryDirectory(prefix="arenabench-check-") as tmp:
        image = Path(tmp, "image.png")  # a stand-in: the probe does not read it
        image.write_bytes(cv2.imencode(".png", np.zeros((1, 1), np.uint8))[1].tobytes())
        record = probe_interpreter(
            probe_template, image=image, make_pipeline=make_pipeline, mode=mode,
            record=PreflightRecord(mode=mode, limits=settings.to_dict()), option="--python",
            command_name="the command running the script")
    return interpreter.with_versions(record.versions)


def _cores() -> int:
    from arenabench.workers import usable_cores

    return usable_cores()


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
