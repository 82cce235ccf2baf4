"""A scene seen again is not drawn again: the renderer keeps its last output and the ground
truth of the last scenes is kept, so a sweep over post-render parameters renders each base
scene once. The bytes never change: a reused render equals a fresh renderer's, and every
caller gets arrays of its own."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from arenabench.eval.sweep.execution import (
    BATCHES_PER_WORKER,
    post_render_only,
    run_sweep,
    sweep_batches,
    sweep_points,
    sweep_tasks,
)
from arenabench.eval.sweep.grid import parse_varies
from arenabench.eval.sweep.records import PipelineSpec, SweepSpec
from arenabench.generator.dataset.make import make_sample
from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.rendering.render import Renderer
from arenabench.generator.truth.groundtruth import compute_ground_truth
from arenabench.imageio import encode_png


def _scenes(preset: str = "eyrc-jitter"):
    return [sample_scene(preset, seed=2, index=i).scene for i in range(2)]


def _fresh(scene, **kw):
    with Renderer() as r:
        return r.render(scene, **kw)


def _equal(a, b) -> None:
    for name in ("rgb", "depth", "instance_mask"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)


@pytest.mark.integration
def test_a_scene_seen_again_is_not_drawn_again_and_gives_the_same_bytes():
    a, b = _scenes()
    want_a, want_b = _fresh(a, depth=True, masks=True), _fresh(b)
    with Renderer() as r:
        first = r.render(a, depth=True, masks=True)
        draws = 0
        draw = r._offscreen.render

        def counted(*args, **kw):  # the real draw, counted
            nonlocal draws
            draws += 1
            return draw(*args, **kw)

        r._offscreen.render = counted
        first.rgb[:] = 0  # the caller may write into what it got ...
        first.depth[:] = 0
        first.instance_mask[:] = 0
        again = r.render(a, depth=True, masks=True)
        assert draws == 0  # ... the same scene again: not drawn
        again.rgb[:] = 1
        twice = r.render(a, depth=True, masks=True)
        assert draws == 0
        plain = r.render(a)  # other outputs asked for: drawn
        assert draws > 0
        other = r.render(b)
        back = r.render(a, depth=True, masks=True)
    for out in (again, twice, back):
        assert out is not first and out.rgb.flags.writeable
    _equal(twice, want_a)
    _equal(back, want_a)
    _equal(other, want_b)
    assert plain.depth is None and plain.instance_mask is None
    np.testing.assert_array_equal(plain.rgb, want_a.rgb)


def test_ground_truth_of_a_scene_seen_again_is_equal_and_a_new_dict():
    a, b = _scenes("warehouse")
    first = compute_ground_truth(a)
    first["count"] = -1
    first["obstacles"].clear()
    again = compute_ground_truth(a)
    assert again["count"] >= 0 and len(again["obstacles"]) == len(a.obstacles)
    assert again == compute_ground_truth(a) != compute_ground_truth(b)


def test_batches_keep_each_scene_s_points_together_when_only_post_render_varies():
    spec = SweepSpec(preset="eyrc", axes=parse_varies(["degrade.noise_sigma=0,10,20,30"]),
                     per_point=25, seed=1, pipelines=(PipelineSpec("pipeline", "reference"),))
    assert post_render_only(spec)
    tasks = sweep_tasks(spec, sweep_points(spec))
    for workers in (1, 2, 16):
        for by_scene in (True, False):
            batches = sweep_batches(tasks, workers, by_scene=by_scene)
            flat = [t for batch in batches for t in batch]
            assert sorted(flat, key=lambda t: (t.point, t.scene)) == tasks  # each task once
            limit = max(1, len(tasks) // (workers * BATCHES_PER_WORKER))
            assert max(map(len, batches)) <= limit  # still spread over the workers
            for batch in batches:
                if by_scene:  # one base scene per batch, its points in order
                    assert len({t.index for t in batch}) == 1
                    assert [t.point for t in batch] == sorted(t.point for t in batch)
                else:  # the points in order
                    assert list(batch) == tasks[tasks.index(batch[0]):][:len(batch)]
    assert max(map(len, sweep_batches(tasks, 2, by_scene=True))) == 4  # all 4 points at once
    independent = sweep_tasks(replace(spec, independent_scenes=True), sweep_points(spec))
    assert all(len(b) == 1 for b in sweep_batches(independent, 2, by_scene=True))
    # a render parameter on an axis: scenes differ between points
    tilt = replace(spec, axes=parse_varies(["degrade.noise_sigma=0,10",
                                            "camera.tilt_deg=0,10"]))
    assert not post_render_only(tilt)


@pytest.mark.integration
def test_a_noise_sweep_gives_the_images_of_a_fresh_renderer(tmp_path):
    """Two workers, each scene's points in one batch (its render reused): every kept image
    has the bytes of that scene rendered and degraded on its own."""
    spec = SweepSpec(preset="eyrc-hard", axes=parse_varies(["degrade.noise_sigma=0,15,30"]),
                     per_point=2, seed=4, keep="all",
                     pipelines=(PipelineSpec("pipeline", "reference"),))
    kept: dict[tuple[int, int], bytes] = {}
    result = run_sweep(spec, workers=2,
                       on_output=lambda o: kept.__setitem__((o["point"], o["scene"]), o["image"]))
    assert result.run["complete"] and len(kept) == 6
    points = sweep_points(spec)
    for (p, s), png in sorted(kept.items()):
        with Renderer() as fresh:
            sample = make_sample(spec.preset, seed=spec.seed, index=s,
                                 overrides={**spec.overrides, **points[p]}, renderer=fresh)
        assert png == encode_png(sample.bgr), (p, s)


@pytest.mark.integration
def test_a_render_interrupted_between_two_node_updates_leaves_the_renderer_usable():
    """Ctrl-C may land anywhere in a render; the next render must still be right (it failed
    with "node not in the digraph" when the camera had been removed and not added back)."""
    import sys

    a, b = _scenes()
    want = _fresh(b)

    def interrupt_after_camera_removal(frame, event, arg):
        if frame.f_code.co_name != "_update_dynamic":
            return None

        def line(frame, event, arg):
            if event == "line" and "cam.intrinsics" in _source_line(frame):
                raise KeyboardInterrupt
            return line
        return line

    with Renderer() as r:
        r.render(a)
        sys.settrace(interrupt_after_camera_removal)
        try:
            with pytest.raises(KeyboardInterrupt):
                r.render(b)
        finally:
            sys.settrace(None)
        _equal(r.render(b), want)


def _source_line(frame) -> str:
    import linecache

    return linecache.getline(frame.f_code.co_filename, frame.f_lineno)
