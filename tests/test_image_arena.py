"""An image file as the arena floor (``arena.texture = "image"``), with the lines and text the
other floors take drawn over it."""

from __future__ import annotations

import cv2
import numpy as np

from arenabench.generator.scene import IMAGE_TEXTURE, ArenaSpec
from arenabench.generator.textures import floor_texture


def test_border_line_is_drawn_over_an_image_floor_of_another_size(tmp_path):
    """The picture's own size sets the texel grid of the lines drawn over it (a 512-texel
    picture under the default 2048-texel grid used to fail with an IndexError)."""
    path = tmp_path / "floor.png"
    cv2.imwrite(str(path), np.full((512, 512, 3), 240, np.uint8))
    arena = ArenaSpec(side_m=4.0, margin_m=0.5, texture=IMAGE_TEXTURE, texture_file=str(path),
                      floor_rgb=(255, 255, 255), border_width_m=0.1, border_rgb=(20, 20, 20),
                      logo_text="")
    img = floor_texture(arena)
    assert img.shape == (512, 512, 3)
    # the border line's centre (x = 2 m) at texel (2 + 2.5) / 5 * 512 = 460.8; the floor beside
    assert (img[256, 459:462] == 20).all()
    assert (img[256, 256] == 240).all() and (img[256, 440] == 240).all()
