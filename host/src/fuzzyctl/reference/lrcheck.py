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


def retry_rejected_segments(disp_lr: np.ndarray, mask: np.ndarray, labels: np.ndarray, winner: np.ndarray,
                            candidates: np.ndarray, scores: np.ndarray, disp_right: np.ndarray, max_diff: float,
                            tries: int, min_share: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Candidate retry after eq. (13) (docs/algorithm.md 5b; the firmware's ``retry_rejected_segments``).

    A segment whose winner (``winner``, integer px, -1 = none) kept no pixel of ``disp_lr`` ranks its other
    candidates (``candidates``/``scores``, (n, K)) by score, ties to the smaller d, skipping those within
    ``max_diff`` of the winner; of the first ``tries``, the first integer d that eq. (13) accepts on at least
    ``min_share`` of the segment's pixels is written on those pixels. Returns (map, mask, segments recovered)."""
    out, m = disp_lr.copy(), mask.copy()
    if tries <= 0:
        return out, m, 0
    h, w = labels.shape
    flat = labels.ravel()
    order = np.argsort(flat, kind="stable")
    starts = np.searchsorted(flat[order], np.arange(len(winner) + 1))
    valid = ~np.isnan(disp_lr).ravel()
    recovered = 0
    for s in range(len(winner)):
        if winner[s] < 0:
            continue
        idx = order[starts[s]:starts[s + 1]]
        if idx.size == 0 or valid[idx].any():
            continue
        ys, xs = np.divmod(idx, w)
        others = [(-float(sc), int(d)) for d, sc in zip(candidates[s], scores[s]) if abs(int(d) - int(winner[s])) > max_diff]
        others.sort()
        need = int(np.ceil(min_share * idx.size))
        for _, d in others[:tries]:
            xr = xs - d
            inside = xr >= 0
            d_r = disp_right[ys, np.clip(xr, 0, w - 1)]
            with np.errstate(invalid="ignore"):
                ok = inside & ~np.isnan(d_r) & (np.abs(d - d_r) <= max_diff)
            n_ok = int(ok.sum())
            if n_ok == 0 or n_ok < need:
                continue
            out[ys[ok], xs[ok]] = float(d)
            m[ys[ok], xs[ok]] = True
            recovered += 1
            break
    return out, m, recovered
