"""Every use of pyrender's private API, for exactly one pyrender release.

The generator's renderer (:class:`arenabench.generator.rendering.render.Renderer`) relies on
pyrender
internals that may change in any release: it subclasses ``pyrender.renderer.Renderer``
(overriding ``_configure_forward_pass_viewport``, ``_sorted_mesh_nodes`` and
``_read_main_framebuffer``), swaps it into ``OffscreenRenderer._renderer`` and, on close, tears
the EGL context down through the platform's ``_egl_*`` attributes. It also restores
``np.infty`` (removed in NumPy 2), which pyrender's ``Mesh.bounds`` still uses. All of that is
here, behind :class:`LeanOffscreen`, and holds only for the pinned release
(:data:`arenabench.glplatform.PYRENDER_VERSION`): importing this module chooses the OpenGL
platform (:func:`arenabench.glplatform.configure`), imports pyrender and raises
:class:`ImportError` when another release is installed.
"""

from __future__ import annotations

import sys
import threading
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from arenabench import glplatform
from arenabench.glplatform import PYRENDER_VERSION
from arenabench.interrupts import deferred_stops

__all__ = ["PYRENDER_VERSION", "LeanOffscreen", "SrgbTexture", "check_version", "draw_order",
           "pyrender"]


def check_version(version: str) -> None:
    """Raise unless ``version`` is :data:`PYRENDER_VERSION`.

    Raises
    ------
    ImportError
        Naming both versions and how to install the pinned one.
    """
    if version != PYRENDER_VERSION:
        raise ImportError(
            f"arenabench needs pyrender {PYRENDER_VERSION} exactly (its renderer uses that "
            f"release's internals), but pyrender {version} is installed; install the pinned "
            f"release with: pip install 'pyrender=={PYRENDER_VERSION}'"
        )


#: Modules held out of pyrender's import when this process has not loaded them yet: trimesh,
#: which pyrender imports, loads SciPy (``scipy.spatial``, ``scipy.optimize``) at import time
#: for features that neither pyrender's drawing nor arenabench use, and treats it as optional.
#: That is 0.37 of the 0.81 s the import takes in every rendering worker. SciPy imported later
#: in the process works as usual (``tests/generator/rendering/test_renderer_api.py`` checks
#: it); only trimesh's own SciPy-based functions (convex hulls, KD-trees) raise in that
#: process. Held only while no other Python thread runs, since an import of SciPy in another
#: thread would fail then.
IMPORT_WITHOUT = ("scipy",)


def _import_pyrender():
    glplatform.configure()  # before the first import of pyrender / OpenGL
    problem = glplatform.pyopengl_problem()
    if problem:  # it would fail only at the first texture, deep in a render
        raise ImportError(problem)
    alone = threading.active_count() == 1
    held = [name for name in IMPORT_WITHOUT if alone and name not in sys.modules]
    for name in held:
        sys.modules[name] = None  # type: ignore[assignment]  # importing it fails meanwhile
    try:
        with deferred_stops():  # a Ctrl-C that trimesh's imports swallowed would break them
            import pyrender
    finally:
        for name in held:
            if name in sys.modules and sys.modules[name] is None:
                del sys.modules[name]
    check_version(str(getattr(pyrender, "__version__", "unknown")))
    return pyrender


pyrender = _import_pyrender()

from OpenGL import GL  # noqa: E402  (after glplatform.configure, as pyrender)

# pyrender's Mesh.bounds still uses np.infty, removed in NumPy 2 (mmatl/pyrender#288).
if not hasattr(np, "infty"):
    setattr(np, "infty", np.inf)  # noqa: B010


def draw_order(nodes) -> list:
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


#: The flat pass of a textured primitive (:class:`SrgbTexture`): filtered in linear light, encoded
#: back to sRGB, then scaled by the material's colour factor.
SRGB_TEXTURE_FRAG = Path(__file__).resolve().parents[1] / "assets" / "flat_srgb_texture.frag"


class SrgbTexture(pyrender.Texture):
    """An RGBA uint8 texture stored as sRGB (``GL_SRGB8_ALPHA8``), as ogre2 stores a diffuse map.

    GL decodes its texels to linear light before filtering them, and ``glGenerateMipmap``
    averages them in linear light (on Mesa and the common drivers;
    ``tests/generator/fitting/test_twin_fidelity.py``
    checks the levels llvmpipe makes). Drawn by :data:`SRGB_TEXTURE_FRAG`, which encodes the
    filtered colour back to sRGB. ``srgb_space_mips=True``: the mip levels are averaged in sRGB
    values instead (drawn marker sheets, as up to generator version 5). ``bottom_up=True``:
    the source's rows already run bottom-up, as GL takes them (no flipped copy is made).
    """

    def __init__(self, *args, srgb_space_mips: bool = False, bottom_up: bool = False,
                 **kwargs):
        super().__init__(*args, **kwargs)
        self.srgb_space_mips = srgb_space_mips
        self.bottom_up = bottom_up

    def _add_to_context(self):
        if self._texid is not None:
            raise ValueError("Texture already loaded into OpenGL context")
        src = self.source
        if src is None or src.dtype != np.uint8 or src.ndim != 3 or src.shape[2] != 4:
            raise ValueError("SrgbTexture needs an (H, W, 4) uint8 source")
        self._texid = GL.glGenTextures(1)
        GL.glBindTexture(self.tex_type, self._texid)
        data = src if self.bottom_up else np.ascontiguousarray(src[::-1])  # GL: bottom-up
        GL.glTexImage2D(self.tex_type, 0, GL.GL_SRGB8_ALPHA8, src.shape[1], src.shape[0], 0,
                        GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, data)
        if self.srgb_space_mips:
            # levels averaged in sRGB values, as a plain RGBA8 texture's glGenerateMipmap made
            # them up to generator version 5 (drawn marker sheets: render.py)
            level, image = 0, data
            while max(image.shape[:2]) > 1:
                h, w = max(1, image.shape[0] // 2), max(1, image.shape[1] // 2)
                image = np.ascontiguousarray(
                    cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA))
                level += 1
                GL.glTexImage2D(self.tex_type, level, GL.GL_SRGB8_ALPHA8, w, h, 0, GL.GL_RGBA,
                                GL.GL_UNSIGNED_BYTE, image)
        else:
            GL.glGenerateMipmap(self.tex_type)
        GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_MAG_FILTER, self.sampler.magFilter)
        GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_MIN_FILTER, self.sampler.minFilter)
        GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_WRAP_S, self.sampler.wrapS)
        GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_WRAP_T, self.sampler.wrapT)
        GL.glBindTexture(self.tex_type, 0)


class _ProgramCache(pyrender.shader_program.ShaderProgramCache):
    """pyrender's shader cache, with :data:`SRGB_TEXTURE_FRAG` for textured flat primitives
    (the only textures the generator draws are :class:`SrgbTexture`)."""

    def get_program(self, vertex_shader, fragment_shader, geometry_shader=None, defines=None):
        if fragment_shader == "flat.frag" and defines and "HAS_BASE_COLOR_TEX" in defines:
            fragment_shader = str(SRGB_TEXTURE_FRAG)
        return super().get_program(vertex_shader, fragment_shader, geometry_shader, defines)


class _LeanRenderer(pyrender.renderer.Renderer):
    """A ``pyrender.Renderer`` with a leaner off-screen path.

    - one single-sample framebuffer (pyrender also allocates a 4x multisample one and resolves
      it on every read: 32 MB and a blit per render that the generator does not use; its
      edges come from two offset renders, :mod:`arenabench.generator.rendering.edges`);
    - ``region`` (x0, y0, x1, y1), when set, limits drawing (scissor) and the read-back to
      that pixel box (image rows top-down, end-exclusive);
    - the depth buffer is read back (and linearised) only when ``want_depth`` is set;
    - meshes are drawn in a fixed order (:func:`draw_order`), not pyrender's.
    """

    want_depth = False
    region: tuple[int, int, int, int] | None = None

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._program_cache = _ProgramCache()

    def _configure_main_framebuffer(self):
        w, h = self.viewport_width, self.viewport_height
        if self._main_fb is not None and self._main_fb_dims != (w, h):
            self._delete_main_framebuffer()
        if self._main_fb is None:
            self._main_cb, self._main_db = GL.glGenRenderbuffers(2)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_RGBA, w, h)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH_COMPONENT24, w, h)
            self._main_fb = GL.glGenFramebuffers(1)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
            GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0,
                                         GL.GL_RENDERBUFFER, self._main_cb)
            GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT,
                                         GL.GL_RENDERBUFFER, self._main_db)
            self._main_fb_dims = (w, h)

    def _delete_main_framebuffer(self):
        if self._main_fb is not None:
            GL.glDeleteFramebuffers(1, [self._main_fb])
        for rb in (self._main_cb, self._main_db):
            if rb is not None:
                GL.glDeleteRenderbuffers(1, [rb])
        self._main_fb = self._main_cb = self._main_db = None
        self._main_fb_ms = self._main_cb_ms = self._main_db_ms = None
        self._main_fb_dims = (None, None)

    def _configure_forward_pass_viewport(self, flags):
        # pyrender's own, drawing into the single-sample framebuffer
        if flags & pyrender.RenderFlags.OFFSCREEN:
            self._configure_main_framebuffer()
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
        else:
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, 0)
        GL.glViewport(0, 0, self.viewport_width, self.viewport_height)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        if self.region is not None:  # before pyrender's glClear, which the scissor limits
            x0, y0, x1, y1 = self.region
            GL.glEnable(GL.GL_SCISSOR_TEST)
            GL.glScissor(x0, self.viewport_height - y1, x1 - x0, y1 - y0)
        else:
            GL.glDisable(GL.GL_SCISSOR_TEST)

    def _sorted_mesh_nodes(self, scene):
        return draw_order(scene.mesh_nodes)

    def _read_main_framebuffer(self, scene, flags):
        w, h = self._main_fb_dims
        x0, y0, x1, y1 = self.region if self.region is not None else (0, 0, w, h)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        depth = None
        if self.want_depth:
            raw = GL.glReadPixels(x0, h - y1, x1 - x0, y1 - y0, GL.GL_DEPTH_COMPONENT,
                                  GL.GL_FLOAT)
            d = np.frombuffer(raw, dtype=np.float32).reshape(y1 - y0, x1 - x0)[::-1]
            cam_ = scene.main_camera_node.camera
            n, f = cam_.znear, cam_.zfar
            hit = d < 1.0
            ndc = 2.0 * d - 1.0
            depth = np.where(hit, 2.0 * n * f / (f + n - ndc * (f - n)), 0.0)
            depth = depth.astype(np.float32)
        raw = GL.glReadPixels(x0, h - y1, x1 - x0, y1 - y0, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
        color = np.frombuffer(raw, dtype=np.uint8).reshape(y1 - y0, x1 - x0, 3)[::-1]
        GL.glDisable(GL.GL_SCISSOR_TEST)
        return color, depth


class LeanOffscreen:
    """A ``pyrender.OffscreenRenderer`` that draws with the lean renderer (one GL context).

    Parameters
    ----------
    width, height : int
        Initial viewport size in px (:meth:`resize` changes it).
    """

    def __init__(self, width: int, height: int) -> None:
        self._off: Any = pyrender.OffscreenRenderer(width, height)
        # swap in the lean renderer before it allocates anything on the GPU
        self._off._renderer = _LeanRenderer(width, height)

    def resize(self, width: int, height: int) -> None:
        """Draw the next renders at ``width`` x ``height`` px."""
        self._off.viewport_width = width
        self._off.viewport_height = height

    def render(self, scene, flags: int, *, want_depth: bool = False,
               seg_node_map: dict | None = None,
               region: tuple[int, int, int, int] | None = None,
               ) -> tuple[np.ndarray, np.ndarray | None]:
        """Draw a pyrender ``scene`` with ``flags``; (colour, linear depth or None).

        Parameters
        ----------
        scene : pyrender.Scene
            What to draw.
        flags : int
            ``pyrender.RenderFlags`` (``OFFSCREEN`` is added by pyrender).
        want_depth : bool, keyword-only
            Also read back the depth buffer, linearised to metres along the optical axis.
        seg_node_map : dict, keyword-only
            Node -> colour of a SEG render.
        region : tuple of int, keyword-only
            ``(x0, y0, x1, y1)``: draw and read back only this pixel box (rows top-down,
            end-exclusive); the arrays returned are the box's size. Pixels inside come out
            exactly as in a full render.
        """
        lean = self._off._renderer
        if region is not None:
            x0, y0, x1, y1 = region
            w, h = self._off.viewport_width, self._off.viewport_height
            if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
                raise ValueError(f"region {region} is not a non-empty box inside {w} x {h}")
        lean.want_depth = want_depth
        lean.region = region
        try:
            return self._off.render(scene, flags=flags, seg_node_map=seg_node_map)
        finally:
            lean.want_depth = False
            lean.region = None

    def make_current(self) -> None:
        """Make this renderer's GL context current in the calling thread."""
        self._off._platform.make_current()

    def close(self) -> None:
        """Release this renderer's GL objects and context (idempotent).

        pyrender's EGL clean-up calls ``eglTerminate`` on the display, which every context of
        the process shares: other renderers would break. Here only this context is destroyed.
        """
        off, self._off = self._off, None
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
