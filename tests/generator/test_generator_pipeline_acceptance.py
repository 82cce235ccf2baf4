"""Acceptance: the reference pipeline on 200 clean ``eyrc`` scenes.

It must get the exact count and the visible area within 5 % on at least 95 % of them. The
measured pass rate is printed (run with ``-s`` to see it) and kept in the assertion message.
"""

from __future__ import annotations

import pytest

from arenabench.generator.dataset.make import make_sample
from arenabench.generator.rendering.render import Renderer
from arenabench.pipeline import DetectConfig, detect

N_SCENES = 200
SEED = 2024
TOLERANCE = 0.05


@pytest.mark.acceptance
def test_reference_pipeline_passes_on_95_percent_of_eyrc_scenes():
    config = DetectConfig()
    passed, failures = 0, []
    with Renderer() as renderer:
        for i in range(N_SCENES):
            s = make_sample("eyrc", seed=SEED, index=i, renderer=renderer)
            det = detect(s.bgr, config)
            gt_count, gt_area = s.gt["count"], s.gt["area"]["visible_px"]
            err = (det.total_area - gt_area) / gt_area if det.status == "ok" else None
            ok = det.status == "ok" and det.count == gt_count and abs(err) <= TOLERANCE
            if ok:
                assert sorted(det.marker_ids) == [80, 85, 90, 95]
                passed += 1
            else:
                failures.append((s.id, det.status, det.count, gt_count, err))
    rate = passed / N_SCENES
    print(f"reference pipeline on {N_SCENES} eyrc scenes (seed {SEED}): pass rate {rate:.3f}")
    assert rate >= 0.95, f"pass rate {rate:.3f}; failures: {failures[:10]}"
