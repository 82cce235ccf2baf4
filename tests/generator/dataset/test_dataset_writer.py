"""Datasets on disk through the real ``arenabench generate`` command (subprocesses)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from clirun import run_cli
from paths import TESTS

from arenabench.fileio import sha256_file
from arenabench.imageio import jpeg_layout, jpeg_quality

COUNT = 4
EXAMPLE = TESTS / "data" / "task1c_image.jpg"


def _generate(out: Path, *extra: str, count: int = COUNT, seed: int = 7):
    return run_cli("generate", "--preset", "eyrc", "--count", str(count), "--seed", str(seed),
                   "--out", str(out), "--no-progress", *extra)


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


@pytest.fixture(scope="module")
def one_worker(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "one"
    proc = _generate(out, "--workers", "1")
    assert proc.returncode == 0, proc.stderr
    return out, proc


def test_layout_manifest_and_metadata(one_worker):
    out, proc = one_worker
    assert "4 rendered" in proc.stdout and not proc.stderr  # the summary is output
    ids = [f"{i:06d}" for i in range(COUNT)]
    assert sorted(p.name for p in (out / "images").iterdir()) == [f"{i}.jpg" for i in ids]
    assert sorted(p.name for p in (out / "gt").iterdir()) == [f"{i}.json" for i in ids]
    lines = (out / "manifest.jsonl").read_text().splitlines()
    assert [json.loads(line)["id"] for line in lines] == ids
    for line in lines:
        row = json.loads(line)
        assert set(row) == {"id", "image", "gt", "image_sha256", "gt_sha256"}
        assert sha256_file(out / row["image"]) == row["image_sha256"]
        assert sha256_file(out / row["gt"]) == row["gt_sha256"]
    meta = json.loads((out / "dataset.json").read_text())
    assert meta["complete"] is True
    assert meta["preset"] == "eyrc" and meta["seed"] == 7 and meta["count"] == COUNT
    for key in ("arenabench", "opencv", "pyrender", "gl_renderer", "gl_version"):
        assert meta["versions"][key], key
    gt = json.loads((out / "gt" / "000002.json").read_text())
    for key in ("schema", "id", "image", "image_size", "preset", "seed", "scene", "count",
                "components", "area", "frame", "homography", "camera", "markers", "obstacles",
                "params", "generator_version"):
        assert key in gt, key
    assert gt["schema"] == "arenabench.gt/1" and gt["image"] == "images/000002.jpg"
    assert gt["params"]["obstacles.count"] == gt["count"]
    assert "camera.tilt_deg" in gt["params"]
    img = cv2.imread(str(out / gt["image"]))
    assert img.shape == (1000, 1000, 3)
    assert meta["render"]["image_format"] == "jpeg" and meta["render"]["jpeg_quality"] == 95


def test_twin_jpeg_is_encoded_as_the_example(one_worker):
    """The twin's JPEGs carry the published example's quantisation tables and 4:2:0
    sampling: both came out of cv2.imwrite at quality 95."""
    out, _ = one_worker
    example = jpeg_layout(EXAMPLE.read_bytes())
    assert example.sampling == ((2, 2), (1, 1), (1, 1))  # 4:2:0
    assert jpeg_quality(EXAMPLE.read_bytes()) == 95
    for path in sorted((out / "images").iterdir()):
        assert jpeg_layout(path.read_bytes()) == example, path.name


def test_png_on_request_keeps_the_gt(one_worker, tmp_path):
    """``--set output.format=png`` writes PNGs; the GT differs only in the image path (and
    the ``--set`` it records)."""
    out, _ = one_worker
    proc = _generate(tmp_path / "png", "--set", "output.format=png", count=1)
    assert proc.returncode == 0, proc.stderr
    assert [p.name for p in (tmp_path / "png" / "images").iterdir()] == ["000000.png"]
    gt_png = json.loads((tmp_path / "png" / "gt" / "000000.json").read_text())
    gt_jpg = json.loads((out / "gt" / "000000.json").read_text())
    assert gt_png.pop("image") == "images/000000.png"
    assert gt_jpg.pop("image") == "images/000000.jpg"
    assert gt_png.pop("overrides") == {"output.format": "png"} and gt_jpg.pop("overrides") == {}
    assert gt_png == gt_jpg


@pytest.mark.integration
def test_two_workers_write_byte_identical_files(one_worker, tmp_path):
    out, _ = one_worker
    proc = _generate(tmp_path / "two", "--workers", "2")
    assert proc.returncode == 0, proc.stderr
    assert _files(tmp_path / "two") == _files(out)


@pytest.mark.integration
def test_rerun_does_nothing_and_interrupted_run_resumes(one_worker, tmp_path):
    out, _ = one_worker
    reference = _files(out)
    proc = _generate(out)
    assert proc.returncode == 0 and f"already complete: {COUNT} images" in proc.stdout
    assert "images/s" not in proc.stdout
    assert _files(out) == reference
    # simulate an interrupted run: an image, a GT file and the final files are missing
    copy = tmp_path / "copy"
    copy.mkdir()
    for rel, data in reference.items():
        if rel in {"images/000001.jpg", "gt/000003.json", "manifest.jsonl", "coco.json"}:
            continue
        (copy / rel).parent.mkdir(parents=True, exist_ok=True)
        (copy / rel).write_bytes(data)
    meta = json.loads(reference["dataset.json"])
    meta["complete"] = False
    (copy / "dataset.json").write_text(json.dumps(meta))
    proc = _generate(copy)
    assert proc.returncode == 0, proc.stderr
    assert "2 rendered" in proc.stdout and "2 already present" in proc.stdout
    assert _files(copy) == reference


@pytest.mark.parametrize(
    ("extra", "kwargs", "needle"),
    [
        ((), {"seed": 8}, "--seed"),
        ((), {"count": 3}, "--count 3 is smaller"),
        (("--set", "obstacles.count=2"), {}, "--set"),
        (("--preset", "eyrc-hard"), {}, "--preset"),
        (("--preset", "eyrc-hard"), {"count": 6}, "--preset"),
    ],
)
def test_different_arguments_are_refused(one_worker, extra, kwargs, needle):
    out, _ = one_worker
    before = _files(out)
    proc = _generate(out, *extra, **kwargs)
    assert proc.returncode == 2
    assert needle in proc.stderr
    assert "different arguments" in proc.stderr or "smaller" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert _files(out) == before


@pytest.mark.integration
def test_larger_count_extends_the_set_byte_identically(one_worker, tmp_path):
    """Extending a set with the same seed gives the files of the larger count at once."""
    out, _ = one_worker
    grown = tmp_path / "grown"
    proc = _generate(grown, count=2)
    assert proc.returncode == 0, proc.stderr
    proc = _generate(grown, count=COUNT)
    assert proc.returncode == 0, proc.stderr
    assert "2 rendered" in proc.stdout and "2 already present" in proc.stdout
    assert _files(grown) == _files(out)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--set", "camera.nope=1"), "camera.nope"),
        (("--set", "camera.tilt_deg=steep"), "camera.tilt_deg"),
        (("--preset", "nosuch"), "nosuch"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(tmp_path, args, needle):
    proc = _generate(tmp_path / "bad", *args)
    assert proc.returncode == 2
    assert needle in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad").exists()


def test_coco_json_loads_in_pycocotools_and_areas_agree(one_worker):
    coco_mod = pytest.importorskip("pycocotools.coco")
    out, _ = one_worker
    coco = coco_mod.COCO(str(out / "coco.json"))
    assert sorted(c["name"] for c in coco.loadCats(coco.getCatIds())) == ["marker", "obstacle"]
    assert len(coco.getImgIds()) == COUNT
    n_obstacles = 0
    for img_id in coco.getImgIds():
        gt = json.loads((out / "gt" / f"{img_id:06d}.json").read_text())
        anns = coco.loadAnns(coco.getAnnIds(imgIds=[img_id]))
        obstacles = [a for a in anns if a["category_id"] == 1]
        assert len(obstacles) == gt["count"]
        assert len([a for a in anns if a["category_id"] == 2]) == 4
        for ann in anns:
            mask = coco.annToMask(ann)
            assert mask.sum() == pytest.approx(ann["area"], rel=0.03), ann["id"]
            x, y, w, h = ann["bbox"]
            ys, xs = np.nonzero(mask)
            assert xs.min() >= np.floor(x) and xs.max() <= np.ceil(x + w)
            assert ys.min() >= np.floor(y) and ys.max() <= np.ceil(y + h)
        n_obstacles += len(obstacles)
    assert n_obstacles >= COUNT


def test_coco_from_the_workers_equals_coco_from_the_gt_files(one_worker):
    """``coco.json`` is assembled from the COCO shares the workers send back; it is the same
    bytes as the COCO file computed from the GT files on disk."""
    from arenabench.fileio import dumps_json
    from arenabench.generator.dataset.dataset_writer import coco_from_gts
    from arenabench.gtrecord import GroundTruth

    out, _ = one_worker
    gts = [GroundTruth.from_dict(json.loads((out / "gt" / f"{i:06d}.json").read_bytes()))
           for i in range(COUNT)]
    assert (out / "coco.json").read_text() == dumps_json(coco_from_gts(gts))
    assert json.loads((out / "coco.json").read_text())["annotations"]  # boxes and markers
