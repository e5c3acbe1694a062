"""Inputs and eq. (5): grey images and gradient magnitude.

Grey conversion is OpenCV's (``IMREAD_COLOR`` + ``COLOR_BGR2GRAY``, as the firmware does); the
gradient is the 3x3 Sobel pair with replicated border, magnitude rounded to the nearest integer.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import FatalError


def load_grey(path: str | Path) -> np.ndarray:
    """An image file as 8-bit grey (H, W) uint8, converted like the firmware; FatalError naming it."""
    path = Path(path)
    if not path.is_file():
        raise FatalError(f"image {path} not found")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise FatalError(f"image {path} cannot be decoded")
    return to_grey(img, str(path))


def to_grey(img: np.ndarray, name: str = "image") -> np.ndarray:
    if img.dtype == np.uint16:
        img = cv2.convertScaleAbs(img, alpha=1.0 / 256.0)
    if img.dtype != np.uint8:
        raise FatalError(f"{name}: only 8- or 16-bit images are supported (got {img.dtype})")
    if img.ndim == 3 and img.shape[2] == 3:
        return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.ndim == 3 and img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
    if img.ndim == 3 and img.shape[2] == 1:
        return np.ascontiguousarray(img[:, :, 0])
    if img.ndim == 2:
        return np.ascontiguousarray(img)
    raise FatalError(f"{name}: unsupported image shape {img.shape}")


def gradient_magnitude(img: np.ndarray) -> np.ndarray:
    """eq. (5): sqrt(gx^2 + gy^2) of 3x3 Sobel derivatives, border replicated, rounded (float64)."""
    f = img.astype(np.float64)
    gx = cv2.Sobel(f, cv2.CV_64F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(f, cv2.CV_64F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    # floor(x + 0.5): ties (never reached for integer gx, gy: sqrt of an integer is never k + 0.5)
    return np.floor(np.sqrt(gx * gx + gy * gy) + 0.5)


def compensate_gradient_gain(ref: np.ndarray, other: np.ndarray, deadband: float) -> tuple[np.ndarray, float]:
    """Gain compensation of the gradients (not in the paper; docs/algorithm.md 2b), float twin of
    the firmware's ``compensate_gradient_gain``: when the mean magnitudes differ by more than
    ``deadband``, ``other`` is scaled to ``ref``'s level (rounded, capped at 1443). Returns the new
    ``other`` and the factor (1.0 = unchanged). The firmware's factor is the same ratio in Q16, so the
    two agree to within one grey level per pixel."""
    sr, so = float(ref.sum()), float(other.sum())
    if sr == 0.0 or so == 0.0:
        return other, 1.0
    ratio = sr / so
    if ratio <= 1.0 + deadband and 1.0 / ratio <= 1.0 + deadband:
        return other, 1.0
    ratio = min(ratio, 16.0)
    return np.minimum(1443.0, np.floor(other * ratio + 0.5)), ratio


def grey_quantile_shift(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute difference [grey levels] of the 5 %, 10 %, ..., 95 % grey-level quantiles of
    two 8-bit images (quantile p: the smallest level v with 100 * #(<= v) >= p * N), twin of the
    firmware's ``grey_quantile_shift`` (exact: integers). Decides the gradient gain compensation
    under ``gradient_gain_trigger = "grey"`` (docs/algorithm.md 2b)."""
    if a.size == 0 or b.size == 0:
        return 0.0

    def quantiles(img: np.ndarray) -> np.ndarray:
        c = np.cumsum(np.bincount(img.ravel(), minlength=256)).astype(np.int64)
        return np.array([min(int(np.searchsorted(100 * c, p * img.size)), 255) for p in range(5, 100, 5)])

    return float(np.abs(quantiles(a) - quantiles(b)).sum()) / 19.0
