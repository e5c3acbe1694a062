"""Densification after ESR (not in the paper; docs/algorithm.md "Densification").

1. Disparity 0 (no match inside the search range) counts as no estimate.
2. Speckle removal: 4-connected regions of valid pixels whose neighbours differ by at most
   ``speckle_max_diff`` px are removed when they hold at most ``speckle_max_size`` pixels
   (OpenCV ``filterSpeckles``, the rule the firmware re-implements without OpenCV).
3. Fill (``fill``): every pixel without an estimate takes the median of the first valid disparity
   met along each of the 8 rays (horizontal, vertical, diagonal) from it; in the left border band,
   where the ray from the left meets no estimate, the nearest estimate to its right.
Float64 px, NaN = invalid.
"""

from __future__ import annotations

import warnings

import cv2
import numpy as np

#: (dy, dx); ray k of a pixel holds the first valid value met walking against (dy, dx).
DIRS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))


def remove_speckles(disp: np.ndarray, max_size: int, max_diff: float) -> tuple[np.ndarray, np.ndarray]:
    """(map with small regions set to NaN, removed mask)."""
    if max_size <= 0 or disp.size == 0:
        return disp.copy(), np.zeros(disp.shape, dtype=bool)
    # filterSpeckles takes int16 only: regions are found on the Q4-rounded map (Q4 = px * 16).
    work = np.where(np.isnan(disp), -1, np.floor(np.where(np.isnan(disp), 0.0, disp) * 16 + 0.5)).astype(np.int16)
    cv2.filterSpeckles(work, -1, int(max_size), int(round(max_diff * 16)))
    removed = ~np.isnan(disp) & (work == -1)
    return np.where(removed, np.nan, disp), removed


def _ray(disp: np.ndarray, dy: int, dx: int) -> np.ndarray:
    h, w = disp.shape
    out = np.full(disp.shape, np.nan)
    if dy == 0:
        prev = np.full(h, np.nan)
        for x in range(w) if dx > 0 else range(w - 1, -1, -1):
            v = disp[:, x]
            prev = np.where(np.isnan(v), prev, v)
            out[:, x] = prev
        return out
    prev = np.full(w, np.nan)
    for y in range(h) if dy > 0 else range(h - 1, -1, -1):
        shifted = np.full(w, np.nan)
        if dx > 0:
            shifted[1:] = prev[:-1]
        elif dx < 0:
            shifted[:-1] = prev[1:]
        else:
            shifted = prev
        v = disp[y]
        prev = np.where(np.isnan(v), shifted, v)
        out[y] = prev
    return out


def median_fill(disp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(filled map, filled mask)."""
    invalid = np.isnan(disp)
    if not invalid.any() or invalid.all():
        return disp.copy(), np.zeros(disp.shape, dtype=bool)
    rays = np.stack([_ray(disp, dy, dx) for dy, dx in DIRS])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN pixels stay NaN
        med = np.nanmedian(rays, axis=0)
    border = np.isnan(rays[0]) & ~np.isnan(rays[1])
    value = np.where(border, rays[1], med)
    out = np.where(invalid, value, disp)
    return out, invalid & ~np.isnan(out)


def densify(disp: np.ndarray, enabled: bool, speckle_max_size: int, speckle_max_diff: float, fill: bool) -> tuple[np.ndarray, np.ndarray]:
    """(final map, changed: 0 kept, 1 filled, 2 zero or removed as a speckle)."""
    if not enabled:
        return disp.copy(), np.zeros(disp.shape, dtype=np.uint8)
    zero = disp == 0
    d = np.where(zero, np.nan, disp)
    d, removed = remove_speckles(d, speckle_max_size, speckle_max_diff)
    out, filled = median_fill(d) if fill else (d, np.zeros(d.shape, dtype=bool))
    changed = np.where(zero | removed, 2, np.where(filled, 1, 0)).astype(np.uint8)
    return out, changed
