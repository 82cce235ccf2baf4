"""The team-facing feedback that ``grade`` writes beside each team's report
(``teams/TEAM/feedback.md`` and ``.html``): verdicts, categories and causes over the whole set,
and nothing of a hidden image: no image data, no image id, no ground-truth or predicted number
of one image, nothing the team's script printed."""

import json
import re
import shutil
import sys
from pathlib import Path

import pytest
from paths import TESTS
from procs_limit import grade_settings

from arenabench.eval.grade.grading import STATE_FILE, GradeOptions, grade
from arenabench.eval.reports.feedback_report import (
    FEEDBACK_FILES,
    feedback_html,
    feedback_markdown,
)

HERE = TESTS
PIPES = HERE / "pipelines"
SECRET = "SECRET-7f3a9c"

LEAKY = f'''"""Prints what it sees of the hidden image and a secret, saves a copy, crashes."""
import argparse, sys
import cv2
image = cv2.imread(argparse.ArgumentParser().add_argument("--image") and
                   sys.argv[sys.argv.index("--image") + 1])
cv2.imwrite("leak.png", image)
print("{SECRET} mean", float(image.mean()), flush=True)
print("{SECRET} shape", image.shape, file=sys.stderr, flush=True)
raise RuntimeError("{SECRET} " + str(image[:4, :4].tolist()))
'''


@pytest.fixture(scope="module")
def graded(tmp_path_factory, shared_sets):
    root = tmp_path_factory.mktemp("feedback")
    data = shared_sets.generated("eyrc", count=4, seed=0, workers=2)
    subs = root / "submissions"
    (subs / "minarea").mkdir(parents=True)
    for name in ("competition_style.py", "style_blur127.py"):
        shutil.copy(PIPES / name, subs / "minarea" / name)
    shutil.copy(PIPES / "style_min_area.py", subs / "minarea" / "map.py")
    (subs / "leaky").mkdir()
    (subs / "leaky" / "map.py").write_text(LEAKY)
    shutil.copytree(HERE / "grade_teams" / "correct", subs / "correct")
    out = root / "results"
    opts = GradeOptions(command=f"{sys.executable} {{submission}}/map.py --image {{image}}",
                        formats=("json", "md", "html"), settings=grade_settings())
    result = grade(data, subs, out, options=opts, workers=2, allow_guessable_seed=True)
    assert sorted(result.graded) == ["correct", "leaky", "minarea"], result.errors
    return data, subs, out, opts


def _texts(out: Path, team: str) -> dict[str, str]:
    return {name: (out / "teams" / team / name).read_text() for name in FEEDBACK_FILES.values()}


def _numbers(value: float) -> set[str]:
    """The ways a report could write one number."""
    return {f"{value:.1f}", f"{value:.0f}", f"{value:.4g}", f"{value:.2f}", repr(value),
            str(round(value, 3))}


@pytest.mark.integration
def test_feedback_holds_no_hidden_image_and_no_number_of_one(graded):
    data, _, out, _ = graded
    gts = [json.loads(p.read_text()) for p in sorted((data / "gt").glob("*.json"))]
    for team in ("correct", "leaky", "minarea"):
        rep = json.loads((out / "teams" / team / "report.json").read_text())
        for name, text in _texts(out, team).items():
            assert "<img" not in text and "data:" not in text and "base64" not in text, name
            assert not re.search(r"(src|href)\s*=", text), name
            assert not re.search(r"[A-Za-z0-9+/]{80,}", text), name  # no encoded blob
            assert str(data) not in text and "hidden-set" not in text, name
            assert SECRET not in text, name  # nothing the script printed
            for gt, img in zip(gts, rep["images"], strict=True):
                assert gt["id"] not in text, (name, gt["id"])
                assert gt["image"] not in text
                for value in (gt["area"]["visible_px"], img["pred"]["area"] or 0.0):
                    if value:
                        assert not (_numbers(value) & set(re.findall(r"[\d.e+]+", text))), (
                            name, team, value)


@pytest.mark.integration
def test_feedback_says_what_failed_and_how_many(graded):
    _, _, out, _ = graded
    md = _texts(out, "leaky")["feedback.md"]
    assert "| passed | 0 of 4 |" in md
    assert "- crash: 4 images (exit status 1: 4) - the run gave no usable answer" in md
    assert "arenabench check map.py" in md
    minarea = _texts(out, "minarea")
    rep = json.loads((out / "teams" / "minarea" / "report.json").read_text())
    n_wrong = rep["summary"]["failures"]["wrong_count"]
    assert n_wrong >= 1
    assert f"- wrong_count: {n_wrong} image{'s' if n_wrong > 1 else ''}" in minarea["feedback.md"]
    assert "<b>wrong_count</b>" in minarea["feedback.html"]
    assert "Every image passed." in _texts(out, "correct")["feedback.md"]
    # the organiser's own report of the same team shows the hidden images and the run's warp
    page = (out / "teams" / "minarea" / "report.html").read_text()
    assert "data:image/jpeg;base64," in page and "transformed_image.png" in page
    assert json.loads((out / "teams" / "minarea" / "report.json").read_text())[
        "manifest_sha256"] == json.loads((out / "leaderboard.json").read_text())[
        "dataset"]["manifest_sha256"]


@pytest.mark.integration
def test_a_team_without_its_feedback_is_graded_again(graded):
    data, subs, out, opts = graded
    again = grade(data, subs, out, options=opts, workers=2, allow_guessable_seed=True)
    assert again.graded == [] and len(again.skipped) == 3
    (out / "teams" / "leaky" / FEEDBACK_FILES["html"]).unlink()
    third = grade(data, subs, out, options=opts, workers=2, allow_guessable_seed=True)
    assert third.graded == ["leaky"]
    assert (out / "teams" / "leaky" / FEEDBACK_FILES["html"]).is_file()
    assert (out / "teams" / "leaky" / STATE_FILE).is_file()


def test_feedback_names_causes_and_offsets_without_their_medians():
    from arenabench.eval.evaluation import build_report
    from arenabench.eval.scoring.results import ImageResult, ImageScore, Prediction, Truth

    def result(i, passed, size):
        return ImageResult(
            id=f"{i:06d}", image=f"images/{i:06d}.png", truth=Truth(count=2, area=1234.5),
            prediction=Prediction(status="ok", count=2 if passed else 6, area=1234.5,
                                  latency_ms=5.0, stdout=f"{SECRET} {i}"),
            score=ImageScore(passed=passed, category=None if passed else "wrong_count",
                             count_err=0 if passed else 4, area_rel_err=0.0,
                             area_err_kind="relative", marker_ids_ok=None),
            params={"gt.min_box_visible_px": size})

    results = [result(i, i >= 6, 1000.0 + 97.0 * i) for i in range(10)]
    report = build_report(results, pipeline="t", dataset="/srv/hidden")
    assert report.causes and report.systematic
    for text in (feedback_markdown(report, team="t"), feedback_html(report, team="t")):
        assert "Systematic error: answered GT + 4 on 6 of 10 answered images" in text
        assert "failures have lower gt.min_box_visible_px (strength 1.00, clear)" in text
        assert "1000" not in text and "1485" not in text  # no per-image fact values
        assert "1234.5" not in text and "000003" not in text and SECRET not in text
        assert "/srv/hidden" not in text
        assert "max" not in text and "min " not in text  # one image's extremes
