"""Entropy-based selective refinement (ESR), Section III-A, eq. (14)-(15).

eq. (14): for every pixel, the Shannon entropy [bit] of the histogram of the disparities (rounded
to the nearest integer px, halves up) of the valid pixels in the w x w window centred on it (clipped at the image border; 0 when the window
has no valid pixel) — for the left-right checked left map (E_l) and the raw right WTA map (E_r) —
and the mean disparity of those valid pixels (mean_l, mean_r).

eq. (15): a valid left pixel with disparity d at (x, y) is compared with the right block at
x_r = x - round(d); when 0 <= x_r < W and |E_l(x, y) - E_r(x_r, y)| > tau it is replaced by mean_l(x, y)
if E_l < E_r, else by mean_r(x_r, y). Invalid left pixels stay invalid.
"""

from __future__ import annotations

import numpy as np

from .lrcheck import round_half_up


def box_sum(a: np.ndarray, window: int) -> np.ndarray:
    """Sum of ``a`` over the w x w window centred on every pixel, clipped at the border."""
    r = window // 2
    h, w = a.shape
    c = np.zeros((h + 1, w + 1))
    c[1:, 1:] = np.cumsum(np.cumsum(a, axis=0), axis=1)
    y0 = np.clip(np.arange(h) - r, 0, h)[:, None]
    y1 = np.clip(np.arange(h) + r + 1, 0, h)[:, None]
    x0 = np.clip(np.arange(w) - r, 0, w)[None, :]
    x1 = np.clip(np.arange(w) + r + 1, 0, w)[None, :]
    return c[y1, x1] - c[y0, x1] - c[y1, x0] + c[y0, x0]


def block_entropy(disp: np.ndarray, window: int, max_disparity: int) -> np.ndarray:
    """eq. (14): entropy [bit] of the (rounded) disparities of the valid pixels in each window."""
    valid = ~np.isnan(disp)
    d = np.where(valid, np.minimum(round_half_up(np.where(valid, disp, 0.0)), max_disparity), -1)
    n = box_sum(valid.astype(np.float64), window)
    sum_clogc = np.zeros(disp.shape)
    for v in np.unique(d[valid]):
        c = np.rint(box_sum((d == v).astype(np.float64), window))
        sum_clogc += np.where(c > 0, c * np.log2(np.where(c > 0, c, 1.0)), 0.0)
    # H = -sum (c/n) log2 (c/n) = log2 n - (1/n) sum c log2 c
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.where(n > 0, np.log2(np.where(n > 0, n, 1.0)) - sum_clogc / np.where(n > 0, n, 1.0), 0.0)
    return np.maximum(H, 0.0)


def block_mean(disp: np.ndarray, window: int) -> np.ndarray:
    """Mean of the valid disparities in each window (NaN when there is none)."""
    valid = ~np.isnan(disp)
    s = box_sum(np.where(valid, disp, 0.0), window)
    n = np.rint(box_sum(valid.astype(np.float64), window))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n > 0, s / np.where(n > 0, n, 1.0), np.nan)


def entropy_selective_refinement(
    disp_lr: np.ndarray, disp_right: np.ndarray, window: int, tau: float, max_disparity: int
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(refined left map, replaced mask, intermediates {E_l, E_r, mean_l, mean_r})."""
    h, w = disp_lr.shape
    E_l = block_entropy(disp_lr, window, max_disparity)
    E_r = block_entropy(disp_right, window, max_disparity)
    mean_l = block_mean(disp_lr, window)
    mean_r = block_mean(disp_right, window)

    valid = ~np.isnan(disp_lr)
    x = np.broadcast_to(np.arange(w), (h, w))
    xr = x - round_half_up(np.where(valid, disp_lr, 0.0))
    inside = valid & (xr >= 0) & (xr < w)
    xr_c = np.clip(xr, 0, w - 1)
    E_r_at = np.take_along_axis(E_r, xr_c, axis=1)
    mean_r_at = np.take_along_axis(mean_r, xr_c, axis=1)
    differs = inside & (np.abs(E_l - E_r_at) > tau)  # eq. (15), first two cases
    replacement = np.where(E_l < E_r_at, mean_l, mean_r_at)
    replaced = differs & ~np.isnan(replacement)
    out = np.where(replaced, replacement, disp_lr)
    return out, replaced, {"E_l": E_l, "E_r": E_r, "mean_l": mean_l, "mean_r": mean_r}
