"""Without an arena texture: one rectified from the image itself, the boxes masked out.

Each texel of the floor square is looked up in the image through the fitted camera (the floor's
homography); texels the image does not show, or shows under a box, are filled from their
neighbours (``cv2.inpaint``) or with the floor's grey. The texture is stored relative to the
floor's grey (the floor's commonest grey becomes white, and ``arena.floor_rgb`` tints it back),
so the floor grey stays a parameter of its own.

Sampling a texture twice (once by the camera that took the image, once by the twin's renderer)
blurs it twice; so the texture is then corrected by back-projection (:data:`ROUNDS` rounds): the
twin's render of the floor, boxes left out, is compared with the image, and the difference,
looked up through the same map, is added to the texture.

Markers painted into the texture (where drawn sheets do not match the image) are painted on
the texel grid that matches them best (:func:`texel_grid_search`): their finest blends, and
the default ArUco detector's whole-pixel corners with them, depend on it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np

from arenabench.generator.assets.texture_store import hold_texture
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import floor_extent
from arenabench.generator.model.scene import IMAGE_TEXTURE, Scene
from arenabench.interrupts import checkpoint

#: Back-projection rounds.
ROUNDS = 4
#: Texels per image pixel across the floor (at least; a power of two a side, at most
#: :data:`MAX_TEXELS`).
TEXELS_PER_PX = 2.0
#: The largest texture side.
MAX_TEXELS = 2048
#: Painted markers: the texture sides tried (:func:`texel_grid_search`) lie in this range.
GRID_SIDES = (2048, 4096)
#: ... and put the markers' outer corners this many texels apart from the texture's edge: an
#: arena image is drawn on its own pixel grid, so its markers' outer edges lie on pixel
#: boundaries (the competition's: 144 texels in, a multiple of 16), and on the boundaries of
#: the texture's first mipmap levels too, which a renderer blends between at these scales.
GRID_ALIGN = 4
#: Then sides this far either way of the best, each with the floor's extent that keeps the
#: markers' corners on the same boundary: the extent moves by under 0.05 %, which the
#: floor's edge in the image places no better (about 0.6 mm of 3.7 m).
GRID_REFINE = 12
#: Pixels around the boxes left out of the texture (their edges blend with the floor).
BOX_PAD_PX = 4


@dataclass(frozen=True)
class TexelGrid:
    """The grid painted markers are printed on: ``side`` texels over a floor square of half
    side ``extent_m`` (scene units); ``cost`` the painted markers' difference from the image
    (mean absolute grey over the marker squares)."""

    side: int
    extent_m: float
    cost: float


def aligned_extent(scene: Scene, side: int, inside: int) -> float:
    """The floor square's half side (scene units) on which a grid of ``side`` texels puts
    ``scene``'s markers' outer corners ``inside`` texels in from the texture's edge."""
    return scene.arena.side_m / 2.0 / (1.0 - 2.0 * inside / side)


def with_extent(scene: Scene, extent_m: float) -> Scene:
    """``scene`` with its floor square's half side ``extent_m`` (the margin changed)."""
    return replace(scene, arena=replace(scene.arena,
                                        margin_m=round(extent_m - scene.arena.side_m / 2, 9)))


def texel_map(scene: Scene, texels: int) -> tuple[np.ndarray, np.ndarray]:
    """Image px (x map, y map; float32 (texels, texels)) of each texel centre of the floor
    square (row 0 north)."""
    e = floor_extent(scene.arena)
    centres = (np.arange(texels) + 0.5) * (2.0 * e / texels) - e
    h = cam.floor_homography(cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera))
    u = np.empty((texels, texels), np.float32)
    v = np.empty((texels, texels), np.float32)
    x = centres[None, :]
    # in bands of rows: the same float64 arithmetic, without (texels, texels) float64 arrays
    # (four of them were 0.5 GB at 4,000 texels)
    for r0 in range(0, texels, MAP_ROWS):
        y = -centres[r0:r0 + MAP_ROWS, None]
        den = h[2, 0] * x + h[2, 1] * y + h[2, 2]
        u[r0:r0 + MAP_ROWS] = (h[0, 0] * x + h[0, 1] * y + h[0, 2]) / den
        v[r0:r0 + MAP_ROWS] = (h[1, 0] * x + h[1, 1] * y + h[1, 2]) / den
    return u, v


#: Rows of :func:`texel_map` computed at once.
MAP_ROWS = 256


def texture_side(scene: Scene) -> int:
    """Texels a side: a power of two giving at least :data:`TEXELS_PER_PX` texels per image
    px across the floor."""
    mx, _ = texel_map(scene, 64)
    px_per_side = float(np.nanmax(mx) - np.nanmin(mx))
    n = 256
    while n < TEXELS_PER_PX * px_per_side and n < MAX_TEXELS:
        n *= 2
    return n


def aligned_sides(scene: Scene, *, sides: tuple[int, int] = GRID_SIDES,
                  align: int = GRID_ALIGN) -> list[int]:
    """Texture sides within ``sides`` on which ``scene``'s markers' outer corners lie a
    multiple of ``align`` texels in from the texture's edge (the floor square's edge), the
    nearest whole side to each such grid.

    Raises
    ------
    ValueError
        When the arena's floor has no margin outside the markers (nothing to align).
    """
    e = floor_extent(scene.arena)
    share = (e - scene.arena.side_m / 2.0) / (2.0 * e)  # texels in, per texel a side
    if share <= 0:
        raise ValueError(f"arena.margin_m must be > 0 to align a texel grid, got "
                         f"{scene.arena.margin_m!r}")
    lo, hi = sides
    ks = range(int(np.ceil(lo * share / align)), int(np.floor(hi * share / align)) + 1)
    return sorted({round(align * k / share) for k in ks})


def paint_markers(texture: np.ndarray, scene: Scene, *, supersample: int = 4) -> np.ndarray:
    """Paint the four markers into ``texture`` (in place) from their dictionary's modules at
    their fitted place: black 0, white the floor's (255 in the texture), each texel's share
    from ``supersample`` x ``supersample`` samples. A marker is a printed pattern the image
    shows only blurred once (by the camera that took it); rectified, it would be blurred a
    second time by the twin's renderer, and its black and white leave no room to sharpen it
    back. Returns the texels painted (bool)."""
    from arenabench.frame import CORNER_ORDER
    from arenabench.generator.fitting.marker_model import module_pattern
    from arenabench.generator.model.layout import marker_corners_world

    n = texture.shape[0]
    e = floor_extent(scene.arena)
    texel = 2.0 * e / n
    painted = np.zeros(texture.shape[:2], bool)
    offs = (np.arange(supersample) + 0.5) / supersample - 0.5
    for corner, marker_id in zip(CORNER_ORDER, scene.markers.ids, strict=True):
        c = marker_corners_world(scene.arena, scene.markers, corner)
        modules = module_pattern(scene.markers.dictionary, marker_id)
        cells = modules.shape[0]
        u_axis, v_axis = c[1] - c[0], c[3] - c[0]
        inv = np.linalg.inv(np.column_stack([u_axis, v_axis]))
        xs, ys = c[:, 0], c[:, 1]
        j0 = max(int(np.floor((xs.min() + e) / texel)) - 1, 0)
        j1 = min(int(np.ceil((xs.max() + e) / texel)) + 1, n)
        i0 = max(int(np.floor((e - ys.max()) / texel)) - 1, 0)
        i1 = min(int(np.ceil((e - ys.min()) / texel)) + 1, n)
        jj, ii = np.meshgrid(np.arange(j0, j1), np.arange(i0, i1))
        white = np.zeros(jj.shape)
        inside = np.zeros(jj.shape)
        for dy in offs:
            for dx in offs:
                x = (jj + 0.5 + dx) * texel - e
                y = e - (ii + 0.5 + dy) * texel
                uv = np.einsum("ij,jkl->ikl", inv, np.stack([x - c[0, 0], y - c[0, 1]]))
                ok = (uv[0] >= 0) & (uv[0] < 1) & (uv[1] >= 0) & (uv[1] < 1)
                cu = np.clip((uv[0] * cells).astype(int), 0, cells - 1)
                cv = np.clip((uv[1] * cells).astype(int), 0, cells - 1)
                white += np.where(ok, modules[cv, cu], 0.0)
                inside += ok
        k = supersample * supersample
        full = inside >= k  # texels wholly inside the marker: painted
        part = (inside > 0) & ~full  # on its outline: blended with what was there
        block = texture[i0:i1, j0:j1].astype(np.float64)
        lin = _to_linear(block)
        mark = (white / k)[..., None]
        share = (inside / k)[..., None]
        blended = _to_srgb((1.0 - share) * lin + mark)  # white is 1 in linear light
        block = np.where(full[..., None], _to_srgb(mark * np.ones_like(lin)), block)
        block = np.where(part[..., None], blended, block)
        texture[i0:i1, j0:j1] = np.clip(np.rint(block), 0, 255).astype(np.uint8)
        painted[i0:i1, j0:j1] |= full
    return painted


def marker_region(scene: Scene, texels: int, grow_m: float) -> np.ndarray:
    """Texels of the floor texture within the four marker squares grown by ``grow_m`` (where
    drawn marker sheets lie: the texture there is never seen)."""
    from arenabench.frame import CORNER_ORDER
    from arenabench.generator.model.layout import marker_square

    e = floor_extent(scene.arena)
    centres = (np.arange(texels) + 0.5) * (2.0 * e / texels) - e
    x, y = np.meshgrid(centres, -centres)
    out = np.zeros((texels, texels), bool)
    for corner in CORNER_ORDER:
        x0, x1, y0, y1 = marker_square(scene.arena, scene.markers, corner)
        out |= (x >= x0 - grow_m) & (x <= x1 + grow_m) & (y >= y0 - grow_m) & (y <= y1 + grow_m)
    return out


def _to_linear(srgb: np.ndarray) -> np.ndarray:
    v = srgb / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def _to_srgb(linear: np.ndarray) -> np.ndarray:
    y = np.clip(linear, 0.0, 1.0)
    return 255.0 * np.where(y <= 0.0031308, y * 12.92, 1.055 * np.power(y, 1.0 / 2.4) - 0.055)


def with_texture(scene: Scene, texture_rgb: np.ndarray) -> Scene:
    """``scene`` on an image arena showing ``texture_rgb`` over the floor square (held in
    memory: :func:`arenabench.generator.assets.texture_store.hold_texture`); its markers printed or
    drawn as ``scene.markers.printed`` says."""
    side = round(2.0 * floor_extent(scene.arena), 6)
    arena = replace(scene.arena, texture=IMAGE_TEXTURE, texture_file=hold_texture(texture_rgb),
                    texture_size_m=(side, side), border_width_m=0.0, logo_text="",
                    grid_step_m=0.0)
    return replace(scene, arena=arena)


class Rectification:
    """The floor square looked up in the image through ``scene``'s camera (the texture before
    its markers are painted and before back-projection), with what it could not see."""

    def __init__(self, real_bgr: np.ndarray, scene: Scene, box_mask: np.ndarray, *,
                 texels: int | None = None, fill_hidden: bool = True) -> None:
        """``texels``: the texture's side (default :func:`texture_side`); ``fill_hidden``:
        inpaint the texels under the boxes (not needed where only the markers are looked at)."""
        self.scene = scene
        n = texture_side(scene) if texels is None else int(texels)
        self.mx, self.my = texel_map(scene, n)
        h, w = real_bgr.shape[:2]
        seen = (self.mx >= 0) & (self.mx <= w - 1) & (self.my >= 0) & (self.my <= h - 1)
        k = 2 * BOX_PAD_PX + 1
        self.boxes = cv2.dilate(box_mask.astype(np.uint8), np.ones((k, k), np.uint8)
                                ).astype(bool)
        hidden = cv2.remap(self.boxes.astype(np.uint8), self.mx, self.my, cv2.INTER_NEAREST,
                           borderMode=cv2.BORDER_CONSTANT, borderValue=1).astype(bool)
        from arenabench.generator.model.shading import floor_factor

        # the floor as rendered: its tint under the light
        floor = (np.asarray(scene.arena.floor_rgb, np.float64)
                 * min(floor_factor(scene.lighting), 1.0))
        self.rgb = cv2.cvtColor(real_bgr, cv2.COLOR_BGR2RGB).astype(np.float32)
        self.scale = (255.0 / np.maximum(floor, 1.0)).astype(np.float32)
        texture = cv2.remap(self.rgb, self.mx, self.my, cv2.INTER_CUBIC,
                            borderMode=cv2.BORDER_REPLICATE)
        np.multiply(texture, self.scale, out=texture)  # in place: one float image, not three
        np.clip(texture, 0, 255, out=texture)
        texture[~seen] = 255.0
        texture = texture.astype(np.uint8)
        if fill_hidden and (hidden & seen).any():
            texture = cv2.inpaint(texture, (hidden & seen).astype(np.uint8), 5,
                                  cv2.INPAINT_TELEA)
        self.texture = texture
        self.unknown = (~seen) | hidden

    def drop_maps(self) -> Rectification:
        """Free the texel maps (two float images of the texture's size), needed only to
        back-project: a texel-grid candidate is painted and rendered without them."""
        self.mx = self.my = None
        return self

    def painted(self, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
        """The texture with ``scene``'s markers painted, and the texels painted."""
        texture = self.texture.copy()
        return texture, paint_markers(texture, scene)

    def back_project(self, texture: np.ndarray, painted: np.ndarray, scene: Scene, renderer,
                     *, rounds: int = ROUNDS,
                     progress: Callable[[str], None] | None = None
                     ) -> tuple[np.ndarray, Scene]:
        """Correct ``texture`` by back-projection (module docstring); returns it and the scene
        showing it."""
        current = with_texture(scene, texture)
        work = texture.astype(np.float32)
        for r in range(1, rounds + 1):
            checkpoint()
            render = renderer.render(replace(current, obstacles=())).rgb.astype(np.float32)
            diff = (self.rgb - render) * self.scale
            diff[self.boxes] = 0.0
            back = cv2.remap(diff, self.mx, self.my, cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            back[self.unknown | painted] = 0.0
            work = np.clip(work + back, 0, 255)
            texture = np.rint(work).astype(np.uint8)
            current = with_texture(current, texture)
            if progress:
                progress(f"texture round {r}: floor difference "
                         f"{float(np.abs(self.rgb - render)[~self.boxes].mean()):.2f} grey "
                         "levels before it")
        return texture, current


def rectified_arena(real_bgr: np.ndarray, scene: Scene, box_mask: np.ndarray, renderer, *,
                    rounds: int = ROUNDS, texels: int | None = None,
                    progress: Callable[[str], None] | None = None) -> tuple[np.ndarray, Scene]:
    """The texture (RGB uint8, row 0 north; ``texels`` a side, default :func:`texture_side`)
    and ``scene`` showing it (``arena.texture`` image, its texture held in memory, which the
    caller keeps when it is the twin's): the markers painted into it when
    ``scene.markers.printed``, else left to the drawn sheets (the texture under them
    untouched)."""
    rect = Rectification(real_bgr, scene, box_mask, texels=texels)
    if scene.markers.printed:
        texture, keep = rect.painted(scene)
    else:
        texture = rect.texture.copy()
        keep = marker_region(scene, texture.shape[0], scene.markers.quiet_zone_m)
    return rect.back_project(texture, keep, scene, renderer, rounds=rounds,
                             progress=progress)


def painted_cost(real_gray: np.ndarray, scene: Scene, rect: Rectification, mask,
                 renderer) -> float:
    """Mean absolute grey difference in ``mask`` between the image and the render of
    ``scene``'s markers painted into ``rect``'s texture (boxes left out)."""
    checkpoint()
    s = replace(scene, markers=replace(scene.markers, printed=True))
    texture, _ = rect.painted(s)
    shown = with_texture(replace(s, obstacles=()), texture)
    got = cv2.cvtColor(renderer.render(shown).rgb, cv2.COLOR_RGB2GRAY)[mask]
    return float(np.abs(got - real_gray.astype(np.float64)[mask]).mean())


def texel_grid_search(real_bgr: np.ndarray, real_gray: np.ndarray, scene: Scene,
                      box_mask: np.ndarray, mask, renderer, *,
                      sides: tuple[int, int] = GRID_SIDES, refine: int = GRID_REFINE,
                      progress: Callable[[str], None] | None = None) -> TexelGrid:
    """The texel grid whose painted markers match the image best in ``mask``.

    A printed marker's finest blends (the default detector's whole-pixel corners follow them)
    depend on the grid of the texture it was printed on: its outer edges sharp where they
    lie on texel boundaries, its modules blended as they fall across texels. The image gives
    neither the grid's side nor, to a texel at the markers, the floor's extent. First the
    sides within ``sides`` that put the outer corners on boundaries at the floor's own
    extent (:func:`aligned_sides`; 27 between 2,048 and 4,096 texels for the competition's
    arena); then the ``refine`` sides either way of the best, each with the extent that keeps
    the corners on the same boundary. The painted markers' difference picks one out
    (docs/measurements.md).

    Raises
    ------
    ValueError
        When ``sides`` holds no aligned side.
    """
    tried = aligned_sides(scene, sides=sides)
    if not tried:
        raise ValueError(f"sides {sides!r} hold no side that aligns the markers' corners")
    e = floor_extent(scene.arena)
    half = scene.arena.side_m / 2.0

    def cost(n: int, extent: float) -> float:
        s = with_extent(scene, extent)
        rect = Rectification(real_bgr, s, box_mask, texels=n, fill_hidden=False).drop_maps()
        return painted_cost(real_gray, s, rect, mask, renderer)

    best = None
    for i, n in enumerate(tried, 1):
        grid = TexelGrid(n, e, cost(n, e))
        if best is None or grid.cost < best.cost:
            best = grid
        if progress:
            progress(f"texel grid {i}/{len(tried)}: {n} texels a side, {grid.cost:.2f} grey "
                     f"levels (best {best.side}: {best.cost:.2f})")
    inside = round((e - half) * best.side / (2.0 * e))  # texels from the edge to the corners
    near = [n for n in range(best.side - refine, best.side + refine + 1)
            if n != best.side and n > 2 * inside]
    for i, n in enumerate(near, 1):
        extent = aligned_extent(scene, n, inside)
        grid = TexelGrid(n, extent, cost(n, extent))
        if grid.cost < best.cost:
            best = grid
        if progress:
            progress(f"texel grid, refined {i}/{len(near)}: {n} texels over "
                     f"{extent / e:.5f} of the floor's extent, {grid.cost:.2f} grey levels "
                     f"(best {best.side}: {best.cost:.2f})")
    return best


def marker_side_search(real_gray: np.ndarray, scene: Scene, rect: Rectification, mask,
                       renderer, *, span: float = 0.01, count: int = 9
                       ) -> tuple[float, float]:
    """The marker side (within ``span`` of ``scene``'s, relative) whose painted markers,
    rendered, match the image best in ``mask`` (mean absolute grey difference): a grid of
    ``count`` sides, then a parabola through the best three. Returns (side, difference)."""
    def cost(side: float) -> float:
        s = replace(scene, markers=replace(scene.markers, side_m=side))
        return painted_cost(real_gray, s, rect, mask, renderer)

    base = scene.markers.side_m
    sides = np.linspace(base * (1 - span), base * (1 + span), count)
    costs = [cost(float(v)) for v in sides]
    i = int(np.clip(np.argmin(costs), 1, count - 2))
    a, b, c = costs[i - 1], costs[i], costs[i + 1]
    den = a - 2 * b + c
    step = sides[1] - sides[0]
    best = float(sides[i] + (0.5 * (a - c) / den * step if den > 0 else 0.0))
    return round(best, 6), cost(best)
