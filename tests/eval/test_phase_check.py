"""The phase check (eval/phase_check.py): failing images re-rendered with the boxes moved by
sub-pixel amounts, the pipeline re-run on each (real renders, real pipelines)."""

from __future__ import annotations

import csv
import json
import threading

import edge_phase
import numpy as np
import pytest

from arenabench.eval.datasets.reader import load_dataset
from arenabench.eval.evaluation import evaluate
from arenabench.eval.phase_check import (
    PhaseResult,
    box_offsets,
    parse_phase_check,
    phase_offsets,
    resolve_phases,
    set_presets,
    shifted_scene,
)
from arenabench.eval.scoring.phase_summary import PHASE_DEPENDENT_MEANING
from arenabench.eval.scoring.results import Report, VariantResult
from arenabench.generator.dataset.dataset_writer import generate_dataset
from arenabench.generator.model.camera import intrinsics, project, world_from_camera
from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.parameters.preset_files import write_preset_file
from arenabench.generator.parameters.presets import builtin_preset, resolve_preset

PHASES = 8
# Scenes 0 and 3 of seed 0: edge_phase:detect fails (edge pixel fully covered); 1 and 2 pass.
COUNT = 4


@pytest.fixture(scope="module")
def twin(shared_sets):
    return shared_sets.generated("eyrc", count=COUNT, seed=0)


class Counting:
    """A callable pipeline that counts its calls."""

    def __init__(self, fn):
        self.fn, self.calls, self._lock = fn, 0, threading.Lock()

    def __call__(self, image):
        with self._lock:
            self.calls += 1
        return self.fn(image)


def test_offsets_spread_over_one_pixel():
    offsets = phase_offsets(PHASES)
    assert len(set(offsets)) == PHASES
    assert all(0 < dx < 1 and 0 <= dy < 1 for dx, dy in offsets)
    # one offset per column and per row of an 8 x 8 grid over the pixel
    assert sorted(int(dx * PHASES) for dx, _ in offsets) == list(range(PHASES))
    assert sorted(int(dy * PHASES) for _, dy in offsets) == list(range(PHASES))


def test_a_shift_moves_each_box_by_its_own_offset_in_image_pixels():
    scene = sample_scene("eyrc", seed=0, index=0).scene
    offsets = box_offsets((0.375, 0.625), len(scene.obstacles))
    assert len(scene.obstacles) >= 2 and offsets[0] == (0.375, 0.625)
    assert len(set(offsets)) == len(offsets)  # the boxes get unrelated phases
    moved = shifted_scene(scene, offsets)
    K, pose = intrinsics(scene.camera), world_from_camera(scene.camera)
    for a, b, off in zip(scene.obstacles, moved.obstacles, offsets, strict=True):
        before = project(np.array([[*a.center_m, a.height_m]]), K, pose)[0]
        after = project(np.array([[*b.center_m, b.height_m]]), K, pose)[0]
        assert after - before == pytest.approx(off, abs=1e-9)


def test_every_box_sweeps_its_pixel_evenly():
    for j in range(4):
        xs = sorted(box_offsets(o, 4)[j][0] for o in phase_offsets(PHASES))
        assert sorted(int(x * PHASES) for x in xs) == list(range(PHASES))


def test_option_values():
    assert parse_phase_check("off") == 0 and parse_phase_check("12") == 12
    assert parse_phase_check("auto") == "auto"
    with pytest.raises(Exception, match="number of phases"):
        parse_phase_check("0")
    assert resolve_phases("auto", ["eyrc"]) == PHASES
    assert resolve_phases("auto", ["eyrc-jitter"]) == 0
    assert resolve_phases(3, ["warehouse"]) == 3
    assert resolve_phases(parse_phase_check("off"), ["eyrc"]) == 0


def _preset_file(folder, *, name, open_):
    eyrc = builtin_preset("eyrc")
    path = folder / f"{name}.toml"
    write_preset_file(path, eyrc.params, name=name, description=name,
                      open={k: eyrc.open[k] for k in open_})
    return resolve_preset(str(path))


def test_auto_is_on_for_a_twin_whatever_its_name(tmp_path):
    """``auto`` follows what a preset declares, not its name: a twin (open parameters) is
    checked, the same parameters with nothing open are not, and a name recorded in GT counts
    only when it names a built-in preset."""
    twin = _preset_file(tmp_path, name="my-arena", open_=["lighting.east_fill"])
    pinned = _preset_file(tmp_path, name="eyrc-pinned", open_=[])
    assert resolve_phases("auto", [twin]) == PHASES
    assert resolve_phases("auto", [pinned]) == 0
    assert resolve_phases("auto", [pinned, twin]) == PHASES
    assert resolve_phases("auto", ["my-arena"]) == 0  # a GT name alone cannot say
    assert resolve_phases("auto", [builtin_preset("eyrc-jitter")]) == 0


def test_parameters_drawn_per_scene_are_not_varied(tmp_path):
    """A twin's box count is open because one image is one draw: another count is another
    scene, not something the example hid about this one, so only the fixed open parameter
    (the east fill) gets variants."""
    from arenabench.eval.phase_check import SceneSource, open_variants
    from arenabench.generator.parameters.params import Range
    from arenabench.generator.parameters.preset_files import OpenParam

    eyrc = builtin_preset("eyrc")
    assert isinstance(eyrc.params["obstacles.count"], Range)  # drawn per scene
    path = tmp_path / "twin.toml"
    write_preset_file(path, eyrc.params, name="twin", open={
        "lighting.east_fill": eyrc.open["lighting.east_fill"],
        "obstacles.count": OpenParam(name="obstacles.count", reason="one image is one draw",
                                     range=Range(1, 6))})
    preset = resolve_preset(str(path))
    variants = open_variants(SceneSource(preset))
    assert variants and {v.param for v in variants} == {"lighting.east_fill"}


def test_a_trade_the_image_pins_is_varied_as_one(tmp_path):
    """A twin's field of view is open, but the image pins its trade with the altitude (and
    the tilt): a variant at one end of the range sets them too, to their values there, and
    the altitude, open as well, is never varied on its own (alone it would move every marker
    off the example's pixels)."""
    from arenabench.eval.phase_check import SceneSource, open_variants
    from arenabench.eval.scoring.results import PhaseResult, VariantResult
    from arenabench.generator.dataset.make import ground_truth_record
    from arenabench.generator.parameters.params import Range
    from arenabench.generator.parameters.preset_files import OpenParam

    eyrc = builtin_preset("eyrc")
    fov, alt = eyrc.params["camera.fov_deg"], eyrc.params["camera.altitude_m"]
    path = tmp_path / "twin.toml"
    write_preset_file(path, eyrc.params, name="twin", open={
        "camera.fov_deg": OpenParam(
            "camera.fov_deg", "the markers fit as well", range=Range(fov - 0.4, fov + 1.8),
            moves_with=(("camera.altitude_m", (alt + 0.025, alt - 0.105)),
                        ("camera.tilt_deg", (4.08, 3.91)))),
        "camera.altitude_m": OpenParam("camera.altitude_m", "moves with the field of view",
                                       range=Range(alt - 0.105, alt + 0.025))})
    preset = resolve_preset(str(path))
    assert preset.open["camera.fov_deg"].at(fov - 0.4) == {"camera.altitude_m": alt + 0.025,
                                                          "camera.tilt_deg": 4.08}
    gt = ground_truth_record(sample_scene(preset, seed=0, index=0).scene, sid="000000",
                             preset="twin")
    variants = open_variants(SceneSource(preset))
    assert [(v.param, v.settings()) for v in variants] == [
        ("camera.fov_deg", {"camera.fov_deg": fov - 0.4, "camera.altitude_m": alt + 0.025,
                            "camera.tilt_deg": 4.08}),
        ("camera.fov_deg", {"camera.fov_deg": fov + 1.8, "camera.altitude_m": alt - 0.105,
                            "camera.tilt_deg": 3.91})]
    assert variants[0].text().startswith("camera.fov_deg=")
    assert "(camera.altitude_m=" in variants[0].text()
    # the scene drawn for a variant has all three
    scene = SceneSource(preset).sample(gt, variants[1].settings()).scene
    assert (scene.camera.fov_deg, scene.camera.altitude_m, scene.camera.tilt_deg) == (
        pytest.approx(fov + 1.8), pytest.approx(alt - 0.105), pytest.approx(3.91))
    # a phase record says what moved with it, and reads back
    record = VariantResult("camera.fov_deg", fov + 1.8, 4, 4, 1,
                           also=variants[1].also)
    assert record.to_dict()["with"] == {"camera.altitude_m": alt - 0.105,
                                        "camera.tilt_deg": 3.91}
    phase = PhaseResult(phases=4, runs=4, completed=4, passes=0, variants=(record,))
    assert PhaseResult.from_dict(phase.to_dict()) == phase


@pytest.mark.integration
def test_a_set_drawn_from_a_twin_file_is_checked_on_auto(tmp_path):
    """``eval`` and ``grade`` decide from the definition the set's ``dataset.json`` records,
    so a twin's set is checked with no preset file at hand."""
    for name, open_, want in (("my-arena", ["lighting.west_fill"], PHASES),
                              ("eyrc-pinned", [], 0)):
        preset = _preset_file(tmp_path, name=name, open_=open_)
        out = tmp_path / f"set-{name}"
        generate_dataset(out, preset=preset, count=1, seed=0, workers=1, progress=False)
        (tmp_path / f"{name}.toml").unlink()  # the set must carry it
        assert resolve_phases("auto", set_presets(load_dataset(out))) == want


@pytest.mark.integration
def test_phase_dependent_failures_get_some_passes_and_passing_images_are_not_rerun(twin,
                                                                                  tmp_path):
    pipe = Counting(edge_phase.detect)
    report = evaluate(pipe, twin, workers=2, phases=PHASES)
    failing = [r for r in report.images if not r.passed]
    assert [r.id for r in failing] == ["000000", "000003"]
    for r in failing:
        assert r.phase is not None and 0 < r.phase.passes < PHASES, r.phase
        assert r.phase.label == "phase_dependent"
    assert all(r.phase is None for r in report.images if r.passed)
    # every image once, then N phases of each failing image only
    assert pipe.calls == COUNT + PHASES * len(failing)
    s = report.summary
    assert s.phase_dependent_failure_rate == pytest.approx(2 / COUNT)
    assert s.robust_failure_rate == 0.0
    assert s.phase_check["phases"] == PHASES and s.phase_check["meaning"] == (
        PHASE_DEPENDENT_MEANING)
    # JSON round trip keeps the per-image record
    doc = json.loads(json.dumps(report.to_dict()))
    assert doc["images"][0]["phase"] == {"runs": PHASES, "completed": PHASES,
                                         "passes": failing[0].phase.passes,
                                         "class": "phase_dependent", "phases": PHASES}
    again = Report.from_dict(doc)
    assert again.images[0].phase == failing[0].phase
    assert again.summary.phase_dependent_failure_rate == s.phase_dependent_failure_rate
    # every human report says what phase-dependent means, beside the rates
    from arenabench.eval.reports import write_reports

    files = write_reports(report, tmp_path, formats=("md", "html", "csv", "junit"))
    assert (f'message="phase-dependent (passes {failing[0].phase.passes}/{PHASES} sub-pixel '
            "phases): wrong_count") in files["junit"].read_text()
    sentence = PHASE_DEPENDENT_MEANING.split(": ", 1)[1]
    md, page = files["md"].read_text(), files["html"].read_text()
    assert sentence in md and "| phase-dependent failures | 50.0 % (2/4; 8 phases" in md
    assert f"{failing[0].phase.passes}/{PHASES} phase-dependent" in md
    assert sentence in page and "robust failures (fail at every phase)" in page
    first = next(csv.DictReader(files["csv"].read_text().splitlines()))
    assert first["phase_class"] == "phase_dependent" and first["phase_n"] == str(PHASES)


@pytest.mark.integration
def test_an_always_wrong_pipeline_fails_every_phase(twin):
    pipe = Counting(edge_phase.always_wrong)
    report = evaluate(pipe, twin, workers=2, limit=1, phases=PHASES)
    (r,) = report.images
    # no phase passes, so each open parameter of eyrc (the unseen east and west faces' fill)
    # is tried at its other end too, at the same phases: it fails under every one
    opened = ("lighting.east_fill", "lighting.west_fill")
    assert r.phase == PhaseResult(
        phases=PHASES, runs=PHASES, completed=PHASES, passes=0,
        variants=tuple(VariantResult(k, 0.4, PHASES, PHASES, 0) for k in opened))
    assert r.phase.label == "robust" and r.phase.depends_on == ()
    assert report.summary.robust_failure_rate == 1.0
    assert report.summary.phase_dependent_failure_rate == 0.0
    assert report.summary.phase_check["not_completed"] == 0
    assert pipe.calls == 1 + PHASES * (1 + len(opened))


@pytest.mark.integration
def test_the_open_table_given_is_varied_not_the_sets_old_one(twin, tmp_path):
    """``check`` reuses a cached set made from the same parameters, whose ``dataset.json``
    records the ``[open]`` table of its day; the preset file it is given now says what is
    open (a twin made again, a range widened), and that is what the phase check varies."""
    from dataclasses import replace

    eyrc = builtin_preset("eyrc")
    now = replace(eyrc, open={"lighting.east_fill": eyrc.open["lighting.east_fill"]})
    report = evaluate(edge_phase.always_wrong, twin, workers=2, limit=1, phases=PHASES,
                      open_from=now)
    (r,) = report.images
    assert [v.param for v in r.phase.variants] == ["lighting.east_fill"]
    # other parameters: another set, and the set's own record stands
    other = replace(now, params={**now.params, "camera.tilt_deg": 1.0})
    report = evaluate(edge_phase.always_wrong, twin, workers=2, limit=1, phases=PHASES,
                      open_from=other)
    assert [v.param for v in report.images[0].phase.variants] == [
        "lighting.east_fill", "lighting.west_fill"]


def test_nothing_is_rerun_when_nothing_fails_or_the_check_is_off(twin):
    good = Counting(edge_phase.reference_answer)
    report = evaluate(good, twin, workers=2, phases=PHASES)
    assert report.summary.pass_rate == 1.0 and good.calls == COUNT
    assert report.summary.phase_check is None and report.summary.robust_failure_rate is None
    off = Counting(edge_phase.always_wrong)
    report = evaluate(off, twin, workers=2, phases=0)
    assert off.calls == COUNT and all(r.phase is None for r in report.images)
    assert "phase" not in report.to_dict()["images"][0]


@pytest.mark.parametrize(("fn", "category"), [(edge_phase.garbage, "bad_output"),
                                               (edge_phase.no_markers, "markers_not_found")])
def test_failures_a_phase_cannot_change_are_not_rerun(twin, fn, category):
    # garbage answers and missed markers: the check moves only the boxes, so re-running
    # would only cost (N renders and N runs per image)
    pipe = Counting(fn)
    report = evaluate(pipe, twin, workers=2, phases=PHASES)
    assert {r.category for r in report.images} == {category}
    assert pipe.calls == COUNT and all(r.phase is None for r in report.images)
    assert report.summary.phase_check is None


def test_only_answers_scored_wrong_are_phase_checked():
    from arenabench.eval.phase_check import CHECKED_CATEGORIES
    from arenabench.eval.scoring.results import CATEGORIES, SCORING_FAILURES

    assert CHECKED_CATEGORIES == frozenset(SCORING_FAILURES) == {"wrong_count", "area_off"}
    assert CHECKED_CATEGORIES <= set(CATEGORIES)


@pytest.mark.integration
def test_a_sweep_phase_checks_its_failures_in_the_worker():
    from arenabench.eval.sweep.execution import run_sweep
    from arenabench.eval.sweep.grid import parse_varies
    from arenabench.eval.sweep.records import PipelineSpec, SweepSpec

    spec = SweepSpec(preset="eyrc", axes=parse_varies(["degrade.gamma=1:1:1"]),
                     per_point=COUNT, seed=0, phases=PHASES,
                     pipelines=(PipelineSpec("pipeline", "edge_phase:detect"),
                                PipelineSpec("pipeline", "edge_phase:reference_answer")))
    result = run_sweep(spec, workers=1, progress=False)
    rows = {(r["pipeline"], r["scene"]): r for r in result.images}
    edge = "edge_phase:detect"
    assert [s for s in range(COUNT) if not rows[(edge, s)]["pass"]] == [0, 3]
    for s in (0, 3):
        phase = rows[(edge, s)]["phase"]
        assert phase["phases"] == PHASES and 0 < phase["passes"] < PHASES
        assert phase["class"] == "phase_dependent" and phase["completed"] == phase["runs"]
    assert all("phase" not in r for r in result.images if r["pass"])
    summaries = {p.pipeline: p.summary for p in result.summaries}
    assert summaries[edge].phase_dependent_failure_rate == pytest.approx(0.5)
    assert summaries["edge_phase:reference_answer"].phase_check is None


def test_a_clean_run_never_loads_the_renderer(twin):
    import subprocess
    import sys

    code = (
        "import sys; from arenabench.eval.evaluation import evaluate\n"
        f"r = evaluate('reference', {str(twin)!r}, workers=1, phases=8)\n"
        "assert r.summary.pass_rate == 1.0\n"
        "print(sorted(m for m in sys.modules if m.startswith(('arenabench.generator', "
        "'pyrender'))))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
