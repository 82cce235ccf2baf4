"""Command templates: the placeholders each command accepts, one-pass filling, literal braces,
and the script a template names (``arenabench.cmdtemplate``,
``arenabench.eval.runs.cmd_script``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from arenabench.cmdtemplate import (
    GRADE_PLACEHOLDERS,
    GRADE_REFUSED,
    PLACEHOLDERS,
    RUN_PLACEHOLDERS,
    TemplateError,
    escape,
    fill,
    placeholders,
    template_problem,
)
from arenabench.eval.grade.grading import GradeOptions
from arenabench.eval.grade.teams import team_command
from arenabench.eval.runs import CommandPipeline
from arenabench.eval.runs.cmd_script import missing_script_problem


def test_every_command_takes_declared_placeholders_only():
    assert set(RUN_PLACEHOLDERS) | set(GRADE_PLACEHOLDERS) | set(GRADE_REFUSED) == set(
        PLACEHOLDERS)
    assert "python" not in GRADE_PLACEHOLDERS and "submission" not in RUN_PLACEHOLDERS


@pytest.mark.parametrize(("arg", "values", "expected"), [
    ("--image={image}", {"image": "/s/i.png"}, "--image=/s/i.png"),
    ("{image}", {"image": "/t/x{python}y/image.png", "python": "/py"}, "/t/x{python}y/image.png"),
    ("{{image}}", {"image": "no"}, "{image}"),
    ("{{\"a\": 1}}", {}, "{\"a\": 1}"),
    ("plain", {}, "plain"),
])
def test_fill_is_one_pass_and_reads_doubled_braces_as_braces(arg, values, expected):
    assert fill(arg, values) == expected


def test_escape_gives_literal_text_back_through_fill():
    for text in ("x{image}y", "a{{b}}c", "}{", "{submission}", "plain"):
        assert fill(escape(text), {"image": "I", "submission": "S"}) == text
        assert placeholders(escape(text)) == []


@pytest.mark.parametrize("arg", ["x}y", "x{y", "{image!r}", "{image:>5}", "{a{b}}"])
def test_an_argument_that_is_no_template_is_an_error(arg):
    with pytest.raises(TemplateError):
        fill(arg, {"image": "I"})


def test_fill_refuses_a_placeholder_without_a_value():
    with pytest.raises(TemplateError, match=r"unknown placeholder \{nosuch\}"):
        fill("{nosuch}", {"image": "I"})


@pytest.mark.parametrize(("template", "accepted", "needle"), [
    ("python3 map.py --image {imgae}", RUN_PLACEHOLDERS, "did you mean '{image}'?"),
    ("python3 {submision}/map.py {image}", GRADE_PLACEHOLDERS, "did you mean '{submission}'?"),
    ("python3 {submission}/map.py {image}", RUN_PLACEHOLDERS, "unknown placeholder {submission}"),
    ("python3 m.py {image} {}", RUN_PLACEHOLDERS, "empty placeholder {}"),
    ("python3 m.py {image} '{\"k\": 1}'", RUN_PLACEHOLDERS, "takes no format spec"),
])
def test_template_problem_names_the_placeholder(template, accepted, needle):
    problem = template_problem(template, accepted)
    assert problem is not None and needle in problem and "\n" not in problem, problem


def test_valid_templates_and_literal_braces_pass():
    assert template_problem("python3 m.py --image {image} '{{\"k\": 1}}'", RUN_PLACEHOLDERS) \
        is None
    assert template_problem("{python} -m pkg --image={image}", RUN_PLACEHOLDERS) is None
    assert template_problem("python3 'unbalanced", RUN_PLACEHOLDERS) is None  # runner's error


def test_grade_refuses_python_with_its_reason():
    assert template_problem("{python} {submission}/map.py {image}", GRADE_PLACEHOLDERS,
                            refused=GRADE_REFUSED) == GRADE_REFUSED["python"]
    with pytest.raises(ValueError, match=r"\{python\} is arenabench's own Python"):
        GradeOptions(command="{python} {submission}/map.py --image {image}")
    with pytest.raises(ValueError, match=r"did you mean '\{submission\}'"):
        GradeOptions(command="python3 {submision}/map.py --image {image}")


@pytest.mark.parametrize("name", ["x{image}y", "x{submission}y", "x{python}y", "a}b{c", "{{}}"])
def test_a_team_folder_is_never_searched_for_placeholders(tmp_path, name):
    team = tmp_path / name
    team.mkdir()
    (team / "map.py").write_text("print('hi')\n")
    cmd = team_command("python3 {submission}/map.py --image {image}", team)
    pipe = CommandPipeline(cmd, base_dir=str(team))
    assert pipe.argv(Path("/d/x.png"), image_dir="/run")[1:] == [
        f"{team}/map.py", "--image", "/run/image.png"]
    relative = CommandPipeline(team_command("python3 map.py --image {image}", team),
                               base_dir=str(team))
    assert relative.argv(Path("/d/x.png"), image_dir="/run")[1] == f"{team}/map.py"


def test_cmd_image_placeholder_is_filled_once(tmp_path):
    pipe = CommandPipeline("python3 -c pass --image {image} --py={python}",
                           base_dir=str(tmp_path))
    argv = pipe.argv(Path("/d/x.png"), image_dir="/tmp/a{python}b")
    assert argv[-2:] == ["/tmp/a{python}b/image.png", f"--py={argv[-1][5:]}"]
    assert "{" not in argv[-1]


@pytest.mark.parametrize(("template", "expected"), [
    ("python3 mapp.py --image {image}", "script 'mapp.py' does not exist (relative to {base}) "
                                        "(did you mean 'map.py'?)"),
    ("python3 -u other/mapp.py {image}",
     "script 'other/mapp.py' does not exist (relative to {base})"),
    ("{python} nosuch {image}", "script 'nosuch' does not exist (relative to {base})"),
    ("/usr/bin/env python3 /nope/run.py {image}", "script '/nope/run.py' does not exist"),
    ("python3 map.py --image {image}", None),
    ("python3 -c 'print(1)' {image}", None),
    ("python3 -m mypkg.detect --image {image}", None),
    ("python3 {image}", None),
    ("./run.sh --model weights.bin {image}", None),
    ("python3 'unbalanced", None),
])
def test_missing_script_problem_names_what_was_typed(tmp_path, template, expected):
    (tmp_path / "map.py").write_text("print('hi')\n")
    problem = missing_script_problem(template, base_dir=tmp_path)
    assert problem == (expected.format(base=tmp_path) if expected else None)
