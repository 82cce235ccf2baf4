"""Every command's parser is a :class:`CommandParser` and takes its shared options from the
builders of :mod:`arenabench.cliopts` (defaults equal to their one declaration); each option
keeps one rule, refused with one line naming the option and the value (exit 2)."""

from __future__ import annotations

import argparse
import ast
import importlib
import re

import pytest
from clirun import run_cli
from paths import ROOT

from arenabench.cli import COMMANDS
from arenabench.clihelp import HelpFormatter
from arenabench.cliopts import (
    DEFAULT_SANDBOX,
    SHARED_OPTIONS,
    CommandParser,
    format_size,
    formats_problem,
    parse_size,
)
from arenabench.competition import DEFAULT_TOLERANCE
from arenabench.generator.parameters.presets import DEFAULT_PRESET
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE
from arenabench.limits import (
    DEFAULT_MAX_DISK,
    DEFAULT_MAX_FILE_SIZE,
    DEFAULT_MAX_OUTPUT,
    DEFAULT_MAX_PROCS,
    DEFAULT_MEMORY_BYTES,
    DEFAULT_TIMEOUT_S,
    MAX_WORKERS,
)
from arenabench.workers import usable_cores

#: (command, option) pairs that share a name but not the meaning: detect's --output is the
#: competition's answer file, not how a --cmd answers.
NOT_SHARED = {("detect", "--output")}
#: (command, option) pairs built by the shared builder with a default of their own: doctor's
#: --timeout is the seconds a check may take, not a run's limit.
OWN_DEFAULT = {("doctor", "--timeout")}

#: What each shared option must default to: its one declaration.
DECLARED = {
    "--tolerance": DEFAULT_TOLERANCE,
    "--area-reference": DEFAULT_AREA_REFERENCE,
    "--timeout": DEFAULT_TIMEOUT_S,
    "--memory-limit": format_size(DEFAULT_MEMORY_BYTES),
    "--max-procs": DEFAULT_MAX_PROCS,
    "--max-file-size": format_size(DEFAULT_MAX_FILE_SIZE),
    "--max-output": format_size(DEFAULT_MAX_OUTPUT),
    "--max-disk": format_size(DEFAULT_MAX_DISK),
    "--sandbox": DEFAULT_SANDBOX,
    "--no-progress": False,
    "--scheduler": None,
    "--preset": DEFAULT_PRESET,
}


def _parser(name: str) -> argparse.ArgumentParser:
    module = importlib.import_module(COMMANDS[name][0])
    return module.build_parser()


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_uses_the_shared_parser_and_builders(name):
    parser = _parser(name)
    assert isinstance(parser, CommandParser), name
    assert parser.formatter_class is HelpFormatter, name
    for action in parser._actions:
        for option in action.option_strings:
            if option not in SHARED_OPTIONS or (name, option) in NOT_SHARED:
                continue
            assert getattr(action, "shared_option", None), \
                f"{name} {option}: declared by hand, not by a cliopts builder"
            if option in DECLARED and (name, option) not in OWN_DEFAULT:
                assert action.default == DECLARED[option], (name, option, action.default)


def test_the_shared_options_are_declared_only_in_cliopts():
    """No module of the three packages calls ``add_argument`` with a shared option's flag:
    each is declared by its builder in arenabench.cliopts (detect's own --output aside)."""
    root = ROOT
    cliopts = root / "src" / "arenabench" / "cliopts.py"
    found = []
    for path in sorted(p for pkg in ("src/arenabench", "generator", "eval")
                       for p in (root / pkg).rglob("*.py")):
        if path == cliopts:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "add_argument"):
                flags = [a.value for a in node.args if isinstance(a, ast.Constant)]
                found += [f"{path.relative_to(root)} {f}" for f in flags if f in SHARED_OPTIONS]
    assert found == ["src/arenabench/detect.py --output"], "\n".join(found)


@pytest.mark.parametrize("name", ["eval", "grade", "sweep", "generate", "bench", "demo"])
def test_workers_default_to_the_usable_cores_everywhere(name, tmp_path):
    required = {"eval": ["d", "--pipeline", "reference"], "grade": ["d", "s", "--out", "o"],
                "sweep": ["--out", "o"], "generate": ["--count", "1", "--out", "o"]}
    args = _parser(name).parse_args(required.get(name, []))
    assert args.workers == usable_cores()


@pytest.mark.parametrize("name", ["grade", "sweep", "generate"])
def test_workers_with_scheduler_is_one_rule(name, capsys):
    required = {"grade": ["d", "s", "--out", "o"], "sweep": ["--out", "o"],
                "generate": ["--count", "1", "--out", "o"]}[name]
    parser = _parser(name)
    assert parser.parse_args([*required, "--scheduler", "tcp://h:1"]).workers is None
    with pytest.raises(SystemExit) as exc:
        parser.parse_args([*required, "--scheduler", "tcp://h:1", "--workers", "2"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"arenabench {name}: error: --workers and --scheduler exclude each other "
                   "(the cluster's workers do the work)")


def test_size_rule():
    assert parse_size("2G", name="--x") == 2 * 1024**3
    assert format_size(parse_size("1P", name="--x")) == "1P"
    for bad in ("99999999T", "0", "2P", "1e309", "inf", "-1"):
        with pytest.raises(ValueError, match="--x"):
            parse_size(bad, name="--x")


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (("eval", ".", "--pipeline", "reference", "--timeout", "inf"),
         "argument --timeout: must be a finite number in [1, 86400], got 'inf'"),
        (("grade", ".", ".", "--out", "o", "--timeout", "1e309"), "got '1e309'"),
        (("sweep", "--out", "o", "--timeout", "1e12"), "got '1e12'"),
        (("eval", ".", "--pipeline", "reference", "--memory-limit", "99999999T"),
         "argument --memory-limit: must be a size in [1, 1P] bytes, got '99999999T'"),
        (("grade", ".", ".", "--out", "o", "--max-file-size", "99999999T"), "--max-file-size"),
        (("grade", ".", ".", "--out", "o", "--tolerance", "inf"),
         "argument --tolerance: must be a finite number in [0, 1], got 'inf'"),
        (("grade", ".", ".", "--out", "o", "--tolerance", "1e309"), "got '1e309'"),
        (("grade", ".", ".", "--out", "o", "--workers", "100000"),
         f"argument --workers: must be an integer in [1, {MAX_WORKERS}], got '100000'"),
        (("generate", "--count", "0", "--out", "o"),
         "argument --count: must be an integer in [1, 1000000], got '0'"),
        (("bench", "--rss-renders", "-1"), "argument --rss-renders: must be an integer"),
        (("fit", "x.png", "--out", "s.json", "--refine-rounds", "1000000000"),
         "argument --refine-rounds: must be an integer in [0, 100]"),
        (("eval", ".", "--pipeline", "reference", "--max-procs", "-1"), "--max-procs"),
        (("eval", ".", "--pipeline", "reference", "--wokers", "2"),
         "did you mean '--workers'?"),
        (("detect", "--image", "x.png", "--profile", "sed"), "did you mean 'seed'?"),
        (("eval", ".", "--pipeline", "reference", "--fail-under", "pas_rate=1"),
         "did you mean 'pass_rate'?"),
    ],
)
def test_one_rule_per_option_one_line(argv, needle, tmp_path):
    proc = run_cli(*argv, cwd=tmp_path)
    err = proc.stderr.strip()
    assert proc.returncode == 2, (proc.returncode, err)
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith(f"arenabench {argv[0]}: error: ") and needle in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["1e-320", "0.5", "1_0", "٣", " 5", "5 ", "0x10", "nan",
                                   "+inf"])
@pytest.mark.parametrize("command", ["eval", "sweep", "grade"])
def test_timeout_is_plain_decimal_and_at_least_the_minimum(command, value, tmp_path):
    from arenabench.limits import MIN_TIMEOUT_S

    argv = {"eval": ("eval", ".", "--pipeline", "reference"),
            "sweep": ("sweep", "--out", "o", "--vary", "camera.tilt_deg=0:10"),
            "grade": ("grade", ".", ".", "--out", "o")}[command]
    proc = run_cli(*argv, "--timeout", value, cwd=tmp_path)
    err = proc.stderr.strip()
    assert proc.returncode == 2 and len(err.splitlines()) == 1, err
    assert (f"argument --timeout: must be a finite number in [{MIN_TIMEOUT_S:g}, 86400], got "
            f"{value!r}") in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize(("argv", "needle"), [
    (("sweep", "--out", "o", "--vary", "camera.tilt_deg=0:10", "--per-point", "1_0"),
     "argument --per-point: invalid int value: '1_0'"),
    (("sweep", "--out", "o", "--vary", "camera.tilt_deg=0:10", "--threshold", "٠.٥"),
     "argument --threshold: invalid float value: '٠.٥'"),
    (("sweep", "--out", "o", "--vary", "camera.tilt_deg=0:1_0", "--pipeline", "reference"),
     "'1_0' is not a number"),
    (("eval", ".", "--pipeline", "reference", "--workers", "٢"),
     "argument --workers: must be an integer in [1, "),
    (("eval", ".", "--pipeline", "reference", "--memory-limit", "٢G"),
     "argument --memory-limit: not a size: '٢G'"),
    (("generate", "--count", "1", "--out", "o", "--set", "obstacles.count=٣"),
     "--set obstacles.count: invalid int value '٣'"),
    (("generate", "--count", "1", "--out", "o", "--seed", "1_0"),
     "argument --seed: not 'random' nor an integer in [0, 2**128 - 1]: '1_0'"),
    (("generate", "--count", "1", "--out", "o", "--seed", "9" * 200),
     "argument --seed: must be an integer in [0, 2**128 - 1], got 99999"),
    (("generate", "--count", "1", "--out", "o", "--seed", str(2**128)),
     "argument --seed: must be an integer in [0, 2**128 - 1]"),
    (("sweep", "--out", "o", "--vary", "camera.tilt_deg=0:10", "--seed", str(2**128)),
     "argument --seed: must be an integer in [0, 2**128 - 1]"),
    (("check", "map.py", "--seed", "٣"), "argument --seed: not an integer in [0, 2**128 - 1]"),
    (("generate", "--count", "1", "--out", "o", "--set", "markers.ids=80,80,80,80"),
     "--set markers.ids: the four corners' ids must differ"),
])
def test_numbers_on_the_command_line_are_plain_ascii_decimal(argv, needle, tmp_path):
    proc = run_cli(*argv, cwd=tmp_path)
    err = proc.stderr.strip()
    assert proc.returncode == 2 and len(err.splitlines()) == 1, err
    assert needle in err and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_random_seed_is_a_valid_seed():
    from arenabench.seeds import (
        GUESSABLE_BELOW,
        MAX_SEED,
        check_seed,
        parse_seed,
        random_seed,
    )

    for _ in range(100):
        seed = random_seed()
        assert GUESSABLE_BELOW <= seed <= MAX_SEED and check_seed(seed) == seed
    assert parse_seed(str(MAX_SEED)) == MAX_SEED
    assert GUESSABLE_BELOW <= parse_seed("random") <= MAX_SEED


@pytest.mark.parametrize("names", [("htm",), ()])
def test_formats_are_one_rule_on_the_command_line_and_in_the_harness(names, capsys):
    """``--formats``, ``GradeOptions(formats=)`` and ``write_reports(formats=)`` refuse the
    same choices with the same words (:func:`arenabench.cliopts.formats_problem`)."""
    from arenabench.eval.grade.grading import GradeOptions
    from arenabench.eval.reports import FORMATS

    problem = formats_problem(names, tuple(FORMATS))
    assert problem and ("did you mean 'html'" in problem if names else "no format" in problem)
    with pytest.raises(ValueError, match=re.escape(f"formats: {problem}")):
        GradeOptions(formats=names)
    with pytest.raises(SystemExit) as exc:
        _parser("eval").parse_args(["--formats", ",".join(names) or ",", "DATASET"])
    assert exc.value.code == 2 and problem in capsys.readouterr().err
