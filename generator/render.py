"""Off-screen rendering: a pyrender adapter over :class:`~arenabench.generator.scene.Scene`.

One :class:`Renderer` per process holds one ``pyrender.OffscreenRenderer`` and one pyrender
scene, reused across scenes: the floor and marker nodes are cached by their description and
only obstacle nodes and the camera change. Renders use ``RenderFlags.FLAT`` with Lambertian
shading baked into colours (:mod:`arenabench.generator.shading`), about 3x faster than lit mode
on Mesa llvmpipe, and 4x MSAA on the colour pass (anti-aliased box edges). Instance masks come
from ``RenderFlags.SEG`` (exact, no MSAA), on request.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from arenabench import glplatform
from arenabench.frame import CORNER_ORDER
from arenabench.generator import camera as cam
from arenabench.generator import competition_arena as comp
from arenabench.generator.degrade import distort_image, has_distortion, lens_canvas
from arenabench.generator.distractors import patch_mesh_arrays
from arenabench.generator.layout import (
    MARKER_Z,
    box_footprint,
    floor_extent,
    marker_corners_world,
)
from arenabench.generator.lights import apply_spot_light, shadow_mesh_arrays
from arenabench.generator.scene import Obstacle, Scene
from arenabench.generator.shading import floor_factor, shade_factors
from arenabench.generator.textures import floor_texture, marker_texture

# pyrender's Mesh.bounds still uses np.infty, removed in NumPy 2 (mmatl/pyrender#288).
if not hasattr(np, "infty"):
    setattr(np, "infty", np.inf)  # noqa: B010

_GL_LINEAR = 9729
_GL_LINEAR_MIPMAP_NEAREST = 9985  # bilinear in the nearest mip level: ~20 % faster than trilinear
_GL_CLAMP_TO_EDGE = 33071


@dataclass
class RenderOutput:
    """What one render gives back.

    Attributes
    ----------
    rgb : numpy.ndarray
        (H, W, 3) uint8, RGB order.
    depth : numpy.ndarray or None
        (H, W) float32 distance along the optical axis in metres, 0 where nothing was hit.
    instance_mask : numpy.ndarray or None
        (H, W) uint8: 0 for no obstacle, ``i + 1`` where obstacle ``i`` is the nearest surface.
    """

    rgb: np.ndarray
    depth: np.ndarray | None = None
    instance_mask: np.ndarray | None = None


#: Texture TL, TR, BR, BL corners of a unit sheet, placed by its node's pose (v points from
#: BL to TL so that the pose keeps the winding: pyrender culls back faces).
_UNIT_QUAD = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])


def _texture(pyrender, image: np.ndarray):
    """A pyrender texture of an RGB ``image``."""
    sampler = pyrender.Sampler(
        magFilter=_GL_LINEAR, minFilter=_GL_LINEAR_MIPMAP_NEAREST,
        wrapS=_GL_CLAMP_TO_EDGE, wrapT=_GL_CLAMP_TO_EDGE,
    )
    # RGBA keeps every row 4-byte aligned (GL's default unpack alignment) whatever the width.
    rgba = np.concatenate([image, np.full((*image.shape[:2], 1), 255, np.uint8)], axis=2)
    return pyrender.Texture(source=rgba, source_channels="RGBA", sampler=sampler)


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


def _fast_renderer_class(pyrender):
    """A ``pyrender.Renderer`` subclass with a leaner off-screen path (pyrender 0.1.45 internals).

    - colour renders draw into pyrender's 4x multisample framebuffer and resolve it (box edges
      get coverage-blended pixels, as the competition's renderer gives) when ``antialias`` is
      set; SEG renders and ``antialias=False`` draw straight into the single-sample
      framebuffer (no resolve blit; SEG colours are exact);
    - the depth buffer is read back (and linearised) only when asked for;
    - meshes are drawn in a fixed order (:func:`_draw_order`), not pyrender's.
    """
    from OpenGL import GL

    flags_cls = pyrender.RenderFlags

    class _LeanRenderer(pyrender.renderer.Renderer):
        antialias = False
        want_depth = False

        def _multisample(self, flags) -> bool:
            return self.antialias and not flags & flags_cls.SEG

        def _configure_forward_pass_viewport(self, flags):
            super()._configure_forward_pass_viewport(flags)
            if flags & flags_cls.OFFSCREEN and not self._multisample(flags):
                GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)

        def _sorted_mesh_nodes(self, scene):
            return _draw_order(scene.mesh_nodes)

        def _read_main_framebuffer(self, scene, flags):
            w, h = self._main_fb_dims
            if self._multisample(flags):
                GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb_ms)
                GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
                GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL.GL_COLOR_BUFFER_BIT,
                                     GL.GL_LINEAR)
                if self.want_depth:
                    GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL.GL_DEPTH_BUFFER_BIT,
                                         GL.GL_NEAREST)
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
            GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
            depth = None
            if self.want_depth:
                raw = GL.glReadPixels(0, 0, w, h, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT)
                d = np.frombuffer(raw, dtype=np.float32).reshape(h, w)[::-1]
                cam_ = scene.main_camera_node.camera
                n, f = cam_.znear, cam_.zfar
                hit = d < 1.0
                ndc = 2.0 * d - 1.0
                depth = np.where(hit, 2.0 * n * f / (f + n - ndc * (f - n)), 0.0)
                depth = depth.astype(np.float32)
            raw = GL.glReadPixels(0, 0, w, h, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
            color = np.frombuffer(raw, dtype=np.uint8).reshape(h, w, 3)[::-1]
            return color, depth

    return _LeanRenderer


#: Draw ranks, front to back, in node names (``"<rank>:<index>"``): the first surface drawn
#: wins a depth tie, so ties resolve the same way in every run (see :func:`_draw_order`).
_RANK = {"obstacle": 0, "overlay": 1, "marker": 2, "floor": 3}


def _node_name(kind: str, index: int) -> str:
    """The name of the ``index``-th mesh node of ``kind``: its place in the draw order."""
    return f"{_RANK[kind]}:{index:06d}"


def _draw_order(nodes) -> list:
    """Mesh nodes in a fixed draw order: opaque ones by name, then transparent ones by name.

    pyrender sorts nodes by the distance of their origin to the camera, and nodes at the same
    distance (floor, obstacles and overlays all sit at the world origin) by the iteration
    order of a ``set``, which follows memory addresses and so changes from run to run. Where
    two surfaces meet (a box side meeting the floor) their depths can tie in a pixel, and the
    first one drawn wins it (``GL_LESS``): such a pixel flipped between box and floor colour
    from one run to the next. Ordering by name makes every render of a scene the same.
    """
    nodes = sorted(nodes, key=lambda n: n.name or "")
    return ([n for n in nodes if not n.mesh.is_transparent]
            + [n for n in nodes if n.mesh.is_transparent])


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


class Renderer:
    """Reusable off-screen renderer (one per process; not thread-safe).

    Parameters
    ----------
    antialias : bool, keyword-only
        4x MSAA on colour renders (on by default): pixels that a box edge crosses get the
        coverage-weighted blend of both sides, as in the competition's Gazebo images.
        Textures (floor, markers) are filtered either way; ground truth, depth and instance
        masks never depend on it.

    Examples
    --------
    >>> with Renderer() as r:                       # doctest: +SKIP
    ...     out = r.render(scene, masks=True)
    """

    def __init__(self, *, antialias: bool = True) -> None:
        glplatform.configure()
        import pyrender

        self._pr = pyrender
        self.antialias = bool(antialias)
        self._lean_cls = _fast_renderer_class(pyrender)
        self._renderer = None
        self._size: tuple[int, int] | None = None
        self._scene = pyrender.Scene(bg_color=[1.0, 1.0, 1.0, 1.0], ambient_light=[1, 1, 1])
        # floor node keyed by the arena; marker nodes by (arena, markers): a scene that changes
        # only the markers (e.g. a drawn markers.side_m) keeps the big floor texture uploaded
        self._floor_key = None
        self._floor_nodes: list = []
        self._markers_key = None
        self._marker_nodes: list = []
        # pyrender textures by the identity of their (cached, read-only) image: pyrender keeps
        # a texture in the GL context while any mesh uses it, so reusing the object between
        # scenes avoids re-uploading it
        self._textures: dict[int, tuple[np.ndarray, Any]] = {}
        self._obstacle_nodes: list = []
        self._overlay_nodes: list = []
        self._camera_node = None

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release this renderer's GL objects and context.

        pyrender's EGL clean-up calls ``eglTerminate`` on the display, which every context of
        the process shares: other renderers would break. Here only this context is destroyed.
        """
        off, self._renderer = self._renderer, None
        if off is None:
            return
        platform = off._platform
        if type(platform).__name__ != "EGLPlatform":
            off.delete()
            return
        from OpenGL import EGL

        platform.make_current()
        off._renderer.delete()
        EGL.eglMakeCurrent(platform._egl_display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE,
                           EGL.EGL_NO_CONTEXT)
        if platform._egl_context is not None:
            EGL.eglDestroyContext(platform._egl_display, platform._egl_context)
            platform._egl_context = None
        platform._egl_display = None  # so that the platform's __del__ skips eglTerminate
        off._renderer = None
        off._platform = None

    def gl_info(self) -> dict[str, str]:
        """OpenGL renderer and version strings (e.g. Mesa llvmpipe or the NVIDIA driver)."""
        self._ensure_renderer(*(self._size or (64, 64)))
        from OpenGL import GL

        self._renderer._platform.make_current()

        def text(name: int) -> str:
            value = GL.glGetString(name)
            return value.decode("ascii", "replace") if value else ""

        return {"gl_renderer": text(GL.GL_RENDERER), "gl_version": text(GL.GL_VERSION),
                "gl_platform": glplatform.configure()}

    def _ensure_renderer(self, width: int, height: int) -> None:
        if self._renderer is None:
            self._renderer = self._pr.OffscreenRenderer(width, height)
            # swap in the lean renderer before it allocates anything on the GPU
            self._renderer._renderer = self._lean_cls(width, height)
            self._renderer._renderer.antialias = self.antialias
        elif self._size != (width, height):
            self._renderer.viewport_width = width
            self._renderer.viewport_height = height
        self._size = (width, height)

    def _cached_texture(self, image: np.ndarray):
        hit = self._textures.get(id(image))
        if hit is None or hit[0] is not image:
            if len(self._textures) >= 64:
                self._textures.clear()
            hit = (image, _texture(self._pr, image))
            self._textures[id(image)] = hit
        return hit[1]

    def _update_static(self, scene: Scene) -> None:
        """Floor and marker nodes, rebuilt only when the arena or markers change."""
        f = np.float32(min(floor_factor(scene.lighting), 1.0))
        pr = self._pr
        if scene.arena != self._floor_key:
            for node in self._floor_nodes:
                self._scene.remove_node(node)
            e = floor_extent(scene.arena)
            floor = np.array([[-e, e], [e, e], [e, -e], [-e, -e]])
            self._floor_nodes = [
                self._scene.add(_textured_quad(
                    pr, floor, 0.0, self._cached_texture(floor_texture(scene.arena)), f),
                    name=_node_name("floor", 0))
            ]
            self._floor_key = scene.arena
        # Marker sheets: one unit quad per marker, kept while the sheet images stay the same;
        # a scene only moves and scales them (node pose), so drawn marker sizes cost nothing.
        mk = scene.markers
        printed = scene.arena.texture == comp.TEXTURE_NAME and comp.markers_are_printed(
            mk.dictionary, mk.ids, mk.side_m, mk.rotation_deg)
        sheets = [] if printed else [
            marker_texture(mk.dictionary, marker_id, mk.side_m, mk.quiet_zone_m)
            for marker_id in mk.ids]
        key = tuple(id(image) for image, _ in sheets)
        if key != self._markers_key:
            for node in self._marker_nodes:
                self._scene.remove_node(node)
            self._marker_nodes = [
                self._scene.add(_textured_quad(pr, _UNIT_QUAD, 0.0,
                                               self._cached_texture(image), f),
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
        (:func:`arenabench.generator.degrade.lens_canvas`); depth and masks follow the same
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
        """
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
        pr = self._pr
        self._ensure_renderer(scene.camera.width, scene.camera.height)
        self._update_static(scene)
        self._update_dynamic(scene)
        flags = pr.RenderFlags.FLAT | pr.RenderFlags.SKIP_CULL_FACES
        self._renderer._renderer.want_depth = depth
        color, z = self._renderer.render(self._scene, flags=flags)
        self._renderer._renderer.want_depth = False
        out = RenderOutput(rgb=apply_spot_light(np.ascontiguousarray(color[:, :, :3]), scene))
        if depth:
            out.depth = z
        if masks:
            if len(self._obstacle_nodes) > 255:
                raise ValueError("instance masks support at most 255 obstacles")
            seg_map = {n: (i + 1, 0, 0) for i, n in enumerate(self._obstacle_nodes)}
            seg_flags = pr.RenderFlags.SEG | pr.RenderFlags.SKIP_CULL_FACES
            seg, _ = self._renderer.render(self._scene, flags=seg_flags, seg_node_map=seg_map)
            out.instance_mask = np.ascontiguousarray(seg[:, :, 0])
        return out
