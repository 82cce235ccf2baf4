"""Phase-check verdicts over what the evidence leaves open: runs that do not complete, open
parameters of the preset, the same labels on a loaded machine, and the image recipe the check
shares with the dataset writer (real renders, real subprocess scripts)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from clirun import run_cli
from dark_faces import dark_pixels
from paths import TESTS

from arenabench.eval.datasets.reader import load_dataset
from arenabench.eval.evaluation import evaluate
from arenabench.eval.phase_check import (
    dataset_scene_source,
    open_variants,
    render_phases,
)
from arenabench.eval.runs import CommandPipeline, RunSettings
from arenabench.generator.dataset.dataset_writer import generate_dataset
from arenabench.generator.parameters.preset_files import write_preset_file
from arenabench.generator.parameters.presets import builtin_preset
from arenabench.imageio import jpeg_settings, load_image

PIPELINES = TESTS / "pipelines"
PHASES = 8
EAST = "lighting.east_fill"


def _script(name: str, **env: str) -> CommandPipeline:
    return CommandPipeline(f"{sys.executable} {PIPELINES / name} --image {{image}}",
                           settings=RunSettings(sandbox="none", env=env))


@pytest.fixture(scope="module")
def twin(shared_sets):
    return shared_sets.generated("eyrc", count=3, seed=0)


# ------------------------------------------------------------------------- the image recipe

@pytest.mark.integration
def test_phase_images_are_encoded_as_the_set_and_the_unmoved_scene_is_its_image(tmp_path):
    out = tmp_path / "set"
    generate_dataset(out, preset="eyrc", count=1, seed=0, workers=1, progress=False,
                     overrides={"output.jpeg_subsampling": "444", "output.jpeg_quality": 90})
    data = load_dataset(out)
    (item,) = data.samples
    own = Path(item.image_path).read_bytes()
    assert jpeg_settings(own)[:2] == (90, "444")
    # the check re-renders a failing image: every phase is encoded as the set's images are
    log = tmp_path / "log"
    log.mkdir()
    pipe = _script("flaky_wrong.py", FLAKY_STEADY=str(out / "images"), FLAKY_LOG=str(log),
                   FLAKY_CRASH_SHARE="0")
    try:
        report = evaluate(pipe, out, workers=1, phases=PHASES)
    finally:
        pipe.close()
    (r,) = report.images
    assert r.phase is not None and r.phase.label == "robust"
    seen = [p.read_text() for p in log.iterdir()]
    assert len(seen) == r.phase.total_runs and set(seen) == {"answered 90 444"}
    # the same recipe as the writer's: the scene unmoved is the set's image, byte for byte
    source = dataset_scene_source(data.root, data.meta.doc)
    folder = tmp_path / "phases"
    folder.mkdir()
    (again,) = render_phases(item.gt, phases=1, folder=folder, output=source.output(),
                             offsets=[(0.0, 0.0)])
    assert again.path.read_bytes() == own
    assert again.gt.to_dict() == item.gt.to_dict()


# ------------------------------------------------------------------- runs that do not complete

@pytest.mark.integration
def test_runs_that_crash_are_not_failed_runs(twin, tmp_path):
    log = tmp_path / "log"
    log.mkdir()
    pipe = _script("flaky_wrong.py", FLAKY_STEADY=str(twin / "images"), FLAKY_LOG=str(log))
    try:
        report = evaluate(pipe, twin, workers=2, phases=PHASES)
    finally:
        pipe.close()
    checked = [r for r in report.images if r.phase is not None]
    assert len(checked) == len(report.images) == 3  # every image wrong by its answer
    outcomes = [p.read_text().split()[0] for p in log.iterdir()]
    crashed = outcomes.count("crash")
    assert 0 < crashed < len(outcomes)
    runs = sum(r.phase.total_runs for r in checked)
    completed = sum(r.phase.total_completed for r in checked)
    # every re-run is counted; each crash is a run that did not complete, never a failed one
    assert runs == len(outcomes) and runs - completed == crashed
    for r in checked:
        record = r.to_dict()["phase"]
        assert record["completed"] < record["runs"] and record["passes"] == 0
        assert record["first_error"].startswith("crash: ")
        assert all(x.split()[0] in ("crash", "answered") for x in outcomes)
        assert "random crash" in record["first_error"]
        assert record["class"] == ("unchecked" if record["completed"] == 0 else "robust")
    pc = report.summary.phase_check
    assert pc["not_completed"] == crashed and pc["runs"] == runs
    assert f"{crashed} of {runs} phase runs did not complete" in _headline(report)


def _headline(report) -> str:
    from arenabench.eval.reports.summary_rows import headline

    return headline(report)


# ---------------------------------------------------------------------- open parameters

@pytest.fixture(scope="module")
def east_open(tmp_path_factory):
    """A set of ``eyrc`` scenes whose preset leaves only the east fill open."""
    root = tmp_path_factory.mktemp("east")
    eyrc = builtin_preset("eyrc")
    preset = root / "east.toml"
    write_preset_file(preset, eyrc.params, name="eyrc-east", description="eyrc, east open",
                      open={EAST: eyrc.open[EAST]})
    out = root / "set"
    from arenabench.generator.parameters.presets import resolve_preset

    generate_dataset(out, preset=resolve_preset(str(preset)), count=3, seed=0, workers=1,
                     progress=False)
    return out


def _dark(path: Path) -> int:
    return dark_pixels(load_image(path))


@pytest.mark.integration
def test_a_failure_that_flips_with_an_open_parameter_names_it(east_open, tmp_path):
    data = load_dataset(east_open)
    source = dataset_scene_source(data.root, data.meta.doc)
    first = data.samples[0].gt
    (variant,) = open_variants(source)
    assert variant.param == EAST and variant.value > 0  # lighter east faces
    # the dark-face count of scene 0: every phase of its own scene above every phase of the
    # scene with lighter east faces; the script's threshold between them
    counts = {}
    for name, change in (("own", None), ("east", {EAST: variant.value})):
        folder = tmp_path / name
        folder.mkdir()
        sampled = source.sample(first, change)
        counts[name] = [_dark(i.path) for i in render_phases(
            first, phases=PHASES, folder=folder, output=source.output(), scene=sampled.scene,
            params=sampled.params)]
    assert min(counts["own"]) > max(counts["east"])
    threshold = (min(counts["own"]) + max(counts["east"])) // 2
    pipe = _script("dark_faces.py", DARK_ABOVE=str(threshold))
    try:
        report = evaluate(pipe, east_open, workers=2, phases=PHASES)
    finally:
        pipe.close()
    r = report.images[0]
    assert not r.passed and r.phase is not None
    assert r.phase.label == "depends_on_open" and r.phase.depends_on == (EAST,)
    assert r.phase.passes == 0 and r.phase.completed == PHASES  # no phase of its own passes
    (v,) = r.phase.variants
    assert (v.param, v.value, v.runs, v.passes) == (EAST, variant.value, PHASES, PHASES)
    for other in report.images:  # a label names the parameter exactly when a variant passed
        if other.phase is not None:
            assert (other.phase.label == "depends_on_open") == any(
                x.passes for x in other.phase.variants)
    doc = report.to_dict()["images"][0]["phase"]
    assert doc["class"] == "depends_on_open" and doc["depends_on"] == [EAST]
    pc = report.summary.phase_check
    assert pc["depends_on"][EAST] == pc["depends_on_open"] >= 1
    # the reports say it
    from arenabench.eval.reports import write_reports

    files = write_reports(report, tmp_path / "report", formats=("md", "html", "junit"))
    assert f"depends on open {EAST}" in files["md"].read_text()
    assert f"depends on open {EAST}" in files["html"].read_text()
    assert f"passes with another {EAST}" in files["junit"].read_text()
    from arenabench.eval.commands.check import verdict_lines

    verdict = verdict_lines(report, min_pass_rate=0.95, phases=PHASES)
    n = pc["depends_on_open"]
    assert f"  depends on open parameters: {n} ({EAST} {n})" in verdict
    # and the leaderboard
    from arenabench.eval.grade.leaderboard import (
        LEADERBOARD_JSON_SCHEMA,
        LeaderboardRow,
        leaderboard_dict,
        rank_rows,
    )
    from arenabench.eval.grade.leaderboard_report import leaderboard_html

    rows = rank_rows([LeaderboardRow("team", report.summary, "teams/team/report.html",
                                     "0" * 64)])
    board = leaderboard_dict(rows, dataset={"path": str(east_open), "n": 3,
                                            "manifest_sha256": "0" * 64}, options={})
    assert board["teams"][0]["phase_check"]["depends_on_open"] == n
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(board, LEADERBOARD_JSON_SCHEMA)
    page = leaderboard_html(board)
    assert "Depend on open parameters" in page
    assert f'<td data-key="depends_on_open" data-v="{n}">{n}</td>' in page


# ----------------------------------------------------------------------- a loaded machine

@pytest.mark.integration
def test_the_same_failures_get_the_same_labels_on_a_loaded_machine(twin):
    def labels():
        pipe = _script("style_canny.py")
        try:
            report = evaluate(pipe, twin, workers=2, phases=PHASES)
        finally:
            pipe.close()
        return [(r.id, None if r.phase is None else r.phase.label) for r in report.images]

    idle = labels()
    burners = [subprocess.Popen([sys.executable, "-u", "-c",
                                 "print('burning', flush=True)\nwhile True: pass"],
                                stdout=subprocess.PIPE, text=True) for _ in range(2)]
    try:
        for b in burners:  # each has started burning
            assert b.stdout.readline().strip() == "burning"
        loaded = labels()
        assert all(b.poll() is None for b in burners)  # they burned all along
    finally:
        for b in burners:
            b.kill()
            b.wait()
    assert loaded == idle
    assert any(label is not None for _, label in idle)


# ------------------------------------------------------------------------ nothing ran

def test_eval_says_what_every_image_met(twin, tmp_path):
    proc = run_cli("eval", str(twin), "--cmd", f"{sys.executable} {PIPELINES / 'crash.py'} "
                   "--image {image}", "--no-progress", "--phase-check", "off")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "crash 3" in proc.stdout
    assert ("first failure: 000000: crash: exit status 1: RuntimeError: deliberate crash in "
            "the test pipeline (the same on 3 of 3 images)") in proc.stdout
