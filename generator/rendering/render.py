"""Off-screen rendering: the pyrender adapters of the renderer interface
(:class:`~arenabench.generator.rendering.renderer_api.SceneRenderer`).

:class:`Renderer` is the generator's renderer. One per process holds one off-screen pyrender
renderer (:class:`~arenabench.generator.rendering.pyrender_compat.LeanOffscreen`) and one pyrender
scene, reused across scenes: the floor and marker nodes are cached by their description and
only obstacle nodes and the camera change. Each render pass is a method: the colour pass
(:meth:`Renderer._colour_pass`) uses ``RenderFlags.FLAT`` with Lambertian shading baked into
colours (:mod:`arenabench.generator.model.shading`), about 3x faster than lit mode on Mesa llvmpipe,
a centre sample per pixel, and offset samples of the obstacles' region for their edges (two,
as the competition's renderer draws them, unless the scene's ``render`` section says
otherwise: :mod:`arenabench.generator.rendering.edges`); floor, markers
and background are drawn once and reused while consecutive scenes share them (the static
layer, see :meth:`Renderer._static_layer`); the mask pass (:meth:`Renderer._mask_pass`) gives
instance masks from ``RenderFlags.SEG`` (exact, one sample), on request.

:class:`NaiveRenderer` is the bench's baseline: a new pyrender renderer and scene per image,
pyrender's default lit shading, public pyrender API only.

pyrender is imported through :mod:`arenabench.generator.rendering.pyrender_compat` (pinned release,
private API), when the first renderer is created.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import cv2
import numpy as np

from arenabench import glplatform
from arenabench.frame import CORNER_ORDER
from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.model import camera as cam
from arenabench.generator.model.distractors import patch_mesh_arrays
from arenabench.generator.model.layout import (
    MARKER_Z,
    box_footprint,
    floor_corners,
    marker_corners_world,
)
from arenabench.generator.model.lens import distort_image, has_distortion, lens_canvas
from arenabench.generator.model.lights import apply_spot_light, shadow_mesh_arrays
from arenabench.generator.model.scene import IMAGE_TEXTURE, Obstacle, Scene
from arenabench.generator.model.shading import floor_factor, shade_factors
from arenabench.generator.rendering.edges import EDGE_PATTERNS, obstacle_region, resolve_samples
from arenabench.generator.rendering.renderer_api import RenderOutput, SceneRenderer
from arenabench.generator.rendering.textures import floor_texture, marker_texture
from arenabench.interrupts import deferred_stops

_GL_LINEAR = 9729
#: Trilinear: ogre2's default sampler (``HlmsSamplerblock``: min, mag and mip filters
#: ``FO_LINEAR``, anisotropy 1), which Gazebo's materials keep (docs/rendering.md).
_GL_LINEAR_MIPMAP_LINEAR = 9987
#: Bilinear in the nearest mip level, the levels averaged in sRGB values: drawn marker sheets
#: (robustness presets; the competition's markers are printed in its floor texture and sampled
#: as ogre2 does). A drawn marker a few px a module wide stays as dark, and as detectable, as in
#: generator version 5: linear-light mips and trilinear filtering made small markers' black
#: modules lighter, and cv2.aruco lost them at 640 x 480 and under rotated cameras.
_GL_LINEAR_MIPMAP_NEAREST = 9985
_GL_CLAMP_TO_EDGE = 33071


#: Texture TL, TR, BR, BL corners of a unit sheet, placed by its node's pose (v points from
#: BL to TL so that the pose keeps the winding: pyrender culls back faces).
_UNIT_QUAD = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])


#: Textures a renderer keeps for reuse between scenes, at most this many and this many bytes
#: of their images (a twin's texel-grid search makes dozens of floors of 2,000-4,000 texels a
#: side, each tens of MB as an image and more as its upload and mips): beyond, the cache starts
#: again (a texture still shown stays with its node; the pixels are the same either way). The
#: competition's arena texture (2,880 texels a side, 25 MB) and the marker sheets fit.
TEXTURE_CACHE_COUNT = 64
TEXTURE_CACHE_BYTES = 48 << 20


def _texture(compat, image: np.ndarray, *, min_filter: int = _GL_LINEAR_MIPMAP_LINEAR):
    """A texture of an RGB ``image`` as ogre2 makes one of a diffuse map: sRGB, its mip chain
    averaged in linear light, sampled trilinearly in linear light
    (:class:`~arenabench.generator.rendering.pyrender_compat.SrgbTexture`); ``min_filter``
    :data:`_GL_LINEAR_MIPMAP_NEAREST` for drawn marker sheets."""
    sampler = compat.pyrender.Sampler(
        magFilter=_GL_LINEAR, minFilter=min_filter,
        wrapS=_GL_CLAMP_TO_EDGE, wrapT=_GL_CLAMP_TO_EDGE,
    )
    # RGBA keeps every row 4-byte aligned (GL's default unpack alignment) whatever the width;
    # made with its rows bottom-up, as GL takes them, in one copy (a 4,000-texel floor's is
    # 64 MB: a second, flipped one was the twin's peak memory)
    rgba = np.concatenate([image[::-1], np.full((*image.shape[:2], 1), 255, np.uint8)], axis=2)
    return compat.SrgbTexture(source=rgba, source_channels="RGBA", sampler=sampler,
                              srgb_space_mips=min_filter == _GL_LINEAR_MIPMAP_NEAREST,
                              bottom_up=True)


def _textured_quad(pyrender, corners_xy: np.ndarray, z: float, texture, factor: float):
    """A quad through ``corners_xy`` (texture TL, TR, BR, BL) showing ``texture``."""
    positions = np.column_stack([corners_xy, np.full(4, z)]).astype(np.float32)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], dtype=np.float32)
    f = float(min(factor, 1.0))
    material = pyrender.MetallicRoughnessMaterial(
        baseColorTexture=texture, baseColorFactor=np.array([f, f, f, 1.0], np.float32),
        metallicFactor=0.0, roughnessFactor=1.0,
    )
    prim = pyrender.Primitive(
        positions=positions, texcoord_0=uv, indices=np.array([[0, 1, 2], [0, 2, 3]]),
        material=material, mode=4,
    )
    return pyrender.Mesh([prim])


#: Draw ranks, front to back, in node names (``"<rank>:<index>"``): the first surface drawn
#: wins a depth tie, so ties resolve the same way in every run (see
#: :func:`arenabench.generator.rendering.pyrender_compat.draw_order`).
_RANK = {"obstacle": 0, "overlay": 1, "marker": 2, "floor": 3}


def _node_name(kind: str, index: int) -> str:
    """The name of the ``index``-th mesh node of ``kind``: its place in the draw order."""
    return f"{_RANK[kind]}:{index:06d}"


def box_mesh_arrays(obstacle: Obstacle, scene: Scene) -> tuple[np.ndarray, ...]:
    """Positions (20, 3), per-vertex RGBA colours (20, 4) and triangles (10, 3) of a box.

    Five faces (the bottom is never seen), each with its own baked Lambertian colour.
    """
    fp = box_footprint(obstacle)
    h = obstacle.height_m
    faces = [np.column_stack([fp, np.full(4, h)])]
    normals = [np.array([0.0, 0.0, 1.0])]
    for i in range(4):
        a, b = fp[i], fp[(i + 1) % 4]
        faces.append(np.array([[*a, 0.0], [*b, 0.0], [*b, h], [*a, h]]))
        edge = b - a
        n = np.array([edge[1], -edge[0], 0.0])
        normals.append(n / np.linalg.norm(n))
    factors = shade_factors(np.array(normals), scene.lighting)
    albedo = np.asarray(obstacle.color_rgb, dtype=np.float64)
    colours = np.clip(np.round(albedo[None, :] * factors[:, None]), 0, 255) / 255.0
    positions = np.concatenate(faces).astype(np.float32)
    rgba = np.repeat(np.column_stack([colours, np.ones(5)]), 4, axis=0).astype(np.float32)
    tris = np.concatenate([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * k for k in range(5)])
    return positions, rgba, tris


class Renderer(SceneRenderer):
    """The generator's pyrender renderer, reused across scenes (one per process; not thread-safe).

    Parameters
    ----------
    antialias : bool, keyword-only
        Edge samples on colour renders (on by default), as the scene's ``render`` section
        asks (:class:`~arenabench.generator.model.scene.RenderSpec`; by default two samples,
        :data:`~arenabench.generator.rendering.edges.EDGE_SAMPLES`): a pixel whose samples see
        different surfaces of the obstacles' region gets their mean (in linear light by
        default), as in the competition's images (docs/rendering.md). Off: hard edges
        whatever the scene asks. Textures (floor, markers) are filtered either way; ground
        truth, depth and instance masks never depend on it.

    Raises
    ------
    ImportError
        When the installed pyrender is not the pinned release
        (:data:`arenabench.generator.rendering.pyrender_compat.PYRENDER_VERSION`).

    Examples
    --------
    >>> with Renderer() as r:                       # doctest: +SKIP
    ...     out = r.render(scene, masks=True)
    """

    def __init__(self, *, antialias: bool = True) -> None:
        from arenabench.generator.rendering import pyrender_compat

        self._compat = pyrender_compat
        self._pr = pyrender_compat.pyrender
        self.antialias = bool(antialias)
        self._offscreen: pyrender_compat.LeanOffscreen | None = None
        self._size: tuple[int, int] | None = None
        # pyrender textures by the identity of their (cached, read-only) image: pyrender keeps
        # a texture in the GL context while any mesh uses it, so reusing the object between
        # scenes avoids re-uploading it
        self._textures: dict[int, tuple[np.ndarray, Any]] = {}
        self._texture_bytes = 0
        self._new_scene()

    def _new_scene(self) -> None:
        """An empty pyrender scene and no cached layer: the state of a new renderer."""
        self._scene = self._pr.Scene(bg_color=[1.0, 1.0, 1.0, 1.0], ambient_light=[1, 1, 1])
        # floor node keyed by the arena; marker nodes by (arena, markers): a scene that changes
        # only the markers (e.g. a drawn markers.side_m) keeps the big floor texture uploaded
        self._floor_key = None
        self._floor_nodes: list = []
        self._markers_key = None
        self._marker_nodes: list = []
        self._obstacle_nodes: list = []
        self._overlay_nodes: list = []
        self._camera_node = None
        # the static layer (see _static_layer): (key, image) once built, and the last key seen
        self._static: tuple[Any, np.ndarray] | None = None
        self._static_key: Any = None
        # the last render (see render): (key, read-only output)
        self._last: tuple[Any, RenderOutput] | None = None

    def close(self) -> None:
        """Release this renderer's GL objects and context; other renderers keep working."""
        off, self._offscreen = self._offscreen, None
        if off is not None:
            off.close()

    def gl_info(self) -> dict[str, str]:
        """OpenGL renderer and version strings (e.g. Mesa llvmpipe or the NVIDIA driver)."""
        self._ensure_renderer(*(self._size or (64, 64)))
        self._offscreen.make_current()
        return _gl_strings()

    def _ensure_renderer(self, width: int, height: int) -> None:
        if self._offscreen is None:
            self._offscreen = self._compat.LeanOffscreen(width, height)
        elif self._size != (width, height):
            self._offscreen.resize(width, height)
        self._size = (width, height)

    def _cached_texture(self, image: np.ndarray, *, min_filter: int = _GL_LINEAR_MIPMAP_LINEAR):
        hit = self._textures.get(id(image))
        if hit is None or hit[0] is not image:
            if (len(self._textures) >= TEXTURE_CACHE_COUNT
                    or self._texture_bytes + image.nbytes > TEXTURE_CACHE_BYTES):
                self._textures.clear()
                self._texture_bytes = 0
            hit = (image, _texture(self._compat, image, min_filter=min_filter))
            self._textures[id(image)] = hit
            self._texture_bytes += image.nbytes
        return hit[1]

    def _update_static(self, scene: Scene) -> None:
        """Floor and marker nodes, rebuilt only when the arena or markers change."""
        f = np.float32(min(floor_factor(scene.lighting), 1.0))
        pr = self._pr
        if scene.arena != self._floor_key:
            for node in self._floor_nodes:
                self._scene.remove_node(node)
            floor = floor_corners(scene.arena)
            self._floor_nodes = [
                self._scene.add(_textured_quad(
                    pr, floor, 0.0, self._cached_texture(floor_texture(scene.arena)), f),
                    name=_node_name("floor", 0))
            ]
            self._floor_key = scene.arena
        # Marker sheets: one unit quad per marker, kept while the sheet images stay the same;
        # a scene only moves and scales them (node pose), so drawn marker sizes cost nothing.
        mk = scene.markers
        printed = (scene.arena.texture == IMAGE_TEXTURE and mk.printed) or (
            scene.arena.texture == comp.TEXTURE_NAME and comp.markers_are_printed(
                mk.dictionary, mk.ids, mk.side_m, mk.rotation_deg))
        sheets = [] if printed else [
            marker_texture(mk.dictionary, marker_id, mk.side_m, mk.quiet_zone_m)
            for marker_id in mk.ids]
        key = tuple(id(image) for image, _ in sheets)
        if key != self._markers_key:
            for node in self._marker_nodes:
                self._scene.remove_node(node)
            self._marker_nodes = [
                self._scene.add(_textured_quad(
                    pr, _UNIT_QUAD, 0.0,
                    self._cached_texture(image, min_filter=_GL_LINEAR_MIPMAP_NEAREST), f),
                                name=_node_name("marker", k))
                for k, (image, _) in enumerate(sheets)
            ]
            self._markers_key = key
        for node, corner, (_, pad) in zip(self._marker_nodes, CORNER_ORDER[:len(sheets)], sheets,
                                          strict=True):
            tl, tr, _, bl = marker_corners_world(scene.arena, mk, corner, pad_m=pad)
            pose = np.eye(4)
            pose[:2, 0], pose[:2, 1] = tr - tl, tl - bl  # unit u -> TL->TR, unit v -> BL->TL
            pose[:2, 3], pose[2, 3] = bl, MARKER_Z
            self._scene.set_pose(node, pose)
        # The lighting changes per scene: only the (uniform) colour factor is updated.
        for node in (*self._floor_nodes, *self._marker_nodes):
            for prim in node.mesh.primitives:
                prim.material.baseColorFactor = np.array([f, f, f, 1.0], np.float32)

    def _update_dynamic(self, scene: Scene) -> None:
        pr = self._pr
        for node in self._obstacle_nodes:
            self._scene.remove_node(node)
        self._obstacle_nodes = []
        for k, ob in enumerate(scene.obstacles):
            pos, rgba, tris = box_mesh_arrays(ob, scene)
            prim = pr.Primitive(positions=pos, color_0=rgba, indices=tris, mode=4)
            self._obstacle_nodes.append(self._scene.add(pr.Mesh([prim]),
                                                        name=_node_name("obstacle", k)))
        for node in self._overlay_nodes:
            self._scene.remove_node(node)
        self._overlay_nodes = []
        patches = patch_mesh_arrays(scene.patches, floor_factor(scene.lighting))
        if patches is not None:
            prim = pr.Primitive(positions=patches[0], color_0=patches[1], indices=patches[2],
                                mode=4)
            self._overlay_nodes.append(self._scene.add(pr.Mesh([prim]),
                                                       name=_node_name("overlay", 0)))
        shadow = shadow_mesh_arrays(scene)
        if shadow is not None:
            material = pr.MetallicRoughnessMaterial(alphaMode="BLEND", doubleSided=True)
            prim = pr.Primitive(positions=shadow[0], color_0=shadow[1], indices=shadow[2],
                                mode=4, material=material)
            self._overlay_nodes.append(self._scene.add(pr.Mesh([prim]),
                                                       name=_node_name("overlay", 1)))
        if self._camera_node is not None:
            self._scene.remove_node(self._camera_node)
        K = cam.intrinsics(scene.camera)
        pose = cam.world_from_camera(scene.camera)
        fx, fy, cx, cy = cam.gl_intrinsics(K)
        height_above = pose[2, 3] - max([o.height_m for o in scene.obstacles], default=0.0)
        znear = float(np.clip(0.5 * height_above, 0.01, 1.0))
        camera = pr.IntrinsicsCamera(fx, fy, cx, cy, znear=znear, zfar=1000.0)
        self._camera_node = self._scene.add(camera, pose=cam.gl_pose(pose))
        bg = np.asarray(scene.background_rgb, dtype=np.float64) / 255.0
        self._scene.bg_color = np.array([*bg, 1.0])

    def render(self, scene: Scene, *, depth: bool = False, masks: bool = False) -> RenderOutput:
        """Render ``scene``.

        A camera with lens distortion is rendered as a larger pinhole canvas and resampled
        (:func:`arenabench.generator.model.lens.lens_canvas`); depth and masks follow the same
        map (nearest neighbour).

        Parameters
        ----------
        scene : Scene
            What to draw.
        depth : bool, keyword-only
            Also return the depth map.
        masks : bool, keyword-only
            Also return the per-obstacle instance mask (a second, exact SEG pass).

        Returns
        -------
        RenderOutput
            Arrays of its own: the caller may change them.

        Notes
        -----
        A render is a pure function of the scene (and ``depth``, ``masks``,
        :attr:`antialias`), so the renderer keeps its last output and gives a copy of it
        when the same scene comes again: a sweep over post-render parameters (noise, blur,
        JPEG, ...) renders each base scene once
        (``tests/generator/rendering/test_render_reuse.py`` checks the bytes against a fresh
        renderer).
        """
        key = (scene, bool(depth), bool(masks), self.antialias)
        if self._last is not None and self._last[0] == key:
            return _copied(self._last[1])
        # A stop signal waits for the render to end (arenabench.interrupts.deferred_stops):
        # raised inside trimesh or PyOpenGL it was swallowed (``except BaseException``) or
        # turned into a ctypes.ArgumentError, a crash instead of a stop.
        with deferred_stops():
            try:
                out = self._render(scene, depth=depth, masks=masks)
            except BaseException:  # e.g. KeyboardInterrupt between two node updates
                self._new_scene()
                raise
        self._last = (key, _copied(out, writeable=False))
        return out

    def _render(self, scene: Scene, *, depth: bool, masks: bool) -> RenderOutput:
        if has_distortion(scene.camera.dist):
            camera = scene.camera
            canvas = lens_canvas(cam.intrinsics(camera), camera.dist, camera.width,
                                 camera.height)
            pinhole = replace(scene, camera=replace(
                camera, K=tuple(map(tuple, canvas.K)), width=canvas.width,
                height=canvas.height, dist=(0.0,) * 5))
            out = self._render_pinhole(pinhole, depth=depth, masks=masks)
            out.rgb = distort_image(out.rgb, canvas)
            if out.depth is not None:
                out.depth = distort_image(out.depth, canvas, interpolation=cv2.INTER_NEAREST)
            if out.instance_mask is not None:
                out.instance_mask = distort_image(out.instance_mask, canvas,
                                                  interpolation=cv2.INTER_NEAREST)
            return out
        return self._render_pinhole(scene, depth=depth, masks=masks)

    def _render_pinhole(self, scene: Scene, *, depth: bool, masks: bool) -> RenderOutput:
        self._ensure_renderer(scene.camera.width, scene.camera.height)
        self._update_static(scene)
        self._update_dynamic(scene)
        rgb, z = self._colour_pass(scene, depth=depth)
        out = RenderOutput(rgb=apply_spot_light(rgb, scene))
        if depth:
            out.depth = z
        if masks:
            out.instance_mask = self._mask_pass()
        return out

    # Render passes: each draws the pyrender scene prepared by _update_static/_update_dynamic.

    def _colour_pass(self, scene: Scene, *, depth: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """(H, W, 3) uint8 colour, flat shaded; and the (H, W) float32 depth map when ``depth``
        is set (else None).

        One sample per pixel at its centre, then, when :attr:`antialias` is set and the
        scene's ``render.edge_samples`` is more than 1, one more render of the obstacles'
        region at each offset of its pattern
        (:data:`~arenabench.generator.rendering.edges.EDGE_PATTERNS`), resolved into the edge pixels
        (:func:`~arenabench.generator.rendering.edges.resolve_samples`, ``render.edge_resolve``).
        The centre sample outside that region comes from the static layer
        (:meth:`_static_layer`) when it is cached: the pixels are the same either way.
        """
        flags = self._pr.RenderFlags.FLAT | self._pr.RenderFlags.SKIP_CULL_FACES
        region = obstacle_region(scene)
        static = None if depth else self._static_layer(scene, flags)
        if static is None:
            color, z = self._offscreen.render(self._scene, flags, want_depth=depth)
            rgb = np.ascontiguousarray(color)
        else:
            rgb, z = static.copy(), None
            if region is not None:
                x0, y0, x1, y1 = region
                rgb[y0:y1, x0:x1] = self._offscreen.render(self._scene, flags, region=region)[0]
        edges = scene.render
        if self.antialias and edges.edge_samples > 1 and region is not None:
            x0, y0, x1, y1 = region
            samples = [self._offset_pass(flags, region, offset)
                       for offset in EDGE_PATTERNS[edges.edge_samples]]
            resolve_samples(rgb[y0:y1, x0:x1], samples, resolve=edges.edge_resolve)
        return rgb, z

    def _offset_pass(self, flags: int, region: tuple[int, int, int, int],
                     offset: tuple[float, float]) -> np.ndarray:
        """Colour of ``region`` sampled at ``offset`` (x, y px) from each pixel's centre."""
        camera = self._camera_node.camera
        cx, cy = camera.cx, camera.cy
        # moving the principal point by (-dx, -dy) moves the image content by (-dx, -dy)
        # (pyrender's cx, cy run along the image's columns and rows, as OpenCV's): each pixel
        # centre then sees the point at (x + dx, y + dy);
        # tests/generator/rendering/test_edges.py checks the signs
        camera.cx, camera.cy = cx - offset[0], cy - offset[1]
        try:
            color, _ = self._offscreen.render(self._scene, flags, region=region)
        finally:
            camera.cx, camera.cy = cx, cy
        return np.ascontiguousarray(color)

    def _static_layer(self, scene: Scene, flags: int) -> np.ndarray | None:
        """The centre-sample render of ``scene`` without its obstacles, when it can be reused.

        The floor, markers, background and camera of consecutive scenes are often the same
        (the ``eyrc`` twin holds them fixed): from the second scene on that repeats them, the
        layer is rendered once and each scene draws only its obstacles' region over it. A
        scene with overlays (patches, shadows) changes the floor outside that region and never
        uses the layer.
        """
        if self._overlay_nodes:
            self._static_key = None
            return None
        key = (scene.camera, scene.arena, scene.markers, floor_factor(scene.lighting),
               scene.background_rgb)
        if self._static is not None and self._static[0] == key:
            return self._static[1]
        if key != self._static_key:  # first time: render as usual, remember the key
            self._static_key = key
            return None
        for node in self._obstacle_nodes:
            node.mesh.is_visible = False
        try:
            color, _ = self._offscreen.render(self._scene, flags)
        finally:
            for node in self._obstacle_nodes:
                node.mesh.is_visible = True
        layer = np.ascontiguousarray(color)
        layer.flags.writeable = False
        self._static = (key, layer)
        return layer

    def _mask_pass(self) -> np.ndarray:
        """(H, W) uint8 instance mask: ``i + 1`` where obstacle ``i`` is nearest (exact SEG)."""
        if len(self._obstacle_nodes) > 255:
            raise ValueError("instance masks support at most 255 obstacles")
        seg_map = {n: (i + 1, 0, 0) for i, n in enumerate(self._obstacle_nodes)}
        seg_flags = self._pr.RenderFlags.SEG | self._pr.RenderFlags.SKIP_CULL_FACES
        seg, _ = self._offscreen.render(self._scene, seg_flags, seg_node_map=seg_map)
        return np.ascontiguousarray(seg[:, :, 0])


def _copied(out: RenderOutput, *, writeable: bool = True) -> RenderOutput:
    """A copy of ``out`` with arrays of its own (read-only ones when not ``writeable``)."""
    arrays = []
    for a in (out.rgb, out.depth, out.instance_mask):
        if a is not None:
            a = a.copy()
            a.flags.writeable = writeable
        arrays.append(a)
    return RenderOutput(*arrays)


class NaiveRenderer(SceneRenderer):
    """The bench's naive baseline: a new pyrender renderer and scene for every image.

    pyrender's default lit shading (4x MSAA) under a directional light, public pyrender API
    only: what a first attempt at the generator would do. It draws the floor, the marker
    sheets and the obstacles through a pinhole camera (no lens distortion, floor patches,
    shadows or spot light) and gives colour only.

    Notes
    -----
    Each render ends with pyrender's own clean-up, which terminates the process's EGL
    display: run it in a process of its own, apart from :class:`Renderer`.
    """

    def __init__(self) -> None:
        from arenabench.generator.rendering import pyrender_compat

        self._pr = pyrender_compat.pyrender

    def close(self) -> None:
        """Nothing to release: every render releases its own renderer."""

    def gl_info(self) -> dict[str, str]:
        """OpenGL renderer and version strings of a fresh pyrender context."""
        off = self._pr.OffscreenRenderer(64, 64)  # its context is current once created
        try:
            return _gl_strings()
        finally:
            off.delete()

    def render(self, scene: Scene, *, depth: bool = False, masks: bool = False) -> RenderOutput:
        """Render ``scene`` (colour only).

        Raises
        ------
        ValueError
            When ``depth`` or ``masks`` is asked for.
        """
        for name, wanted in (("depth", depth), ("masks", masks)):
            if wanted:
                raise ValueError(f"{name}: the naive baseline renders colour only")
        pr = self._pr
        pr_scene = pr.Scene(bg_color=[*(np.asarray(scene.background_rgb) / 255.0), 1.0],
                            ambient_light=[0.3, 0.3, 0.3])
        floor = floor_corners(scene.arena)
        pr_scene.add(_textured_quad(pr, floor, 0.0, floor_texture(scene.arena), 1.0))
        mk = scene.markers
        for corner, marker_id in zip(CORNER_ORDER, mk.ids, strict=True):
            image, pad = marker_texture(mk.dictionary, marker_id, mk.side_m, mk.quiet_zone_m)
            sheet = marker_corners_world(scene.arena, mk, corner, pad_m=pad)
            pr_scene.add(_textured_quad(pr, sheet, MARKER_Z, image, 1.0))
        for ob in scene.obstacles:
            pos, _, tris = box_mesh_arrays(ob, scene)
            material = pr.MetallicRoughnessMaterial(
                baseColorFactor=[*(np.asarray(ob.color_rgb) / 255.0), 1.0],
                metallicFactor=0.0, roughnessFactor=1.0)
            pr_scene.add(pr.Mesh([pr.Primitive(positions=pos, indices=tris, mode=4,
                                               material=material)]))
        K = cam.intrinsics(scene.camera)
        pose = cam.world_from_camera(scene.camera)
        fx, fy, cx, cy = cam.gl_intrinsics(K)
        pr_scene.add(pr.IntrinsicsCamera(fx, fy, cx, cy, znear=0.05, zfar=1000.0),
                     pose=cam.gl_pose(pose))
        pr_scene.add(pr.DirectionalLight(color=np.ones(3), intensity=3.0), pose=np.eye(4))
        renderer = pr.OffscreenRenderer(scene.camera.width, scene.camera.height)
        try:
            # lit (default) shading; both sides drawn, as the generator's quads need
            color, _ = renderer.render(pr_scene, flags=pr.RenderFlags.SKIP_CULL_FACES)
        finally:
            renderer.delete()
        return RenderOutput(rgb=color)


def _gl_strings() -> dict[str, str]:
    """``gl_renderer``, ``gl_version`` (of the current GL context) and ``gl_platform``."""
    from OpenGL import GL

    def text(name: int) -> str:
        value = GL.glGetString(name)
        return value.decode("ascii", "replace") if value else ""

    return {"gl_renderer": text(GL.GL_RENDERER), "gl_version": text(GL.GL_VERSION),
            "gl_platform": glplatform.configure()}
