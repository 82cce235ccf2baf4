"""Textures are sampled as ogre2 samples a diffuse map (docs/rendering.md, "Textures"): stored
as sRGB, the mip chain averaged in linear light, trilinear; a uniform texture keeps its value."""

from __future__ import annotations

import numpy as np
import pytest

from arenabench.generator.rendering.edges import linear_to_srgb
from arenabench.generator.rendering.textures import halve_in_linear_light

#: A 1-texel black / white checker seen from far enough that only its mip levels >= 1 are
#: sampled: each of those is the checker's mean, 0.5 in linear light.
CHECKER_TEXELS = 256
VIEW_PX = 64  # 4 texels per pixel: level of detail 2
LINEAR_HALF = int(linear_to_srgb(0.5))  # 188; averaging the sRGB numbers would give 128


def _render_quad(image: np.ndarray, factor: float = 1.0) -> np.ndarray:
    """A quad filling a VIEW_PX square view, textured with ``image``, drawn by the generator's
    flat pass (:class:`~arenabench.generator.rendering.pyrender_compat.LeanOffscreen`)."""
    from arenabench.generator.rendering import pyrender_compat as compat
    from arenabench.generator.rendering.render import _texture, _textured_quad

    pr = compat.pyrender
    scene = pr.Scene(bg_color=[0.0, 0.0, 0.0, 1.0], ambient_light=[1, 1, 1])
    corners = np.array([[-1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])
    scene.add(_textured_quad(pr, corners, 0.0, _texture(compat, image), factor), name="3:0")
    pose = np.eye(4)
    pose[2, 3] = 1.0
    scene.add(pr.OrthographicCamera(xmag=1.0, ymag=1.0, znear=0.1, zfar=10.0), pose=pose)
    off = compat.LeanOffscreen(VIEW_PX, VIEW_PX)
    try:
        rgb, _ = off.render(scene, pr.RenderFlags.FLAT | pr.RenderFlags.SKIP_CULL_FACES)
    finally:
        off.close()
    return np.asarray(rgb)


def test_halving_averages_in_linear_light():
    tile = np.array([[0, 255], [255, 0]], np.uint8)[:, :, None].repeat(3, axis=2)
    assert LINEAR_HALF == 188
    assert (halve_in_linear_light(np.tile(tile, (3, 3, 1))) == LINEAR_HALF).all()
    grey = np.full((6, 8, 3), 120, np.uint8)
    assert (halve_in_linear_light(grey) == 120).all()
    assert halve_in_linear_light(np.zeros((5, 7, 3), np.uint8)).shape == (2, 3, 3)


def test_gl_filters_a_minified_texture_in_linear_light():
    """The GPU's mip chain and trilinear filter average in linear light, as ogre2's sRGB
    textures do: a minified black / white checker is grey 188, not 128."""
    y, x = np.mgrid[:CHECKER_TEXELS, :CHECKER_TEXELS]
    checker = np.where((x + y) % 2 == 0, 0, 255).astype(np.uint8)[:, :, None].repeat(3, axis=2)
    rgb = _render_quad(checker)
    inner = rgb[4:-4, 4:-4].astype(int)
    assert np.abs(inner - LINEAR_HALF).max() <= 1, (inner.min(), inner.max())


@pytest.mark.parametrize(("value", "factor"), [(120, 1.0), (248, 1.0), (200, 0.9), (37, 0.5)])
def test_uniform_texture_keeps_its_value_times_the_shade(value, factor):
    """Decoding to linear light and encoding back leaves a uniform region as it was; the
    floor's shade then scales the sRGB value (as before the texture was sRGB)."""
    rgb = _render_quad(np.full((32, 32, 3), value, np.uint8), factor)
    want = round(value * factor)
    assert np.abs(rgb[4:-4, 4:-4].astype(int) - want).max() == 0
