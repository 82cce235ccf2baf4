"""Image similarity: SSIM (Gaussian window) and mean absolute difference, in grayscale."""

from __future__ import annotations

import cv2
import numpy as np

#: SSIM constants (Wang et al. 2004): K1 = 0.01, K2 = 0.03, dynamic range 255.
_C1 = (0.01 * 255.0) ** 2
_C2 = (0.03 * 255.0) ** 2
#: Gaussian window: sigma 1.5, 11 x 11.
_SIGMA = 1.5
_WINDOW = 11


def to_gray(image: np.ndarray) -> np.ndarray:
    """Grayscale float64 copy of an (H, W) or (H, W, 3) BGR uint8 image."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    return img.astype(np.float64)


def _gray_pair(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x, y = to_gray(a), to_gray(b)
    if x.shape != y.shape:
        raise ValueError(f"images must have the same shape, got {x.shape} and {y.shape}")
    return x, y


def ssim_map(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel SSIM of two grayscale images of the same shape (Gaussian window, sigma 1.5).

    Raises
    ------
    ValueError
        When the shapes differ.
    """
    x, y = _gray_pair(a, b)

    def blur(img: np.ndarray) -> np.ndarray:
        return cv2.GaussianBlur(img, (_WINDOW, _WINDOW), _SIGMA, borderType=cv2.BORDER_REFLECT)

    mx, my = blur(x), blur(y)
    sxx = blur(x * x) - mx * mx
    syy = blur(y * y) - my * my
    sxy = blur(x * y) - mx * my
    num = (2 * mx * my + _C1) * (2 * sxy + _C2)
    den = (mx * mx + my * my + _C1) * (sxx + syy + _C2)
    return num / den


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean SSIM of two images compared in grayscale (BGR or gray uint8 input)."""
    return float(ssim_map(a, b).mean())


def mean_abs_diff(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute difference in grey levels of two images compared in grayscale.

    Raises
    ------
    ValueError
        When the shapes differ.
    """
    x, y = _gray_pair(a, b)
    return float(np.abs(x - y).mean())
