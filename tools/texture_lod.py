"""The texture level of detail on the fitted example (docs/rendering.md, "The level of detail"):
the lambda the renderer samples at, against GL's exact one, and the figures of
``tools/twin_pixels.py`` with the level of detail moved.

lambda is measured by rendering the example with a floor texture whose mip level 0 is black
and every level below white: the output's linear value is then the fraction of lambda between
the uploaded levels 0 and 1 (the competition texture is uploaded at half size, so add 1 for
the full-size chain). The exact lambda is log2 of the larger texel footprint of a pixel step in
x and in y, from the homography between the markers' inner corners in full-size texels and in
pixels.

    .venv/bin/python tools/texture_lod.py [--implicit] [--bias B ...]

``--implicit`` samples with llvmpipe's own lambda (``texture()``, generator version 7) instead
of the shader's exact one (``textureLod``, version 8); ``--bias`` prints the figures with
``GL_TEXTURE_LOD_BIAS`` set to each B.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))

from twin_pixels import IMAGE, SCENE, figures  # noqa: E402

from arenabench.generator.assets import competition_arena as comp  # noqa: E402
from arenabench.generator.model.scene import load_scene  # noqa: E402
from arenabench.generator.rendering import pyrender_compat as pc  # noqa: E402  (before OpenGL)
from arenabench.generator.rendering.edges import srgb_to_linear  # noqa: E402
from arenabench.generator.rendering.render import Renderer  # noqa: E402
from arenabench.imageio import decode_image, encode_jpeg  # noqa: E402

#: Pixels where lambda is reported: near the top-left warp corner, bottom left, centre.
PIXELS = ((178, 229), (157, 898), (500, 560))
#: The markers' inner corners on the example (px; cv2.aruco finds them on whole pixels).
INNER_CORNERS_PX = ((177, 228), (826, 228), (847, 901), (156, 901))


def _implicit_shader(directory: str) -> Path:
    """A copy of the textured flat shader that samples at llvmpipe's implicit lambda."""
    src = pc.SRGB_TEXTURE_FRAG.read_text()
    start = src.index("    // GL's level of detail")
    end = src.index("log2(rho));") + len("log2(rho));")
    out = Path(directory) / "implicit_lod.frag"
    out.write_text(src[:start] + "    vec4 texel = texture(material.base_color_texture, uv_0);"
                   + src[end:])
    return out


def _patch_upload(*, probe: bool, bias: float | None) -> None:
    """Upload textures as a lambda probe (level 0 black, the rest white) and/or with a bias."""
    from OpenGL import GL  # after arenabench has chosen the GL platform

    original = pc.SrgbTexture._add_to_context

    def add(self):
        if probe:
            h, w = self.source.shape[:2]
            self._texid = GL.glGenTextures(1)
            GL.glBindTexture(self.tex_type, self._texid)
            level = 0
            while True:
                img = np.full((h, w, 4), 255, np.uint8)
                if level == 0:
                    img[..., :3] = 0
                GL.glTexImage2D(self.tex_type, level, GL.GL_SRGB8_ALPHA8, w, h, 0, GL.GL_RGBA,
                                GL.GL_UNSIGNED_BYTE, img)
                if max(h, w) == 1:
                    break
                h, w, level = max(1, h // 2), max(1, w // 2), level + 1
            for name, value in ((GL.GL_TEXTURE_MAG_FILTER, self.sampler.magFilter),
                                (GL.GL_TEXTURE_MIN_FILTER, self.sampler.minFilter)):
                GL.glTexParameteri(self.tex_type, name, value)
        else:
            original(self)
            GL.glBindTexture(self.tex_type, self._texid)
        if bias is not None:
            GL.glTexParameterf(self.tex_type, GL.GL_TEXTURE_LOD_BIAS, bias)
        GL.glBindTexture(self.tex_type, 0)

    pc.SrgbTexture._add_to_context = add


def exact_lambda(x: float, y: float) -> float:
    """GL's lambda (full-size chain) at pixel (x, y) of the example."""
    centre = comp.texture_rgb().shape[1] / 2.0
    texels_per_m = 2.0 * centre / comp.TEXTURE_SIDE_M
    d = (comp.ARENA_SIDE_M / 2.0 - comp.MARKER_SIDE_M) * texels_per_m  # centre to inner corner
    tex = np.float32([[-d, -d], [d, -d], [d, d], [-d, d]]) + centre
    H = cv2.getPerspectiveTransform(np.float32(INNER_CORNERS_PX), tex)

    def to_tex(px, py):
        p = H @ [px, py, 1.0]
        return p[:2] / p[2]

    dx = to_tex(x + 0.5, y) - to_tex(x - 0.5, y)
    dy = to_tex(x, y + 0.5) - to_tex(x, y - 0.5)
    return float(np.log2(max(np.linalg.norm(dx), np.linalg.norm(dy))))


def main(argv: list[str] | None = None) -> int:
    """Print lambda at :data:`PIXELS`, then the figures for each ``--bias``."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--implicit", action="store_true",
                   help="sample at llvmpipe's own lambda (generator version 7)")
    p.add_argument("--bias", type=float, nargs="*", default=[],
                   help="GL_TEXTURE_LOD_BIAS values to print the figures for")
    args = p.parse_args(argv)
    scene = load_scene(SCENE)
    real = cv2.imread(str(IMAGE), cv2.IMREAD_GRAYSCALE)
    original = pc.SrgbTexture._add_to_context
    with tempfile.TemporaryDirectory() as tmp:
        if args.implicit:
            pc.SRGB_TEXTURE_FRAG = _implicit_shader(tmp)
        _patch_upload(probe=True, bias=None)
        with Renderer(antialias=False) as r:
            lam = srgb_to_linear(r.render(scene).rgb[..., 1].astype(float))
        for x, y in PIXELS:
            got = lam[y - 4:y + 4, x - 4:x + 4].mean() + 1.0
            want = exact_lambda(x, y)
            print(f"({x}, {y}): lambda {got:.3f}, exact {want:.3f} ({got - want:+.3f})")
        for bias in args.bias:
            pc.SrgbTexture._add_to_context = original
            _patch_upload(probe=False, bias=bias)
            with Renderer() as r:
                bgr = cv2.cvtColor(r.render(scene).rgb, cv2.COLOR_RGB2BGR)
            jpeg = cv2.cvtColor(decode_image(encode_jpeg(bgr, quality=95)), cv2.COLOR_BGR2GRAY)
            print(f"bias {bias:+.3f} PNG ", figures(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY), real))
            print(f"bias {bias:+.3f} JPEG", figures(jpeg, real))
    return 0


if __name__ == "__main__":
    sys.exit(main())
