"""Photometric degradations applied to a rendered image, each a preset parameter with a neutral
default.

:class:`Degradations` and :func:`apply_degradations`, in the order a camera applies them:
vignetting, exposure, motion / defocus blur, Gaussian and Poisson noise, gamma, JPEG. Each one
at its neutral value is skipped entirely, so an all-neutral :class:`Degradations` returns the
input array unchanged (byte-identical). Lens distortion (geometric) is
:mod:`arenabench.generator.model.lens`.

All randomness (noise) comes from the generator passed in
(:func:`arenabench.generator.dataset.make.degrade_rng`).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields
from typing import Any

import cv2
import numpy as np

from arenabench.generator.parameters.params import PARAMETERS, lands_in

#: Preset parameter name of each :class:`Degradations` field (declared in the registry).
PARAM_NAMES: dict[str, str] = lands_in("degrade")

@dataclass(frozen=True)
class Degradations:
    """Photometric degradations of one image (all neutral by default).

    Each field is the ``degrade.*`` parameter of :data:`PARAM_NAMES` and takes the values its
    declaration allows (:data:`arenabench.generator.parameters.params.PARAMS`: bounds, integer or
    not).

    Parameters
    ----------
    vignetting : float
        Corner darkening, 0..1: gain ``1 - vignetting * (r / r_corner)^2`` (0 = none).
    exposure_ev : float
        Exposure change in stops: intensities times ``2 ** exposure_ev`` (0 = none).
    motion_blur_px : float
        Length of a linear motion-blur kernel in px (0 = none).
    motion_angle_deg : float
        Direction of the motion blur, counter-clockwise from the image x axis.
    defocus_px : float
        Radius of a disc (defocus) blur kernel in px (0 = none).
    noise_sigma : float
        Standard deviation of additive Gaussian noise in grey levels (0 = none).
    poisson_photons : float
        Photons collected at full scale (255) for shot noise; fewer = noisier (0 = none).
        Exact Poisson below :data:`POISSON_EXACT_BELOW` photons, a Gaussian with the same mean
        and variance above.
    gamma : float
        Display gamma: ``out = 255 (in / 255) ** (1 / gamma)``; > 1 brightens mid-tones
        (1 = none).
    jpeg_quality : int
        JPEG encode + decode at this quality, 1..100 (0 = none).
    """

    vignetting: float = 0.0
    exposure_ev: float = 0.0
    motion_blur_px: float = 0.0
    motion_angle_deg: float = 0.0
    defocus_px: float = 0.0
    noise_sigma: float = 0.0
    poisson_photons: float = 0.0
    gamma: float = 1.0
    jpeg_quality: int = 0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            spec = PARAMETERS[PARAM_NAMES[f.name]]  # its bounds and kind: declared once
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ValueError(f"{spec.name} must be a number, got {value!r}")
            if not math.isfinite(float(value)):
                raise ValueError(f"{spec.name} must be finite, got {value!r}")
            b = spec.bounds
            if b is not None and not b.lo <= value <= b.hi:
                raise ValueError(f"{spec.name}: value {value!r} out of range "
                                 f"[{b.lo:g}, {b.hi:g}]")
            if spec.kind == "int" and int(value) != value:
                raise ValueError(f"{spec.name}: value {value!r} is not an integer")
        object.__setattr__(self, "jpeg_quality", int(self.jpeg_quality))

    @classmethod
    def from_params(cls, params: dict[str, Any]) -> Degradations:
        """Build from a mapping of preset parameter names (``degrade.*``); missing = neutral."""
        kwargs = {f: params[p] for f, p in PARAM_NAMES.items() if p in params}
        return cls(**kwargs)

    @property
    def is_neutral(self) -> bool:
        """True when :func:`apply_degradations` would return its input unchanged."""
        return self == Degradations(motion_angle_deg=self.motion_angle_deg)


def _motion_kernel(length: float, angle_deg: float) -> np.ndarray:
    """Normalised line kernel of ``length`` px (anti-aliased ends) at ``angle_deg``."""
    size = math.ceil(length) | 1
    size = max(size, 3)
    k = np.zeros((size * 4, size * 4), np.float32)  # drawn 4x supersampled
    c = (size * 4 - 1) / 2.0
    a = math.radians(angle_deg)
    dx, dy = math.cos(a) * length * 2.0, -math.sin(a) * length * 2.0
    p0 = (round((c - dx) * 16), round((c - dy) * 16))
    p1 = (round((c + dx) * 16), round((c + dy) * 16))
    cv2.line(k, p0, p1, 1.0, thickness=4, lineType=cv2.LINE_AA, shift=4)
    k = cv2.resize(k, (size, size), interpolation=cv2.INTER_AREA)
    return k / k.sum()


def _disc_kernel(radius: float) -> np.ndarray:
    """Normalised disc kernel of ``radius`` px (anti-aliased edge, 4x supersampled)."""
    size = 2 * math.ceil(radius) + 1
    n = size * 4
    yy, xx = np.mgrid[0:n, 0:n]
    c = (n - 1) / 2.0
    k = ((xx - c) ** 2 + (yy - c) ** 2 <= (radius * 4) ** 2).astype(np.float32)
    k = cv2.resize(k, (size, size), interpolation=cv2.INTER_AREA)
    if k.sum() == 0:
        k[size // 2, size // 2] = 1.0
    return k / k.sum()


@functools.lru_cache(maxsize=8)
def _vignette_gain(width: int, height: int, strength: float) -> np.ndarray:
    xs = (np.arange(width, dtype=np.float32) - (width - 1) / 2.0) / ((width - 1) / 2.0 or 1.0)
    ys = (np.arange(height, dtype=np.float32) - (height - 1) / 2.0) / ((height - 1) / 2.0 or 1.0)
    r2 = (xs[None, :] ** 2 + ys[:, None] ** 2) / 2.0  # 1 at the image corners
    gain = (1.0 - strength * r2).astype(np.float32)
    gain.setflags(write=False)
    return gain


#: Below this many photons a pixel's shot noise is drawn from the exact Poisson law; above it
#: from a Gaussian with the Poisson mean and variance (indistinguishable there, ~10x faster).
POISSON_EXACT_BELOW = 30.0


def standard_normal(shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
    """Float32 N(0, 1) samples of ``shape``, seeded from ``rng``.

    OpenCV's ziggurat sampler (``cv2.randn``) is about 4x faster than NumPy's for an image's
    worth of samples. Its state is OpenCV's per-thread default RNG, which is re-seeded from
    ``rng`` on every call, so the result depends only on ``rng`` (the same across processes,
    threads and OpenCV thread counts).

    The samples are a function of that seed and ``shape``: the last field is kept and a copy
    of it given (0.8 ms instead of 6.6 ms for 1000 x 1000 x 3) when they come again, as they do
    at every noise level of a sweep's scene.
    """
    return _normal_field(int(rng.integers(0, 2**31 - 1)), tuple(shape)).copy()


@functools.lru_cache(maxsize=1)
def _normal_field(seed: int, shape: tuple[int, ...]) -> np.ndarray:
    """Read-only float32 N(0, 1) samples of ``shape`` from ``cv2.randn`` seeded with ``seed``."""
    field = np.empty(shape, dtype=np.float32)
    cv2.setRNGSeed(seed)  # OpenCV's RNG of this thread, used right here
    cv2.randn(field.reshape(-1, shape[-1] if len(shape) > 1 else 1), 0.0, 1.0)
    field.flags.writeable = False
    return field


def _shot_noise(img: np.ndarray, photons: float, rng: np.random.Generator) -> np.ndarray:
    """Shot noise on a float32 image in grey levels, ``photons`` collected at 255."""
    scale = np.float32(photons / 255.0)
    lam = np.clip(img, 0.0, None) * scale
    counts = standard_normal(lam.shape, rng)
    counts *= np.sqrt(lam)
    counts += lam
    small = lam < POISSON_EXACT_BELOW
    if small.any():
        counts[small] = rng.poisson(lam[small]).astype(np.float32)
    return counts / scale


def apply_degradations(rgb: np.ndarray, params: Degradations,
                       rng: np.random.Generator) -> np.ndarray:
    """Apply photometric degradations to an image.

    Parameters
    ----------
    rgb : numpy.ndarray
        (H, W, 3) uint8 image.
    params : Degradations
        What to apply; neutral fields are skipped.
    rng : numpy.random.Generator
        Source of the noise (only drawn from when noise is on).

    Returns
    -------
    numpy.ndarray
        (H, W, 3) uint8; the input object itself when ``params`` is neutral.

    Raises
    ------
    ValueError
        When ``rgb`` is not an (H, W, 3) uint8 array.
    """
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb must be (H, W, 3) uint8, got {rgb.dtype} {rgb.shape}")
    if params.is_neutral:
        return rgb
    h, w = rgb.shape[:2]
    out = rgb
    linear = (params.vignetting > 0 or params.exposure_ev != 0 or params.motion_blur_px > 0
              or params.defocus_px > 0 or params.noise_sigma > 0 or params.poisson_photons > 0)
    if linear:
        img = rgb.astype(np.float32)
        if params.vignetting > 0:
            img *= _vignette_gain(w, h, float(params.vignetting))[:, :, None]
        if params.exposure_ev != 0:
            img *= np.float32(2.0 ** params.exposure_ev)
        if params.exposure_ev > 0 or params.vignetting > 0:
            np.clip(img, 0.0, 255.0, out=img)  # the sensor saturates before the optics blur
        if params.motion_blur_px > 0:
            kernel = _motion_kernel(float(params.motion_blur_px), float(params.motion_angle_deg))
            img = cv2.filter2D(img, -1, kernel, borderType=cv2.BORDER_REFLECT)
        if params.defocus_px > 0:
            img = cv2.filter2D(img, -1, _disc_kernel(float(params.defocus_px)),
                               borderType=cv2.BORDER_REFLECT)
        if params.poisson_photons > 0:
            img = _shot_noise(img, float(params.poisson_photons), rng)
        if params.noise_sigma > 0:
            noise = standard_normal(img.shape, rng)
            noise *= np.float32(params.noise_sigma)
            img += noise
        # round half to even and saturate, as np.clip(np.rint(img), 0, 255) would, in one pass
        out = cv2.add(img, 0.0, dtype=cv2.CV_8U)
    if params.gamma != 1.0:
        lut = np.clip(np.rint(255.0 * (np.arange(256) / 255.0) ** (1.0 / params.gamma)), 0, 255)
        out = cv2.LUT(out, lut.astype(np.uint8))
    if params.jpeg_quality > 0:
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(out, cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_JPEG_QUALITY, int(params.jpeg_quality)])
        if not ok:  # pragma: no cover - OpenCV always encodes a valid uint8 image
            raise ValueError("degrade.jpeg_quality: JPEG encoding failed")
        out = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return np.ascontiguousarray(out)
