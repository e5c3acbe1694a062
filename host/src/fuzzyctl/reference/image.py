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


def grey_quantiles(img: np.ndarray) -> np.ndarray:
    """The 5 %, 10 %, ..., 95 % grey-level quantiles of an 8-bit image (quantile p: the smallest
    level v with 100 * #(<= v) >= p * N), twin of the firmware's ``grey_quantiles`` (exact); all 0
    for an empty image."""
    if img.size == 0:
        return np.zeros(19, dtype=np.int64)
    c = np.cumsum(np.bincount(img.ravel(), minlength=256)).astype(np.int64)
    return np.array([min(int(np.searchsorted(100 * c, p * img.size)), 255) for p in range(5, 100, 5)])


def grey_quantile_shift(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute difference [grey levels] of the grey-level quantiles of two 8-bit images, twin
    of the firmware's ``grey_quantile_shift`` (exact: integers). Decides the gradient gain
    compensation under ``gradient_gain_trigger = "grey"`` (docs/algorithm.md 2b)."""
    if a.size == 0 or b.size == 0:
        return 0.0
    return float(np.abs(grey_quantiles(a) - grey_quantiles(b)).sum()) / 19.0


def estimate_noise_sigma(img: np.ndarray) -> float:
    """Noise std [grey levels] (not in the paper; docs/algorithm.md 2c), twin of the firmware's
    ``estimate_noise_sigma``: median of |N * I| over the interior pixels, N = [1 -2 1; -2 4 -2;
    1 -2 1] (Immerkaer 1996, median instead of mean so edges and texture do not count), divided by
    6 * 0.67449 (median |X| of X ~ N(0, 36 sigma^2)), over the interior pixels of rows 1, 3, 5, ...
    Exact: integer convolution, lower median."""
    if img.ndim != 2 or img.shape[0] < 3 or img.shape[1] < 3:
        return 0.0
    f = img.astype(np.int32)
    k = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.int32)
    h, w = f.shape
    v = np.zeros((h - 2, w - 2), dtype=np.int32)
    for j in range(3):
        for i in range(3):
            v += k[j, i] * f[j : j + h - 2, i : i + w - 2]
    a = np.sort(np.abs(v[::2]).ravel())  # rows y = 1, 3, 5, ... of the image
    n = a.size
    median = int(a[(n + 1) // 2 - 1])  # the smallest m with 2 * #(<= m) >= n
    return median / (6.0 * 0.67449)


def binomial_smooth(img: np.ndarray) -> np.ndarray:
    """One pass of the 3x3 binomial [1 2 1]^T [1 2 1] / 16, border replicated, rounded half up
    (uint8), twin of the firmware's ``binomial_smooth`` (exact: integers)."""
    f = np.pad(img.astype(np.int32), 1, mode="edge")
    col = f[:-2, :] + 2 * f[1:-1, :] + f[2:, :]
    s = col[:, :-2] + 2 * col[:, 1:-1] + col[:, 2:]
    return ((s + 8) >> 4).astype(np.uint8)


def grey_spread(img: np.ndarray) -> int:
    """q95 - q5 of the grey levels (at least 1), twin of the firmware's ``grey_spread`` (exact)."""
    q = grey_quantiles(img)
    return max(1, int(q[18] - q[0]))


def noise_excess(sigma_l: float, sigma_r: float, spread_l: int, spread_r: int) -> float:
    """Noise of the noisier image beyond the other's at the left image's contrast [grey levels]:
    sqrt(|sigma_l^2 - (sigma_r * spread_l / spread_r)^2|), twin of the firmware's ``noise_excess``."""
    r = sigma_r * spread_l / max(1, spread_r)
    return float(np.sqrt(abs(sigma_l * sigma_l - r * r)))


def noise_equalise(left: np.ndarray, right: np.ndarray, excess: float, image_passes: int,
                   gradient_passes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The matcher's noise equalisation (not in the paper; docs/algorithm.md 2c): when one image has
    more noise than the other by more than ``excess`` (0 = off), both get ``image_passes`` binomial
    passes for SLIC and the costs and ``gradient_passes`` for the gradients of eq. (5). Returns
    (left, right, gradient input left, gradient input right, smoothed)."""
    if excess <= 0.0:
        return left, right, left, right, False
    e = noise_excess(estimate_noise_sigma(left), estimate_noise_sigma(right), grey_spread(left), grey_spread(right))
    if e <= excess:
        return left, right, left, right, False

    def passes(img: np.ndarray, n: int) -> np.ndarray:
        for _ in range(n):
            img = binomial_smooth(img)
        return img

    return (passes(left, image_passes), passes(right, image_passes), passes(left, gradient_passes),
            passes(right, gradient_passes), True)
