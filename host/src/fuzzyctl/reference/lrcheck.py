"""eq. (13): left-right consistency check.

A left pixel (x, y) with disparity d_l is kept when its partner x - d_l lies in the image, the
right map is valid there and |d_l(x, y) - d_r(x - d_l(x, y), y)| <= max_diff; otherwise it becomes
invalid (NaN). With sub-pixel disparities the partner column is x - round(d_l), halves rounded
up (the firmware's ``partner_x``).
"""

from __future__ import annotations

import numpy as np


def round_half_up(d: np.ndarray) -> np.ndarray:
    """Nearest integer pixel, halves up (non-negative disparities)."""
    return np.floor(d + 0.5).astype(np.int64)


def left_right_check(disp_left: np.ndarray, disp_right: np.ndarray, max_diff: float) -> tuple[np.ndarray, np.ndarray]:
    """(checked left map with NaN = invalid, mask with True where eq. (13) holds)."""
    h, w = disp_left.shape
    valid_l = ~np.isnan(disp_left)
    x = np.broadcast_to(np.arange(w), (h, w))
    xr = x - round_half_up(np.where(valid_l, disp_left, 0.0))
    inside = valid_l & (xr >= 0) & (xr < w)
    d_r = np.take_along_axis(disp_right, np.clip(xr, 0, w - 1), axis=1)
    with np.errstate(invalid="ignore"):
        mask = inside & ~np.isnan(d_r) & (np.abs(disp_left - d_r) <= max_diff)
    return np.where(mask, disp_left, np.nan), mask
