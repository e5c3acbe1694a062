"""Densification after ESR (not in the paper; docs/algorithm.md "Densification").

1. Disparity 0 (no match inside the search range) counts as no estimate.
2. Speckle removal: 4-connected regions of valid pixels whose neighbours differ by at most
   ``speckle_max_diff`` px are removed when they hold at most ``speckle_max_size`` pixels
   (OpenCV ``filterSpeckles``, the rule the firmware re-implements without OpenCV).
3. Fill (``fill``): every pixel without an estimate takes the median of the first valid disparity
   met along each of the 8 rays (horizontal, vertical, diagonal) from it; in the left border band,
   where the ray from the left meets no estimate, the nearest estimate to its right. With
   ``interpolate_max_diff`` > 0, each pair of opposite rays whose values differ by at most that
   many px (one surface on both sides) gives both its members the linear interpolation between
   them at the pixel before the median (slant-aware fill; docs/algorithm.md 6b).
Before 3, with ``occlusion_fill`` (docs/algorithm.md 6c): a pixel without an estimate that no pixel of
the right-reference map sees (xr + round(d_r(xr)) further than ``occlusion_dilate`` px from it) is
occluded in the right image; in a run of holes along its row of at most ``occlusion_max_gap`` px it
takes the background, the smaller of the two estimates bounding the run (the one there is at a border).
After 3, with ``smooth`` (docs/algorithm.md 6d): a bilateral filter of the dense map on the sparse
tap grid {-r, .., r}^2 in steps of ``smooth_step`` (r = ``smooth_radius`` rounded down to a multiple of
the step, image edges replicated); weights exp(-(dx^2 + dy^2) / 2 sigma_s^2) * (1 - (delta / 2 sigma_r)^2)^2
(Tukey's biweight, 0 from 2 sigma_r on) with sigma_r = max(``smooth_sigma_range``, ``smooth_sigma_range_rel``
* d); the firmware in Q12 with delta / 2 sigma_r in 1/128 steps, here in float.
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


#: pairs of opposite directions in DIRS
OPPOSITE = ((0, 1), (2, 3), (4, 7), (5, 6))


def _ray(disp: np.ndarray, dy: int, dx: int) -> tuple[np.ndarray, np.ndarray]:
    """(first valid value walking against (dy, dx), the number of steps to it)."""
    h, w = disp.shape
    out = np.full(disp.shape, np.nan)
    steps = np.zeros(disp.shape)
    if dy == 0:
        prev = np.full(h, np.nan)
        pt = np.zeros(h)
        for x in range(w) if dx > 0 else range(w - 1, -1, -1):
            v = disp[:, x]
            ok = ~np.isnan(v)
            prev = np.where(ok, v, prev)
            pt = np.where(ok, 0.0, pt + 1)
            out[:, x] = prev
            steps[:, x] = pt
        return out, steps
    prev = np.full(w, np.nan)
    pt = np.zeros(w)
    for y in range(h) if dy > 0 else range(h - 1, -1, -1):
        shifted = np.full(w, np.nan)
        st = np.zeros(w)
        if dx > 0:
            shifted[1:] = prev[:-1]
            st[1:] = pt[:-1]
        elif dx < 0:
            shifted[:-1] = prev[1:]
            st[:-1] = pt[1:]
        else:
            shifted, st = prev, pt
        v = disp[y]
        ok = ~np.isnan(v)
        prev = np.where(ok, v, shifted)
        pt = np.where(ok, 0.0, st + 1)
        out[y] = prev
        steps[y] = pt
    return out, steps


def median_fill(disp: np.ndarray, interpolate_max_diff: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(filled map, filled mask)."""
    invalid = np.isnan(disp)
    if not invalid.any() or invalid.all():
        return disp.copy(), np.zeros(disp.shape, dtype=bool)
    walks = [_ray(disp, dy, dx) for dy, dx in DIRS]
    rays = np.stack([r for r, _ in walks])
    values = rays.copy()
    if interpolate_max_diff > 0:
        with np.errstate(invalid="ignore", divide="ignore"):
            for a, b in OPPOSITE:
                (va, ta), (vb, tb) = walks[a], walks[b]
                ok = ~np.isnan(va) & ~np.isnan(vb) & (np.abs(va - vb) <= interpolate_max_diff)
                line = (va * tb + vb * ta) / np.where(ok, ta + tb, 1.0)
                values[a] = np.where(ok, line, values[a])
                values[b] = np.where(ok, line, values[b])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN pixels stay NaN
        med = np.nanmedian(values, axis=0)
    border = np.isnan(rays[0]) & ~np.isnan(rays[1])
    value = np.where(border, rays[1], med)
    out = np.where(invalid, value, disp)
    return out, invalid & ~np.isnan(out)


def seen_by_right(disp_right: np.ndarray, dilate: int) -> np.ndarray:
    """Left pixels some right pixel lands on: x = xr + round(d_r(xr)), widened by ``dilate`` px."""
    h, w = disp_right.shape
    hit = np.zeros((h, w), dtype=bool)
    ys, xr = np.nonzero(~np.isnan(disp_right))
    x = xr + np.floor(disp_right[ys, xr] + 0.5).astype(np.int64)
    ok = (x >= 0) & (x < w)
    hit[ys[ok], x[ok]] = True
    seen = hit.copy()
    for k in range(1, dilate + 1):
        seen[:, k:] |= hit[:, :-k]
        seen[:, :-k] |= hit[:, k:]
    return seen


def occlusion_fill(disp: np.ndarray, disp_right: np.ndarray, dilate: int, max_gap: int) -> tuple[np.ndarray, np.ndarray]:
    """(map with the occluded holes set to their row's background, filled mask); see the module doc."""
    if disp_right.shape != disp.shape:
        raise ValueError(f"occlusion_fill: right map {disp_right.shape} and left map {disp.shape} differ in size")
    seen = seen_by_right(disp_right, dilate)
    out = disp.copy()
    filled = np.zeros(disp.shape, dtype=bool)
    h, w = disp.shape
    for y in range(h):
        holes = np.isnan(disp[y])
        if not holes.any():
            continue
        # runs of holes: starts where a hole follows an estimate (or the border), ends likewise
        edges = np.diff(np.concatenate(([0], holes.astype(np.int8), [0])))
        for x0, x1 in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]):
            bounds = [disp[y, x0 - 1]] if x0 > 0 else []
            bounds += [disp[y, x1]] if x1 < w else []
            if x1 - x0 > max_gap or not bounds:
                continue
            take = ~seen[y, x0:x1]
            out[y, x0:x1][take] = min(bounds)
            filled[y, x0:x1] = take
    return out, filled


def smooth_disparity(disp: np.ndarray, radius: int, step: int, sigma_space: float, sigma_range: float,
                     sigma_range_rel: float = 0.0) -> np.ndarray:
    """The bilateral smoothing of the module doc; NaN pixels stay NaN and weigh nothing."""
    r = (radius // step) * step
    h, w = disp.shape
    pad = np.pad(disp, r, mode="edge") if r > 0 else disp
    sigma = np.maximum(sigma_range, sigma_range_rel * np.nan_to_num(disp))
    num = np.zeros_like(disp, dtype=np.float64)
    den = np.zeros_like(disp, dtype=np.float64)
    for oy in range(-r, r + 1, step):
        for ox in range(-r, r + 1, step):
            s = pad[r + oy : r + oy + h, r + ox : r + ox + w]
            u = np.abs(s - disp) / (2.0 * sigma)
            wr = np.where(u < 1.0, (1.0 - u**2) ** 2, 0.0)  # Tukey's biweight
            wt = np.exp(-(ox * ox + oy * oy) / (2.0 * sigma_space**2)) * np.nan_to_num(wr)
            num += wt * np.nan_to_num(s)
            den += wt
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.isnan(disp), np.nan, num / den)


def extrapolate_left_border(out: np.ndarray, before: np.ndarray, window: int, cap: float = 0.0,
                            min_slope: float = 0.0) -> int:
    """Left border band (docs/algorithm.md 6f): per row whose first estimate of ``before`` (NaN = none) is at
    x0 > 0, the least-squares line through its estimates in [x0, x0 + window) (at least max(3, window // 4));
    when it rises towards the border by at least ``min_slope`` px per column (and by anything when 0),
    ``out[:x0]`` takes its values, capped at ``cap`` (> 0). In place; returns the rows extrapolated."""
    rows = 0
    if window <= 0:
        return 0
    for y in range(before.shape[0]):
        valid = ~np.isnan(before[y])
        if not valid.any() or valid[0]:
            continue
        x0 = int(np.argmax(valid))
        xs = np.nonzero(valid[x0:x0 + window])[0] + x0
        if len(xs) < max(3, window // 4):
            continue
        ds = before[y, xs].astype(np.float64)
        xm, dm = xs.mean(), ds.mean()
        sxx, sxd = float(((xs - xm) ** 2).sum()), float(((xs - xm) * (ds - dm)).sum())
        if sxx <= 0 or sxd >= 0 or (min_slope > 0 and -sxd < min_slope * sxx):
            continue
        v = dm + sxd / sxx * (np.arange(x0) - xm)
        out[y, :x0] = np.minimum(v, cap) if cap > 0 else v
        rows += 1
    return rows


def densify(
    disp: np.ndarray, enabled: bool, speckle_max_size: int, speckle_max_diff: float, fill: bool, interpolate_max_diff: float = 0.0,
    disp_right: np.ndarray | None = None, occlusion_dilate: int = 1, occlusion_max_gap: int = 64,
    smooth: tuple[int, int, float, float, float] | None = None,
    border_fit: tuple[int, float, int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(final map, changed: 0 kept, 1 filled, 2 zero or removed as a speckle). The occlusion fill runs
    when ``disp_right`` (the right-reference WTA map) is given, the smoothing when ``smooth`` is.
    ``changed`` marks the fill only: smoothing moves almost every pixel by a fraction of a pixel."""
    if not enabled:
        return disp.copy(), np.zeros(disp.shape, dtype=np.uint8)
    zero = disp == 0
    d = np.where(zero, np.nan, disp)
    d, removed = remove_speckles(d, speckle_max_size, speckle_max_diff)
    occ = np.zeros(d.shape, dtype=bool)
    if disp_right is not None:
        d, occ = occlusion_fill(d, disp_right, occlusion_dilate, occlusion_max_gap)
    out, filled = median_fill(d, interpolate_max_diff) if fill else (d, np.zeros(d.shape, dtype=bool))
    if fill and border_fit is not None and border_fit[0] > 0:  # (window px, min slope px/column, max_disparity)
        extrapolate_left_border(out, d, border_fit[0], border_fit[2] - 1 if border_fit[2] > 0 else 0.0, border_fit[1])
    if smooth is not None:  # (radius, step, sigma_space, sigma_range, sigma_range_rel)
        out = smooth_disparity(out, *smooth)
    changed = np.where(occ, 1, np.where(zero | removed, 2, np.where(filled, 1, 0))).astype(np.uint8)
    return out, changed


def densify_config(disp: np.ndarray, disp_right: np.ndarray | None, dn, max_disparity: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """densify with the fields of a ``[densify]`` config section (the occlusion fill when it is on);
    ``max_disparity`` (the ``[cost]`` search range) caps the left border extrapolation."""
    return densify(disp, dn.enabled, dn.speckle_max_size, dn.speckle_max_diff, dn.fill, dn.interpolate_max_diff,
                   disp_right if dn.occlusion_fill else None, dn.occlusion_dilate, dn.occlusion_max_gap,
                   (dn.smooth_radius, dn.smooth_step, dn.smooth_sigma_space, dn.smooth_sigma_range, dn.smooth_sigma_range_rel)
                   if dn.smooth else None,
                   (dn.border_fit_px, dn.border_fit_min_slope, max_disparity) if dn.border_fit_px > 0 else None)
