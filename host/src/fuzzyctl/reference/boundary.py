"""Segment-boundary refinement of the WTA maps (not in the paper; docs/algorithm.md 4b).

Census transform of both images ((2r+1)^2 - 1 bits, a bit set where the neighbour is darker than
the centre, border replicated). For every valid pixel of a WTA map, the map's values at +-step and
+-2 step px along its row and column that differ from its own by >= min_jump px are candidates.
The cost of a disparity d is the sum over a window x window square (window pixels outside the
image take the nearest image pixel) of the Hamming distance between each pixel's census code and
its partner's at x - direction * round(d) (a partner outside the other image counts all bits). The
pixel takes the cheapest candidate (the first of equals, in the order row -step, +step, column
-step, +step, then the same at 2 step) when it beats its own disparity's cost by more than
round(margin * window^2). The firmware computes the same integers segment by segment with
summed-area tables; this twin computes one box-filtered Hamming plane per integer disparity.
"""

from __future__ import annotations

import numpy as np

from .esr import box_sum
from .lrcheck import round_half_up


def census(img: np.ndarray, radius: int) -> np.ndarray:
    """uint32 census codes of an 8-bit grey image (row-major neighbours, centre skipped)."""
    h, w = img.shape
    pad = np.pad(img.astype(np.int16), radius, mode="edge")
    centre = img.astype(np.int16)
    code = np.zeros((h, w), dtype=np.uint32)
    bit = 0
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dx == 0 and dy == 0:
                continue
            nb = pad[radius + dy : radius + dy + h, radius + dx : radius + dx + w]
            code |= (nb < centre).astype(np.uint32) << np.uint32(bit)
            bit += 1
    return code


def _popcount(v: np.ndarray) -> np.ndarray:
    v = v.astype(np.uint32)
    v = v - ((v >> 1) & 0x55555555)
    v = (v & 0x33333333) + ((v >> 2) & 0x33333333)
    v = (v + (v >> 4)) & 0x0F0F0F0F
    return ((v * np.uint32(0x01010101)) & np.uint32(0xFFFFFFFF)) >> 24


def _window_sums(plane: np.ndarray, r: int) -> np.ndarray:
    """Sum over the (2r+1)^2 window with replicated borders (exact integers): the ESR box sum of the
    edge-padded plane, whose windows are then never clipped."""
    return box_sum(np.pad(plane, r, mode="edge"), 2 * r + 1)[r : r + plane.shape[0], r : r + plane.shape[1]].astype(np.int64)


def refine(disp: np.ndarray, census_ref: np.ndarray, census_other: np.ndarray, direction: int, window: int,
           margin: float, step: int, min_jump: int, passes: int, bits: int) -> np.ndarray:
    """Refined map [px] (NaN = invalid) of one WTA map; direction +1: left reference."""
    h, w = disp.shape
    r = window // 2
    margin_total = int(np.floor(margin * window * window + 0.5))
    x = np.arange(w)
    cur = disp.astype(np.float64)
    for _ in range(passes):
        valid = ~np.isnan(cur)
        # The eight candidate planes, in the firmware's order, NaN where not a candidate.
        offs = [(-step, 0), (step, 0), (0, -step), (0, step), (-2 * step, 0), (2 * step, 0), (0, -2 * step), (0, 2 * step)]
        ys = np.arange(h)
        cands = []
        for ox, oy in offs:
            v = cur[np.clip(ys + oy, 0, h - 1)][:, np.clip(x + ox, 0, w - 1)]
            with np.errstate(invalid="ignore"):
                ok = valid & ~np.isnan(v) & (np.abs(v - cur) >= min_jump)
            cands.append(np.where(ok, v, np.nan))
        need = np.zeros((h, w), dtype=bool)
        for c in cands:
            need |= ~np.isnan(c)
        own_i = round_half_up(np.where(valid, cur, 0.0))
        cand_i = [round_half_up(np.where(np.isnan(c), 0.0, c)) for c in cands]
        own_cost = np.zeros((h, w), dtype=np.int64)
        cand_cost = [np.zeros((h, w), dtype=np.int64) for _ in cands]
        ds = set(np.unique(own_i[need]).tolist())
        for c, ci in zip(cands, cand_i):
            ds |= set(np.unique(ci[~np.isnan(c)]).tolist())
        for d in sorted(ds):
            xo = x - direction * d
            inside = (xo >= 0) & (xo < w)
            ham = np.full((h, w), bits, dtype=np.int64)
            ham[:, inside] = _popcount(census_ref[:, inside] ^ census_other[:, xo[inside]])
            sums = _window_sums(ham, r)
            sel = need & (own_i == d)
            own_cost[sel] = sums[sel]
            for c, ci, cc in zip(cands, cand_i, cand_cost):
                sel = ~np.isnan(c) & (ci == d)
                cc[sel] = sums[sel]
        best = own_cost - margin_total
        out = cur.copy()
        for c, cc in zip(cands, cand_cost):
            better = ~np.isnan(c) & (cc < best)
            best = np.where(better, cc, best)
            out = np.where(better, c, out)
        cur = np.where(need, out, cur)
    return cur


def refine_pair(disp_l: np.ndarray, disp_r: np.ndarray, left: np.ndarray, right: np.ndarray, b) -> tuple[np.ndarray, np.ndarray]:
    """Both WTA maps refined with the ``[boundary]`` config section ``b``, as the firmware's matcher does:
    the census of each image once, and a partner outside the other image counting all its bits."""
    cl, cr = census(left, b.census_radius), census(right, b.census_radius)
    args = (b.window, b.margin, b.step, b.min_jump, b.passes, (2 * b.census_radius + 1) ** 2 - 1)
    return refine(disp_l, cl, cr, +1, *args), refine(disp_r, cr, cl, -1, *args)
