"""Bench item 9 (an external Python script per image) on the competition's example image, for
real: in one process, cold and warm, and the warm figure split into the server's start and
the CPU per later image. Figures are not judged here (speed belongs to the benchmark)."""

from __future__ import annotations

import shutil

import pytest
from paths import TESTS

from arenabench.eval.bench.items import script_per_image

EXAMPLE = TESTS / "data" / "task1c_image.jpg"


@pytest.mark.integration
def test_script_item_reports_every_figure_and_warm_answers_as_cold(tmp_path):
    images = []
    for i in range(3):
        images.append(tmp_path / f"{i}.jpg")
        shutil.copyfile(EXAMPLE, images[-1])
    figures, details = script_per_image(images)
    assert set(figures) == {"script_inprocess_cpu_ms", "script_cold_cpu_ms",
                            "script_warm_cpu_ms", "script_warm_vs_inprocess",
                            "script_cold_vs_inprocess"}
    assert all(v > 0 for v in figures.values())
    assert figures["script_warm_vs_inprocess"] == pytest.approx(
        figures["script_warm_cpu_ms"] / figures["script_inprocess_cpu_ms"])
    assert details["warm_equals_cold"] and details["ok"] == 3
    assert details["warm_start_and_one_run_cpu_ms"] > 0
    assert details["images"] == 3
