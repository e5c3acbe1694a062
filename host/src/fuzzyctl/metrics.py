"""Disparity error metrics with KITTI devkit semantics, the twin of ``firmware/app/metrics.cpp``.

Invalid estimates are first filled with the devkit's ``interpolateBackground()``, then every pixel
with ground truth is scored, so a sparse method is not rewarded for leaving holes.

Conventions (float32 maps of one shape, as the firmware holds them):
  estimate      valid where finite and > 0 (invalid = -1, 0 or NaN: the KITTI PNG cannot hold 0);
  ground truth  valid where finite and > 0 (0 = unknown, as ``dataset.load_ground_truth`` writes).

Errors are taken in double from the float32 values, like the firmware, so both give the same
figures to rounding of the sums (~1e-12).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from . import dump as dumpmod

ABS_THRESH = 3.0  # KITTI evaluate_stereo.cpp ABS_THRESH
REL_THRESH = 0.05  # KITTI REL_THRESH
BAD2_THRESH = 2.0

#: the figures of one frame / one set, in the firmware eval JSON's order
FIGURES = ("avg_err", "bad2", "bad3", "d1", "density")


@dataclass
class DispMetrics:
    avg_err: float = 0.0  # mean |d_est - d_gt| [px] over GT-valid pixels (after filling)
    bad2: float = 0.0  # % of GT-valid pixels with error > 2 px
    bad3: float = 0.0  # % with error > 3 px
    d1: float = 0.0  # % with error > 3 px AND > 5 % of d_gt (KITTI 2015 D1)
    density: float = 0.0  # % of GT-valid pixels that had an estimate before filling
    gt_pixels: int = 0

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def est_valid(d: np.ndarray) -> np.ndarray:
    return np.isfinite(d) & (d > 0)


def gt_valid(d: np.ndarray) -> np.ndarray:
    return np.isfinite(d) & (d > 0)


def disp_q4_to_float(q4: np.ndarray) -> np.ndarray:
    """A firmware Q4 map as ``disp_q4_to_float`` makes it: float32 px, -1 where invalid."""
    q4 = np.asarray(q4)
    return np.where(q4 == dumpmod.INVALID_DISP, np.float32(-1.0), q4.astype(np.float32) / np.float32(dumpmod.DISP_SCALE))


def fill_invalid_kitti(disp: np.ndarray) -> np.ndarray:
    """KITTI devkit ``interpolateBackground()``: per row, each run of invalid pixels with valid
    pixels on both sides takes the smaller (background) of the two neighbours; runs touching the
    left/right border take the nearest valid value of the row; then rows with no valid pixel above
    the first / below the last valid row take that row (an all-invalid row between valid rows stays
    invalid, as in the devkit)."""
    out = np.array(disp, dtype=np.float32, copy=True)
    h, w = out.shape
    valid = est_valid(out)
    for y in range(h):
        m = valid[y]
        if not m.any():
            continue
        d = out[y]
        idx = np.flatnonzero(m)
        # interior runs: between consecutive valid pixels idx[k], idx[k+1] with a gap
        gaps = np.flatnonzero(np.diff(idx) > 1)
        for k in gaps:
            a, b = idx[k], idx[k + 1]
            d[a + 1 : b] = min(d[a], d[b])
        d[: idx[0]] = d[idx[0]]
        d[idx[-1] + 1 :] = d[idx[-1]]
    rows = np.flatnonzero(valid.any(axis=1))
    if rows.size:
        out[: rows[0]] = out[rows[0]]
        out[rows[-1] + 1 :] = out[rows[-1]]
    return out


def evaluate_disparity(est: np.ndarray, gt: np.ndarray, area: np.ndarray | None = None,
                       filled: np.ndarray | None = None) -> DispMetrics:
    """Metrics of ``est`` against ``gt`` (float32 maps of one shape, conventions above). With ``area``
    (bool, same shape) only the GT-valid pixels inside it are scored; the filling still sees the
    whole map (the firmware's evaluate_disparity with an evaluation area). ``filled``: the map
    already filled (``fill_invalid_kitti(est)``), so several areas share one fill (evaluate_filled)."""
    est = np.asarray(est, dtype=np.float32)
    gt = np.asarray(gt, dtype=np.float32)
    if est.shape != gt.shape:
        raise ValueError(f"estimate {est.shape} and ground truth {gt.shape} sizes differ")
    if area is not None and np.shape(area) != gt.shape:
        raise ValueError(f"evaluation area {np.shape(area)} and ground truth {gt.shape} sizes differ")
    if filled is None:
        filled = fill_invalid_kitti(est)
    elif np.shape(filled) != gt.shape:
        raise ValueError(f"filled map {np.shape(filled)} and ground truth {gt.shape} sizes differ")
    g_ok = gt_valid(gt)
    if area is not None:
        g_ok &= np.asarray(area, dtype=bool)
    n = int(g_ok.sum())
    m = DispMetrics(gt_pixels=n)
    if n == 0:
        return m
    g = gt[g_ok].astype(np.float64)
    e = filled[g_ok]
    d_est = np.where(est_valid(e), e.astype(np.float64), 0.0)  # still invalid (whole map): scored as 0
    err = np.abs(g - d_est)
    m.avg_err = float(err.sum()) / n
    m.bad2 = 100.0 * int((err > BAD2_THRESH).sum()) / n
    m.bad3 = 100.0 * int((err > ABS_THRESH).sum()) / n
    m.d1 = 100.0 * int(((err > ABS_THRESH) & (err / np.abs(g) > REL_THRESH)).sum()) / n
    m.density = 100.0 * int(est_valid(est[g_ok]).sum()) / n
    return m


def set_means(per_frame: list[DispMetrics]) -> dict[str, float]:
    """A set's figures: the means of its per-frame figures (each frame weighs the same)."""
    k = len(per_frame)
    return {f: (sum(getattr(m, f) for m in per_frame) / k if k else 0.0) for f in FIGURES}
