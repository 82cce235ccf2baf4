"""``--area-reference contour`` in ``arenabench eval`` and ``arenabench sweep``: scored against
GT ``area.contour_px``; a dataset written before that field existed is refused with one line
naming the file, before any work."""

from __future__ import annotations

import hashlib
import json
import shutil
import statistics
from dataclasses import replace
from pathlib import Path

import pytest

from arenabench.cli import main as arenabench_main
from arenabench.eval.commands.sweep import main as sweep_main
from arenabench.eval.datasets.reader import DatasetError, DatasetItem, load_dataset
from arenabench.generator.commands.generate import main as generate_main


@pytest.fixture(scope="module")
def eyrc(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("contour") / "eyrc"
    assert generate_main(["--preset", "eyrc", "--count", "6", "--seed", "2", "--out", str(out),
                          "--no-progress", "--workers", "1"]) == 0
    return out


def _eval(dataset: Path, out: Path, reference: str) -> dict:
    rc = arenabench_main(["eval", str(dataset), "--pipeline", "reference", "--area-reference",
                          reference, "--out", str(out), "--formats", "json", "--no-progress"])
    assert rc == 0
    return json.loads((out / "report.json").read_text())


@pytest.mark.integration
def test_contour_reference_scores_against_contour_px(eyrc, tmp_path):
    contour = _eval(eyrc, tmp_path / "contour", "contour")
    visible = _eval(eyrc, tmp_path / "visible", "visible")
    assert contour["area_reference"] == "contour"
    for image in contour["images"]:
        gt = json.loads((eyrc / "gt" / f"{image['id']}.json").read_text())
        assert image["gt"]["area"] == gt["area"]["contour_px"] < gt["area"]["visible_px"]
    # the reference pipeline measures with cv2.contourArea: it reads low against the visible
    # area and much closer to 0 against the contour reference
    def median_signed(report):
        return statistics.median(im["area_rel_err"] for im in report["images"])

    assert median_signed(visible) < -0.005
    assert abs(median_signed(contour)) < abs(median_signed(visible)) / 2


def _rewrite_gt(dataset: Path, gt_file: Path, gt: dict) -> None:
    """Replace one GT file and its manifest hash, as an older (consistent) dataset would be."""
    data = json.dumps(gt).encode()
    gt_file.write_bytes(data)
    manifest = dataset / "manifest.jsonl"
    lines = [json.loads(line) for line in manifest.read_text().splitlines() if line.strip()]
    for line in lines:
        if line["gt"] == f"gt/{gt_file.name}":
            line["gt_sha256"] = hashlib.sha256(data).hexdigest()
    manifest.write_text("".join(json.dumps(line, sort_keys=True) + "\n" for line in lines))


def test_old_dataset_without_contour_px_is_refused_naming_the_file(eyrc, tmp_path, capsys):
    old = tmp_path / "old"
    shutil.copytree(eyrc, old)
    gt_file = old / "gt" / "000003.json"
    gt = json.loads(gt_file.read_text())
    del gt["area"]["contour_px"]
    _rewrite_gt(old, gt_file, gt)
    out = tmp_path / "out"
    rc = arenabench_main(["eval", str(old), "--pipeline", "reference", "--area-reference",
                          "contour", "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1, err
    assert str(gt_file) in err and "'area.contour_px'" in err and "regenerate" in err
    assert not out.exists()
    # the other references still work on it
    assert arenabench_main(["eval", str(old), "--pipeline", "reference", "--no-progress"]) == 0


def test_negative_contour_px_makes_the_dataset_invalid(eyrc, tmp_path):
    bad = tmp_path / "bad"
    shutil.copytree(eyrc, bad)
    gt_file = bad / "gt" / "000001.json"
    gt = json.loads(gt_file.read_text())
    gt["area"]["contour_px"] = -1.0
    _rewrite_gt(bad, gt_file, gt)
    with pytest.raises(DatasetError, match=r"area\.contour_px"):
        load_dataset(bad)


def test_truth_without_contour_px_raises_naming_the_file():
    sample = DatasetItem(id="000000", image_path=Path("x.png"), gt_path=Path("gt/000000.json"),
                    gt={"count": 1, "area": {"visible_px": 10.0, "footprint_px": 9.0}})
    with pytest.raises(DatasetError, match=r"gt/000000\.json: field 'area\.contour_px'"):
        sample.truth(area_reference="contour")
    sample = replace(sample, gt=replace(sample.gt, area=replace(sample.gt.area, contour_px=8.5)))
    assert sample.truth(area_reference="contour").area == 8.5


@pytest.mark.integration
def test_sweep_with_contour_reference(tmp_path):
    # --workers 2: worker processes, so no renderer is left cached in this test process
    out = tmp_path / "sweep"
    assert sweep_main(["--preset", "eyrc", "--vary", "camera.tilt_deg=0,3", "--per-point", "2",
                       "--pipeline", "reference", "--area-reference", "contour", "--out",
                       str(out), "--workers", "2", "--no-plots", "--no-progress"]) == 0
    assert json.loads((out / "sweep.json").read_text())["area_reference"] == "contour"
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(rows) == 4
    assert all(0 < r["gt"]["area"] < r["gt"]["area_visible_px"] for r in rows)
