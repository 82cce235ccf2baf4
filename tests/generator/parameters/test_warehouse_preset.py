"""The warehouse preset: concrete floor, pallets and coloured crates, clutter; GT unaffected."""

import numpy as np

from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.model.scene import ArenaSpec
from arenabench.generator.rendering.textures import floor_texture


def test_concrete_texture_is_seeded_and_textured():
    a = floor_texture(ArenaSpec(texture="concrete", texture_seed=1, margin_m=1.0), texels=256)
    b = floor_texture(ArenaSpec(texture="concrete", texture_seed=1, margin_m=1.0), texels=256)
    c = floor_texture(ArenaSpec(texture="concrete", texture_seed=2, margin_m=1.0), texels=256)
    plain = floor_texture(ArenaSpec(texture="plain", margin_m=1.0), texels=256)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.astype(float).std() > plain.astype(float).std() + 2
    # yellow lane paint in the margin: red and green well above blue somewhere
    r, g, bl = (a[..., k].astype(int) for k in range(3))
    assert ((r - bl > 100) & (g - bl > 80)).any()


def test_warehouse_scenes_have_pallets_and_coloured_crates():
    scenes = [sample_scene("warehouse", seed=0, index=i) for i in range(30)]
    obstacles = [o for s in scenes for o in s.scene.obstacles]
    assert all(s.scene.arena.texture == "concrete" for s in scenes)
    assert len({s.scene.arena.texture_seed for s in scenes}) > 1
    colourful = [o for o in obstacles if max(o.color_rgb) - min(o.color_rgb) > 40]
    assert len(colourful) > len(obstacles) // 2
    assert any(o.height_m <= 0.2 for o in obstacles)  # pallets
    assert any(s.scene.patches for s in scenes)  # tape / paper clutter


def test_eyrc_jitter_draws_are_unchanged_by_the_warehouse_options():
    # eyrc never draws a palette colour or a texture seed from the scene stream
    s = sample_scene("eyrc-jitter", seed=3, index=4).scene
    assert all(len(set(o.color_rgb)) == 1 for o in s.obstacles)
    assert s.arena.texture == "plain" and s.arena.texture_seed == 0
