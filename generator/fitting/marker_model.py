"""A renderer-free model of the four printed markers as a camera sees them, to fit the camera
to the image's marker pixels.

Each marker's modules (its dictionary's bits and the black border) are mapped through the
camera onto the image. A pixel's white coverage is the module pattern blurred by a Gaussian of
``sigma_px`` combined with the pixel's own area, in linear light (what texture filtering does
to a printed marker), sampled at the pixel's centre: smooth in the camera and the blur, so that
finite differences see every sub-pixel move. Each marker gets its own black and white levels
(solved in closed form). Only pixels well inside each marker's outline are compared: what lies
around a marker (a quiet zone, a border line, the floor) differs from arena to arena, its
modules do not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from arenabench.frame import CORNER_ORDER
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import marker_corners_world
from arenabench.generator.model.scene import ArenaSpec, MarkerSpec
from arenabench.generator.rendering.edges import srgb_to_linear

#: Pixels compared lie this far (px) inside each marker's detected outline.
INSET_PX = 2.0
#: Pixels around each marker's bounding box in its window.
PAD_PX = 4
#: Texels per module of the blurred pattern the pixels are sampled from.
TEXELS_PER_MODULE = 32
#: White modules drawn around the pattern (room for the blur).
MARGIN_MODULES = 2
#: The largest blur (modules, a Gaussian's sigma) the pattern is drawn with: a marker blurred
#: by a module is no longer decoded, and a larger one would run past the white margin. A fit
#: that wanders beyond it stays there (a photo's fit asked for a blur whose kernel took 6 GB).
MAX_BLUR_MODULES = 1.0


@dataclass(frozen=True)
class MarkerPatch:
    """One marker's window in the image: its module pattern and the image's pixels there.

    Attributes
    ----------
    corner : str
        Arena corner (``nw`` .. ``sw``).
    modules : numpy.ndarray
        (n, n) float modules, border included: 0 black, 1 white; row 0 is the marker image's
        top (its corner 0 at the top left).
    x0, y0 : int
        The window's top-left pixel in the image.
    image_linear : numpy.ndarray
        (h, w) the image's grey in linear light in the window.
    mask : numpy.ndarray
        (h, w) bool: the pixels compared.
    """

    corner: str
    modules: np.ndarray
    x0: int
    y0: int
    image_linear: np.ndarray
    mask: np.ndarray


def module_pattern(dictionary: str, marker_id: int) -> np.ndarray:
    """(n + 2, n + 2) float modules of a marker, border included: 0 black, 1 white."""
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    cells = d.markerSize + 2
    img = cv2.aruco.generateImageMarker(d, int(marker_id), cells, borderBits=1)
    return (img > 127).astype(np.float64)


def _uv_to_world(arena: ArenaSpec, markers: MarkerSpec, corner: str) -> np.ndarray:
    """3x3 map from a marker's unit square (u right, v down in the marker image; (0, 0) its
    corner 0) to floor (x, y, 1)."""
    c = marker_corners_world(arena, markers, corner)
    a = np.eye(3)
    a[:2, 0] = c[1] - c[0]
    a[:2, 1] = c[3] - c[0]
    a[:2, 2] = c[0]
    return a


def image_to_uv(K: np.ndarray, pose: np.ndarray, arena: ArenaSpec, markers: MarkerSpec,
                corner: str) -> np.ndarray:
    """3x3 map from image px to the unit square of the marker in ``corner``."""
    return np.linalg.inv(cam.floor_homography(K, pose) @ _uv_to_world(arena, markers, corner))


def marker_patches(gray: np.ndarray, quads: dict[str, np.ndarray],
                   modules: dict[str, np.ndarray]) -> list[MarkerPatch]:
    """The windows around each marker (its detected quad's bounding box grown by
    :data:`PAD_PX`), with the image's pixels in linear light and the pixels to compare: those
    at least :data:`INSET_PX` inside the detected outline."""
    out = []
    lin = srgb_to_linear(gray)
    for corner in CORNER_ORDER:
        q = quads[corner]
        x0, y0 = (np.floor(q.min(axis=0)).astype(int) - PAD_PX).clip(0)
        x1, y1 = np.ceil(q.max(axis=0)).astype(int) + PAD_PX + 1
        x1, y1 = min(x1, gray.shape[1]), min(y1, gray.shape[0])
        inside = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillPoly(inside, [np.round((q - [x0, y0]) * 16).astype(np.int32)], 1, shift=4)
        dist = cv2.distanceTransform(inside, cv2.DIST_L2, 5)
        out.append(MarkerPatch(corner, modules[corner], int(x0), int(y0),
                               lin[y0:y1, x0:x1], dist >= INSET_PX))
    return out


def _blurred_pattern(modules: np.ndarray, sigma_tex: float) -> np.ndarray:
    pad = MARGIN_MODULES * TEXELS_PER_MODULE
    big = cv2.resize(modules.astype(np.float32), None, fx=TEXELS_PER_MODULE,
                     fy=TEXELS_PER_MODULE, interpolation=cv2.INTER_NEAREST)
    big = cv2.copyMakeBorder(big, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=1.0)
    sigma_tex = min(sigma_tex, MAX_BLUR_MODULES * TEXELS_PER_MODULE)
    if sigma_tex > 0.05:
        big = cv2.GaussianBlur(big, (0, 0), sigma_tex, borderType=cv2.BORDER_REPLICATE)
    return big


def coverage(patch: MarkerPatch, to_uv: np.ndarray, sigma_px: float) -> np.ndarray:
    """White coverage (0..1, linear light) of each window pixel: the module pattern (white
    around it) blurred by a Gaussian of ``sigma_px``, sampled at the pixel's centre.

    Texture filtering (mip levels on the texture's own grid) is not shift-invariant: along an
    edge its blend changes with the edge's phase in the texel grid. A Gaussian is its
    shift-invariant average (the render of the competition's example fits it to 5.7 linear
    grey levels RMS at the true camera, the edges' phase effects included), so the camera it
    fits is unbiased but not exact; with a known texture the renderer itself refines it."""
    h, w = patch.mask.shape
    n = patch.modules.shape[0]
    X, Y = np.meshgrid(patch.x0 + np.arange(w, dtype=np.float64),
                       patch.y0 + np.arange(h, dtype=np.float64))
    m = to_uv
    den = m[2, 0] * X + m[2, 1] * Y + m[2, 2]
    u = (m[0, 0] * X + m[0, 1] * Y + m[0, 2]) / den
    v = (m[1, 0] * X + m[1, 1] * Y + m[1, 2]) / den
    # pattern texels per px at the window's centre
    cy, cx = h // 2, min(w // 2, w - 2)
    texels_per_px = math.hypot(u[cy, cx + 1] - u[cy, cx], v[cy, cx + 1] - v[cy, cx]) \
        * n * TEXELS_PER_MODULE
    pattern = _blurred_pattern(patch.modules, sigma_px * texels_per_px)
    pad = MARGIN_MODULES * TEXELS_PER_MODULE
    mx = (u * n * TEXELS_PER_MODULE + pad - 0.5).astype(np.float32)
    my = (v * n * TEXELS_PER_MODULE + pad - 0.5).astype(np.float32)
    return cv2.remap(pattern, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=1.0).astype(np.float64)


def residuals(patches: list[MarkerPatch], K: np.ndarray, pose: np.ndarray, arena: ArenaSpec,
              markers: MarkerSpec, sigma_px: float) -> np.ndarray:
    """Model minus image over every compared pixel, in linear light scaled to 0..255 (sRGB's
    steep dark end would let the darkest edge pixels dominate); each marker's black and white
    levels fitted by least squares."""
    out = []
    for patch in patches:
        cov = coverage(patch, image_to_uv(K, pose, arena, markers, patch.corner),
                       sigma_px)[patch.mask]
        y = patch.image_linear[patch.mask]
        a = np.column_stack([np.ones_like(cov), cov])
        (b, slope), *_ = np.linalg.lstsq(a, y, rcond=None)
        out.append(255.0 * (b + slope * cov - y))
    return np.concatenate(out)
