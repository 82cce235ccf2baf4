"""Big sets stream: the reader keeps ids and paths only, a run keeps its results in a
temporary file, the report files and coco.json are written as streams, with the same bytes as
when everything is held in memory; and a 100,000-image set evaluates under 1 GB."""

import csv
import hashlib
import json
import math
import subprocess
import sys
from dataclasses import replace

import pytest

from arenabench.eval.datasets.bigset import fixed_answer, write_big_set
from arenabench.eval.datasets.reader import DatasetError, DatasetSamples, load_dataset
from arenabench.eval.datasets.result_store import ResultStore, StoredResults
from arenabench.eval.evaluation import evaluate
from arenabench.eval.reports import FORMATS, write_reports
from arenabench.fileio import dumps_json
from arenabench.jsonstream import Streamed, write_json_stream


@pytest.fixture(scope="module")
def small_set(tmp_path_factory):
    return write_big_set(tmp_path_factory.mktemp("big") / "set", 60, templates=6)


@pytest.mark.parametrize("doc", [
    {"images": [{"x": [1, 2.5, {"y": math.nan}], "s": "a\nb\u2028"}, {"z": {}}], "b": {"c": []}},
    {"images": [], "annotations": [1, [2, [3, {}]]], "z": "\u00e9", "info": {"k": None}},
    {"n": {"images": [[1, [2, 3]], []], "m": math.inf}},
])
def test_streamed_json_has_the_bytes_of_dumps_json(tmp_path, doc):
    def streamed(obj):
        if isinstance(obj, dict):
            return {k: Streamed(iter(v)) if k in ("images", "annotations") else streamed(v)
                    for k, v in obj.items()}
        return obj

    path = write_json_stream(tmp_path / "x.json", streamed(doc))
    assert path.read_text(encoding="utf-8") == dumps_json(doc)
    assert [p.name for p in tmp_path.iterdir()] == ["x.json"]  # no temporary file left


def test_reader_keeps_paths_and_reads_a_gt_when_its_item_is_taken(small_set, tmp_path):
    data = load_dataset(small_set.root)
    assert isinstance(data.samples, DatasetSamples)
    assert len(data) == 60 and data.samples.ids[:2] == ["000000", "000001"]
    item = data.samples[7]
    assert item.id == "000007" and item.gt.index == 7
    assert item.image_path == small_set.root.resolve() / "images" / "000007.png"
    assert item.params and all(isinstance(v, float) for v in item.params.values())
    assert [s.id for s in data.samples[10:13]] == ["000010", "000011", "000012"]
    assert data.presets() == ["eyrc"]
    assert set(data.items_by_id(["000003", "nope"])) == {"000003"}
    # a GT file changed after loading is named when its item is taken
    gt = small_set.root / "gt" / "000009.json"
    text = gt.read_text()
    try:
        gt.write_text(text.replace('"index": 9', '"index": 10'))
        with pytest.raises(DatasetError, match=r"000009\.json: changed since the dataset"):
            data.samples[9]
    finally:
        gt.write_text(text)


def test_big_set_scores_as_its_builder_says(small_set):
    report = evaluate(fixed_answer, small_set.root, workers=2)
    assert report.summary.n == 60
    assert report.summary.n_passed == small_set.passes > 0


@pytest.mark.integration
def test_spilled_run_gives_the_same_report_files(small_set, tmp_path):
    """A run's results kept in a file give the same report files as in memory (the same
    report written both ways), and the same results as a run kept in memory."""
    data = load_dataset(small_set.root)
    held = evaluate(fixed_answer, data, workers=2, spill=False)
    spilled = evaluate(fixed_answer, data, workers=2, spill=True)
    assert isinstance(spilled.images, StoredResults) and isinstance(held.images, tuple)

    def without_latency(report):
        return [replace(r, prediction=replace(r.prediction, latency_ms=0.0))
                for r in report.images]

    assert without_latency(spilled) == without_latency(held)
    assert spilled.summary.n_passed == held.summary.n_passed
    assert spilled.breakdown.keys() == held.breakdown.keys()
    store = ResultStore(len(held.images), spill=True)
    for i, r in enumerate(held.images):
        store.add(i, r)
    write_reports(held, tmp_path / "held", dataset=data)
    write_reports(replace(held, images=store.images()), tmp_path / "spilled", dataset=data)
    for name in FORMATS.values():
        assert (tmp_path / "held" / name).read_bytes() == \
            (tmp_path / "spilled" / name).read_bytes(), name
    saved = json.loads((tmp_path / "spilled" / "report.json").read_text())
    assert saved == json.loads(dumps_json(held.to_dict()))


@pytest.mark.acceptance  # a measurement against a bound: minutes
def test_100k_images_evaluate_in_under_1_gb(tmp_path):
    """``arenabench eval`` of a synthetic 100,000-entry set with a do-nothing pipeline: the
    command's largest process stays under 1 GB and the report counts every image."""
    n = 100_000
    big = write_big_set(tmp_path / "set", n)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "arenabench", "eval", str(big.root),
               "--pipeline", "arenabench.eval.datasets.bigset:fixed_answer", "--phase-check", "off",
               "--workers", "2", "--no-progress", "--out", str(out)]
    # a fresh process whose only children are the command's: their largest peak RSS
    probe = ("import resource, subprocess, sys; rc = subprocess.call(sys.argv[1:]); "
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(rc)")
    proc = subprocess.run([sys.executable, "-c", probe, *command], capture_output=True,
                          text=True, timeout=3600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    peak_kb = int(proc.stdout.split()[-1])
    assert peak_kb < 1_000_000, f"peak RSS {peak_kb / 1024:.0f} MB"
    report = json.loads((out / "report.json").read_text())
    assert report["summary"]["n"] == n and len(report["images"]) == n
    assert report["summary"]["n_passed"] == big.passes
    with open(out / "results.csv", newline="") as fh:
        assert sum(1 for _ in csv.reader(fh)) == n + 1
    assert (out / "junit.xml").read_text().count("<testcase ") == n


def _first_error(root, workers):
    try:
        load_dataset(root, workers=workers)
    except DatasetError as exc:
        return str(exc)
    return None


@pytest.mark.integration
def test_several_processes_refuse_junk_ids_and_gt_values_first_as_one_does(small_set,
                                                                          tmp_path):
    import shutil

    root = tmp_path / "set"
    shutil.copytree(small_set.root, root)
    one, two = load_dataset(root, workers=1), load_dataset(root, workers=2)
    assert one.facts == two.facts and one.facts.weakest_seed == (0, 0)  # every GT says seed 0
    manifest = root / "manifest.jsonl"
    lines = manifest.read_text().splitlines(keepends=True)
    entry = json.loads(lines[50])
    entry["id"] = "../x"
    manifest.write_text("".join([*lines[:50], json.dumps(entry) + "\n", *lines[51:]]))
    assert "manifest.jsonl:51: field 'id' '../x'" in _first_error(root, 1)
    assert _first_error(root, 2) == _first_error(root, 1)
    gt = root / "gt" / "000020.json"
    doc = json.loads(gt.read_text())
    doc["markers"][1]["id"] = float(doc["markers"][1]["id"])
    gt.write_text(json.dumps(doc))
    lines = manifest.read_text().splitlines(keepends=True)
    entry = json.loads(lines[20])
    entry["gt_sha256"] = hashlib.sha256(gt.read_bytes()).hexdigest()
    lines[20] = json.dumps(entry) + "\n"
    manifest.write_text("".join(lines))
    first = _first_error(root, 1)
    assert "000020.json: markers[1].id" in first and "is not an integer" in first
    assert _first_error(root, 2) == first


@pytest.mark.integration
def test_checking_on_several_processes_gives_the_same_dataset_and_first_error(tmp_path):
    big = write_big_set(tmp_path / "set", 5000, templates=4)
    one, two = load_dataset(big.root, workers=1), load_dataset(big.root, workers=2)
    assert one.samples.ids == two.samples.ids and one.facts == two.facts
    manifest = big.root / "manifest.jsonl"
    lines = manifest.read_text().splitlines(keepends=True)
    # a duplicate id late in the manifest, a broken GT file earlier: the GT's error comes first
    manifest.write_text("".join([*lines[:4500], lines[10], *lines[4500:]]))
    assert "duplicate id '000010'" in _first_error(big.root, 1)
    assert _first_error(big.root, 2) == _first_error(big.root, 1)
    gt = big.root / "gt" / "003210.json"
    gt.write_text(gt.read_text().replace('"count": ', '"count": -', 1))
    first = _first_error(big.root, 1)
    assert "003210.json" in first and _first_error(big.root, 2) == first
    # a damaged image: refused, or left out with --skip-damaged, the same either way
    manifest.write_text("".join(lines))
    gt.write_text(gt.read_text().replace('"count": -', '"count": ', 1))
    image = big.root / "images" / "004321.png"
    image.unlink()  # (a hard link: the others keep their bytes)
    image.write_bytes(b"")
    entry = json.loads(lines[4321])
    entry["image_sha256"] = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    lines[4321] = json.dumps(entry) + "\n"
    manifest.write_text("".join(lines))
    assert "dataset damaged" in _first_error(big.root, 1)
    assert _first_error(big.root, 2) == _first_error(big.root, 1)
    kept = [load_dataset(big.root, workers=w, skip_damaged=True) for w in (1, 2)]
    assert kept[0].skipped == kept[1].skipped == (("004321", "empty file"),)
    assert kept[0].samples.ids == kept[1].samples.ids and len(kept[1]) == 4999
