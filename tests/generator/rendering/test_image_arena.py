"""An image file as the arena floor (``arena.texture = "image"``): the picture is the floor,
at its own texel grid, with no lines or text drawn over it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from arenabench.generator.assets.texture_store import import_texture
from arenabench.generator.model.scene import IMAGE_TEXTURE, ArenaSpec
from arenabench.generator.rendering.textures import floor_texture


@pytest.fixture
def picture(tmp_path, monkeypatch):
    """A 512-texel grey picture's reference (read into a private texture cache)."""
    monkeypatch.setenv("ARENABENCH_CACHE_DIR", str(tmp_path / "cache"))
    path = tmp_path / "floor.png"
    cv2.imwrite(str(path), np.full((512, 512, 3), 240, np.uint8))
    return import_texture(path)


def test_an_image_floor_of_another_size_keeps_its_own_texel_grid(picture):
    """A 512-texel picture (the default texel grid is 2048) is the floor texture as it is."""
    arena = ArenaSpec(side_m=4.0, margin_m=0.5, texture=IMAGE_TEXTURE, texture_file=picture,
                      texture_size_m=(5.0, 5.0), floor_rgb=(255, 255, 255), border_width_m=0.0,
                      logo_text="")
    img = floor_texture(arena)
    assert img.shape == (512, 512, 3)
    assert (img == 240).all()


@pytest.mark.parametrize(("field", "value"), [("border_width_m", 0.1), ("grid_step_m", 0.5),
                                              ("logo_text", "lab 7")])
def test_lines_or_text_over_an_image_floor_are_refused(picture, field, value):
    """The picture is the floor: a border line, grid or text over it is refused in one line
    naming the field and its value."""
    base = {"side_m": 4.0, "margin_m": 0.5, "texture": IMAGE_TEXTURE, "texture_file": picture,
            "texture_size_m": (5.0, 5.0), "border_width_m": 0.0, "logo_text": ""}
    with pytest.raises(ValueError, match=rf"arena\.{field}={value!r}") as info:
        ArenaSpec(**{**base, field: value})
    assert "\n" not in str(info.value)


def test_a_held_texture_is_read_back_exactly_and_never_cached(tmp_path, monkeypatch):
    """A texture made in memory (the twin's trial textures) is found by its reference, pixel
    for pixel, without a file in the cache; released, it is gone."""
    from arenabench.generator.assets import texture_store

    monkeypatch.setenv("ARENABENCH_CACHE_DIR", str(tmp_path / "cache"))
    rgb = np.random.default_rng(0).integers(0, 256, (64, 96, 3), dtype=np.uint8)
    ref = texture_store.hold_texture(rgb)
    try:
        assert texture_store.has(ref)
        assert np.array_equal(texture_store.texture_rgb(ref), rgb)
        assert not (tmp_path / "cache" / "textures").exists()
        texture_store.keep_held(ref)
        assert (tmp_path / "cache" / ref).is_file()
    finally:
        texture_store.release_held()
    other = texture_store.hold_texture(rgb[::-1].copy())
    texture_store.release_held()
    assert not texture_store.has(other)
