"""Float64 reference of the obstacle detection (paper Section III-B, eq. 16-25) — the desktop twin
of firmware/core/src/detect/, with the same parameters (``[detect]`` of the config) and the same
choices (docs/detection.md), written independently in float/numpy:

  road     eq. (16)-(17)  v-disparity, weighted RANSAC (same xorshift64* stream) + per-row refit,
                          |d - (a v + b)| <= tol in float, closing by OpenCV (rectangle)
  sky      eq. (18)-(21)  HSV in float, exactly as written (no rounding)
  kmeans   eq. (22)-(23)  1-D Lloyd in float on the pixels, quantile init, centre merge
  udisp    eq. (24)-(25)  per-cluster column histograms (numpy), support and runs
  objects                 8-connected flood fill with the disparity step, bimodal split (Otsu on the
                          float values), fragment and occlusion merging, float median, Z = f B / d

Where the firmware rounds (Q4 disparities, integer HSV, integer k-means means) this twin does not,
so results agree up to those roundings; ``fuzzyctl compare`` measures the agreement.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

_M64 = (1 << 64) - 1


@dataclass
class DetectParams:
    values: dict[str, Any]

    def __getattr__(self, key: str) -> Any:
        try:
            return self.values[key]
        except KeyError as exc:
            raise AttributeError(key) from exc


@dataclass
class Obstacle:
    id: int
    box: tuple[int, int, int, int]
    pixel_count: int
    disparity_px: float
    distance_m: float
    lateral_m: float
    cls: str


@dataclass
class DetectReferenceResult:
    bins: int
    vdisp: np.ndarray
    road_found: bool
    road_a: float
    road_b: float
    horizon_row: int
    road_raw: np.ndarray
    road_mask: np.ndarray
    sky_skipped: bool
    sky_rows: int
    sky_mask: np.ndarray
    candidates: np.ndarray
    centres_px: list[float]
    cluster_labels: np.ndarray
    kept: np.ndarray
    obstacles: list[Obstacle] = field(default_factory=list)
    obstacle_labels: np.ndarray | None = None


def params_from_config(cfg) -> DetectParams:
    """The ``[detect]`` section of a :class:`fuzzyctl.config.Config` (already validated)."""
    return DetectParams(dict(cfg.as_dict()["detect"]))


# ---- (a) road ---------------------------------------------------------------------------------

def disp_bin(d: np.ndarray) -> np.ndarray:
    """round(d), half up (d >= 0)."""
    return np.floor(d + 0.5).astype(np.int64)


def v_disparity(disp: np.ndarray, bins: int) -> np.ndarray:
    """eq. (17): per row, count of pixels with round(d) = column."""
    h = disp.shape[0]
    valid = np.isfinite(disp)
    rows = np.nonzero(valid)[0]
    out = np.zeros((h, bins), np.int64)
    np.add.at(out, (rows, disp_bin(disp[valid])), 1)
    return out


class _XorShift64Star:
    """Same generator as the firmware (firmware/core/src/detect/vdisparity.cpp)."""

    def __init__(self, seed: int):
        self.s = (0x9E3779B97F4A7C15 ^ (seed & 0xFFFFFFFF)) & _M64 or 1

    def next(self) -> int:
        s = self.s
        s ^= s >> 12
        s ^= (s << 25) & _M64
        s ^= s >> 27
        self.s = s
        return (s * 0x2545F4914F6CDD1D) & _M64


def fit_road_line(vd: np.ndarray, valid_pixels: int, p: DetectParams) -> tuple[bool, float, float, int]:
    v_idx, d_idx = np.nonzero(vd)
    keep = (d_idx >= 1) & (vd[v_idx, d_idx] >= p.road_min_cell_count)
    v_c, d_c = v_idx[keep].astype(np.float64), d_idx[keep].astype(np.float64)
    w = vd[v_idx[keep], d_idx[keep]].astype(np.int64)
    if len(w) < 2:
        return False, 0.0, 0.0, -1
    cum = np.cumsum(w)
    total = int(cum[-1])
    rng = _XorShift64Star(int(p.road_ransac_seed))
    tol = p.road_fit_tolerance_px

    def score(a: float, b: float) -> int:
        return int(w[np.abs(d_c - (a * v_c + b)) <= tol].sum())

    best = (-1, 0.0, 0.0)
    for _ in range(int(p.road_ransac_iterations)):
        i1 = int(np.searchsorted(cum, rng.next() % total, side="right"))
        i2 = int(np.searchsorted(cum, rng.next() % total, side="right"))
        if v_c[i1] == v_c[i2]:
            continue
        a = (d_c[i2] - d_c[i1]) / (v_c[i2] - v_c[i1])
        if a < p.road_slope_min or a > p.road_slope_max:
            continue
        b = d_c[i1] - a * v_c[i1]
        s = score(a, b)
        if s > best[0]:
            best = (s, a, b)
    bs, ba, bb = best
    if bs <= 0:
        return False, 0.0, 0.0, -1
    # Refit: per row the inlier cell with the most pixels, weighted least squares.
    inl = np.abs(d_c - (ba * v_c + bb)) <= tol
    rows: dict[int, int] = {}
    for i in np.nonzero(inl)[0]:
        r = int(v_c[i])
        if r not in rows or w[i] > w[rows[r]]:
            rows[r] = i
    idx = np.array(sorted(rows.values()))
    if len(idx) >= 2:
        a, b = np.polyfit(v_c[idx], d_c[idx], 1, w=np.sqrt(w[idx].astype(np.float64)))
        s = score(a, b)
        if p.road_slope_min <= a <= p.road_slope_max and s * 100 >= bs * 98:
            bs, ba, bb = s, float(a), float(b)
    if bs < p.road_min_support_pct / 100.0 * valid_pixels:
        return False, 0.0, 0.0, -1
    horizon = int(np.clip(np.floor(-bb / ba) + 1, 0, vd.shape[0]))
    return True, float(ba), float(bb), horizon


def road_slope_range(p: DetectParams, calib: dict) -> tuple[float, float]:
    """Slope prior (docs/detection.md "(a) Slope prior"): [road_slope_min, road_slope_max], narrowed with a
    known mounting (height_m > 0) to a0 / (1 + r) .. a0 * (1 + r), a0 = B cos(pitch) / h."""
    lo, hi = float(p.road_slope_min), float(p.road_slope_max)
    h, base = float(calib.get("height_m", 0.0) or 0.0), float(calib["baseline_m"])
    if p.road_slope_prior_rel > 0 and h > 0 and base > 0:
        a0 = base * np.cos(np.radians(float(calib.get("pitch_deg", 0.0) or 0.0))) / h
        lo, hi = max(lo, a0 / (1 + p.road_slope_prior_rel)), min(hi, a0 * (1 + p.road_slope_prior_rel))
    return lo, hi


def road_pixels(disp: np.ndarray, a: float, b: float, horizon: int, tol: float, rel: float = 0.0) -> np.ndarray:
    """|d - (a v + b)| <= tol + rel * (a v + b): the band grows with the line's disparity."""
    h, w = disp.shape
    v = np.arange(h, dtype=np.float64)[:, None]
    line = a * v + b
    with np.errstate(invalid="ignore"):
        on = np.abs(disp - line) <= tol + rel * np.maximum(line, 0.0) + 1e-9
    on &= np.isfinite(disp)
    on[:horizon] = False
    return on.astype(np.uint8)


def close_mask(mask: np.ndarray, radius: int) -> np.ndarray:
    """Closing with a (2r+1)^2 rectangle; OpenCV's default border leaves the border untouched."""
    if radius <= 0:
        return mask.copy()
    k = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * radius + 1, 2 * radius + 1))
    return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, k)


def complete_road(road: np.ndarray, disp: np.ndarray, horizon: int, max_run: int) -> np.ndarray:
    """Rows >= horizon: a NaN run of <= max_run px whose neighbours are road (or road and the image
    border) becomes road. Only NaN pixels change (they are never obstacle candidates)."""
    out = road.copy()
    if max_run <= 0:
        return out
    h, w = disp.shape
    for y in range(max(0, horizon), h):
        bad = np.isnan(disp[y])
        if not bad.any():
            continue
        edges = np.flatnonzero(np.diff(np.concatenate(([0], bad.astype(np.int8), [0]))))
        for x0, x1 in zip(edges[0::2], edges[1::2]):  # [x0, x1) invalid
            if x1 - x0 > max_run:
                continue
            left = bool(road[y, x0 - 1]) if x0 > 0 else None
            right = bool(road[y, x1]) if x1 < w else None
            if left is not False and right is not False and (left or right):
                out[y, x0:x1] = 1
    return out


# ---- (b) sky ----------------------------------------------------------------------------------

def rgb_to_hsv(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """eq. (18)-(21) in float: H [deg, 0..360), S and V [0..100]."""
    x = rgb.astype(np.float64) / 255.0  # eq. (18)
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    cmax, cmin = x.max(-1), x.min(-1)
    delta = cmax - cmin
    safe = np.where(delta > 0, delta, 1.0)
    h = np.where(cmax == r, 60.0 * np.mod((g - b) / safe, 6.0),
                 np.where(cmax == g, 60.0 * ((b - r) / safe + 2.0), 60.0 * ((r - g) / safe + 4.0)))
    h = np.where(delta > 0, h, 0.0)  # eq. (19)
    s = np.where(cmax > 0, delta / np.where(cmax > 0, cmax, 1.0) * 100.0, 0.0)  # eq. (20)
    v = cmax * 100.0  # eq. (21)
    return h, s, v


def textured_mask(rgb: np.ndarray, rows: int, radius: int, max_std: float) -> np.ndarray:
    """Texture (docs/detection.md "(b) Texture", session 8): grey-level (integer luma) standard deviation over the
    (2r+1)^2 window clipped at the border > max_std, then eroded by the same window within rows < rows."""
    hh, ww = rgb.shape[:2]
    out = np.zeros((hh, ww), bool)
    rows = int(np.clip(rows, 0, hh))
    if max_std <= 0 or radius < 1 or rows == 0:
        return out
    r = rgb.astype(np.int64)
    g = ((77 * r[..., 0] + 150 * r[..., 1] + 29 * r[..., 2] + 128) >> 8).astype(np.float64)
    k = (2 * radius + 1, 2 * radius + 1)
    box = lambda a: cv2.boxFilter(a, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)  # noqa: E731
    n = box(np.ones_like(g))
    mean = box(g) / n
    var = box(g * g) / n - mean * mean
    tex = (var > max_std * max_std)[:rows].astype(np.uint8)
    er = cv2.erode(tex, np.ones(k, np.uint8), borderType=cv2.BORDER_CONSTANT, borderValue=1)
    out[:rows] = er > 0
    return out


def sky_mask(rgb: np.ndarray, disp: np.ndarray, rows: int, p: DetectParams) -> np.ndarray:
    h, s, v = rgb_to_hsv(rgb)
    m = np.zeros(h.shape, bool)
    for name in ("blue", "grey", "sunset"):
        g = lambda k: p.values[f"sky_{name}_{k}"]  # noqa: E731
        if not g("enabled"):
            continue
        h0, h1 = g("h_min"), g("h_max")
        hue = (h >= h0) & (h <= h1) if h0 <= h1 else (h >= h0) | (h <= h1)
        m |= hue & (s >= g("s_min")) & (s <= g("s_max")) & (v >= g("v_min")) & (v <= g("v_max"))
    if p.sky_max_disparity_px > 0:
        with np.errstate(invalid="ignore"):
            m &= ~(np.isfinite(disp) & (disp > p.sky_max_disparity_px))
    m &= ~textured_mask(rgb, rows, int(getattr(p, "sky_texture_radius", 2)), float(getattr(p, "sky_max_texture", 0.0)))
    m[max(0, rows):] = False
    return m.astype(np.uint8)


# ---- (c) k-means ------------------------------------------------------------------------------

def kmeans_1d(values: np.ndarray, k: int, max_it: int, merge_px: float) -> tuple[list[float], np.ndarray]:
    """Lloyd in float with quantile init; returns centres nearest first and each value's cluster."""
    if len(values) == 0:
        return [], np.zeros(0, np.int64)
    srt = np.sort(values)
    n = len(values)
    c = np.array([srt[(n * (2 * i + 1)) // (2 * k)] for i in range(k)], np.float64)
    for _ in range(max_it):
        a = np.argmin(np.abs(values[:, None] - c[None, :]), axis=1)  # first minimum = lower index
        new = c.copy()
        for i in range(k):
            sel = values[a == i]
            if len(sel):
                new[i] = sel.mean()
        if np.allclose(new, c, atol=1e-12, rtol=0):
            break
        c = new
    a = np.argmin(np.abs(values[:, None] - c[None, :]), axis=1)
    counts = np.bincount(a, minlength=k)
    order = [i for i in np.argsort(-c, kind="stable") if counts[i] > 0]
    groups: list[list[int]] = []
    prev = None
    for i in order:
        if not groups or merge_px <= 0 or prev - c[i] >= merge_px:
            groups.append([])
        groups[-1].append(int(i))
        prev = c[i]
    remap = np.full(k, -1, np.int64)
    centres = []
    for gi, g in enumerate(groups):
        remap[g] = gi
        centres.append(float(np.sum(c[g] * counts[g]) / np.sum(counts[g])))
    return centres, remap[a]


# ---- (d) u-disparity --------------------------------------------------------------------------

def u_disparity_filter(disp: np.ndarray, labels: np.ndarray, clusters: int, bins: int, p: DetectParams) -> np.ndarray:
    h, w = disp.shape
    kept = np.zeros((h, w), np.uint8)
    t = int(p.udisp_d_tolerance_px)
    for c in range(clusters):
        ys, xs = np.nonzero(labels == c)
        ds = disp_bin(disp[ys, xs])
        u = np.zeros((bins, w), np.int64)  # eq. (25)
        np.add.at(u, (ds, xs), 1)
        padded = np.pad(u, ((t, t), (0, 0)))
        support = sum(padded[i:i + bins] for i in range(2 * t + 1))
        ok = (u > 0) & (support >= p.udisp_min_height_px)
        cells = np.zeros_like(ok)
        for d in np.nonzero(ok.any(axis=1))[0]:
            row = np.concatenate([[0], ok[d].astype(np.int8), [0]])
            starts, ends = np.nonzero(np.diff(row) == 1)[0], np.nonzero(np.diff(row) == -1)[0]
            for s, e in zip(starts, ends):
                if e - s >= p.udisp_min_run_px:
                    cells[d, s:e] = True
        kept[ys, xs] = cells[ds, xs]
    return kept


# ---- (e) components and distance -------------------------------------------------------------

def components(mask: np.ndarray, disp: np.ndarray, max_step_px: float, rel_step: float = 0.0,
               min_step_px: float = 0.0) -> tuple[np.ndarray, int]:
    """8-connected components; neighbours join when |d1 - d2| <= max_step_px and, with rel_step > 0,
    also <= max(min_step_px, rel_step * max(d1, d2)) (relative step, docs/detection.md "(e)")."""
    h, w = mask.shape
    lab = np.zeros((h, w), np.int32)
    n = 0
    for y0, x0 in zip(*np.nonzero(mask)):
        if lab[y0, x0]:
            continue
        n += 1
        lab[y0, x0] = n
        q = deque([(y0, x0)])
        while q:
            y, x = q.popleft()
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < h and 0 <= xx < w and mask[yy, xx] and not lab[yy, xx] \
                            and abs(disp[yy, xx] - disp[y, x]) <= max_step_px + 1e-9 \
                            and (rel_step <= 0 or abs(disp[yy, xx] - disp[y, x]) <= min_step_px + 1e-9
                                 or abs(disp[yy, xx] - disp[y, x]) <= rel_step * max(disp[yy, xx], disp[y, x]) + 1e-9):
                        lab[yy, xx] = n
                        q.append((yy, xx))
    return lab, n


def fill_holes(disp: np.ndarray, max_run: int, left_border: bool = True) -> np.ndarray:
    """Row-wise background interpolation: a NaN run of <= max_run px takes the smaller of its two
    bounding disparities (its one neighbour at the right border, and at the left border only with
    ``left_border``); longer runs stay NaN."""
    out = disp.copy()
    if max_run <= 0:
        return out
    h, w = disp.shape
    for y in range(h):
        bad = np.isnan(disp[y])
        if not bad.any():
            continue
        edges = np.flatnonzero(np.diff(np.concatenate(([0], bad.astype(np.int8), [0]))))
        for x0, x1 in zip(edges[0::2], edges[1::2]):  # [x0, x1) invalid
            if x1 - x0 > max_run or (x0 == 0 and not left_border):
                continue
            nb = [disp[y, x0 - 1]] if x0 > 0 else []
            nb += [disp[y, x1]] if x1 < w else []
            if nb:
                out[y, x0:x1] = min(nb)
    return out


class _Joins:
    """Union of groups by label with the smaller label as root, as in the firmware's merge passes."""

    def __init__(self, labels) -> None:
        self.root = {int(c): int(c) for c in labels}

    def find(self, c: int) -> int:
        while self.root[c] != c:
            c = self.root[c]
        return c

    def join(self, a: int, b: int) -> None:
        r1, r2 = self.find(a), self.find(b)
        if r1 != r2:
            self.root[max(r1, r2)] = min(r1, r2)

    def relabel(self, roots: np.ndarray, n: int, dropped: frozenset | set = frozenset()) -> np.ndarray:
        """roots (component -> group) with every group replaced by its joined root (0 if dropped)."""
        out = np.array(roots).copy()
        for c in range(1, n + 1):
            if out[c] in self.root:
                r = self.find(int(out[c]))
                out[c] = 0 if r in dropped else r
        return out


def _group_stats(comp: np.ndarray, disp: np.ndarray, roots: np.ndarray):
    """Group image (component labels mapped through roots) and per group: box (x0, y0, x1, y1),
    median disparity, pixel count."""
    g = roots[comp] * (comp > 0)
    box, med, cnt = {}, {}, {}
    for c in np.unique(g[g > 0]):
        c = int(c)
        ys, xs = np.nonzero(g == c)
        box[c] = (xs.min(), ys.min(), xs.max(), ys.max())
        med[c] = float(np.median(disp[ys, xs]))
        cnt[c] = len(xs)
    return g, box, med, cnt


def merge_fragments(comp: np.ndarray, disp: np.ndarray, n: int, gap: int, rel: float, group_rel: float = 0.0,
                    attach: bool = False, gap_vertical: int = 0, bridge_px: int = 0,
                    bridge_overlap: float = 1.0) -> np.ndarray:
    """Component -> group root (smallest label): boxes grown by `gap` (in y by max(gap, gap_vertical),
    session 9) overlap and the medians differ
    by <= rel of the larger (the firmware uses the lower median of Q4 values). group_rel <= 0: single
    linkage. group_rel > 0 (session 8): complete linkage, closest pairs first, two groups join only when all
    their members' medians span <= group_rel of the largest; then, with `attach`, each group joins the
    touching larger group (more pixels) whose group median is nearest within rel (no chains: a group that
    joins is no target). bridge_px > 0 with single linkage (session 10): components with fewer pixels
    ("small") link among themselves, the large ones among themselves; each small group then joins its anchor
    (the large component of its closest pair) and every other large component it pairs with whose median is
    within rel of the anchor's or whose box shares more than bridge_overlap of the narrower one's columns."""
    joins = _Joins(range(n + 1))
    if gap < 0 or rel <= 0:
        return np.arange(n + 1)
    box, med = {}, {}
    for c in range(1, n + 1):
        ys, xs = np.nonzero(comp == c)
        if len(xs):
            box[c] = (xs.min(), ys.min(), xs.max(), ys.max())
            med[c] = float(np.median(disp[ys, xs]))

    gv = max(gap, gap_vertical)

    def touch(a, b, gy=gv):
        return not (b[0] > a[2] + gap or a[0] > b[2] + gap or b[1] > a[3] + gy or a[1] > b[3] + gy)

    cs = sorted(box)
    pairs = []
    for i, c1 in enumerate(cs):
        for c2 in cs[i + 1:]:
            if not touch(box[c1], box[c2]):
                continue
            if abs(med[c1] - med[c2]) > rel * max(med[c1], med[c2]) + 1e-9:
                continue
            if group_rel <= 0 and bridge_px <= 0:
                joins.join(c1, c2)
            else:
                pairs.append((abs(med[c1] - med[c2]) / max(med[c1], med[c2], 1e-9), c1, c2))
    if group_rel <= 0 and bridge_px > 0:
        size = {c: int((comp == c).sum()) for c in cs}
        big = {c: size[c] >= bridge_px for c in cs}
        for _, c1, c2 in pairs:
            if big[c1] == big[c2]:
                joins.join(c1, c2)
        anchor = {}
        for f, c1, c2 in pairs:
            if big[c1] != big[c2]:
                rs, cb = joins.find(c2 if big[c1] else c1), (c1 if big[c1] else c2)
                if rs not in anchor or (f, cb) < anchor[rs]:
                    anchor[rs] = (f, cb)
        todo = []
        for _, c1, c2 in pairs:
            if big[c1] != big[c2]:
                rs, cb = joins.find(c2 if big[c1] else c1), (c1 if big[c1] else c2)
                ca = anchor[rs][1]
                a, b = box[ca], box[cb]
                ov = min(a[2], b[2]) - max(a[0], b[0]) + 1
                side = ov <= bridge_overlap * (min(a[2] - a[0], b[2] - b[0]) + 1)
                if not side or abs(med[ca] - med[cb]) <= rel * max(med[ca], med[cb]) + 1e-9:
                    todo.append((rs, cb))
        for rs, cb in todo:
            joins.join(rs, cb)
        return np.array([joins.find(c) for c in range(n + 1)])
    if group_rel <= 0:
        return np.array([joins.find(c) for c in range(n + 1)])
    lo = dict(med)
    hi = dict(med)
    for _, c1, c2 in sorted(pairs):
        r1, r2 = joins.find(c1), joins.find(c2)
        if r1 == r2:
            continue
        glo, ghi = min(lo[r1], lo[r2]), max(hi[r1], hi[r2])
        if ghi - glo > group_rel * ghi + 1e-9:
            continue
        joins.join(r1, r2)
        r = joins.find(r1)
        lo[r], hi[r] = glo, ghi
    roots = np.array([joins.find(c) for c in range(n + 1)])
    if not attach:
        return roots
    _, gbox, gmed, gcnt = _group_stats(comp, disp, roots)
    target = {}
    for g1 in gbox:
        best = None
        for g2 in gbox:
            if g2 == g1 or gcnt[g2] <= gcnt[g1] or not touch(gbox[g1], gbox[g2], gap):  # attach: merge_gap_px both ways
                continue
            if abs(gmed[g1] - gmed[g2]) > rel * max(gmed[g1], gmed[g2]) + 1e-9:
                continue
            key = (abs(gmed[g2] - gmed[g1]), -gcnt[g2], g2)
            if best is None or key < best[0]:
                best = (key, g2)
        if best is not None:
            target[g1] = best[1]
    move = {g: t for g, t in target.items() if t not in target}
    return np.array([move.get(int(r), int(r)) for r in roots])


def bimodal_threshold(v: np.ndarray, min_px: int, min_rel: float, max_valley: float) -> float | None:
    """Otsu's threshold over the component's disparities (class 0: d < t, t between two distinct
    values) when both classes have >= min_px pixels, their lower medians differ by >= min_rel of the
    larger and the middle half between them holds <= max_valley of the pixels; else None."""
    v = np.sort(v.astype(np.float64))
    n = len(v)
    if n < 2 * min_px or n == 0 or v[0] == v[-1]:
        return None
    cut = np.flatnonzero(np.diff(v) > 0) + 1  # class 0 = v[:k]
    cut = cut[(cut >= min_px) & (n - cut >= min_px)]
    if not len(cut):
        return None
    cs = np.cumsum(v)
    n0 = cut.astype(np.float64)
    mu0 = cs[cut - 1] / n0
    mu1 = (cs[-1] - cs[cut - 1]) / (n - n0)
    k = int(cut[int(np.argmax(n0 * (n - n0) * (mu0 - mu1) ** 2))])
    m0, m1 = v[(k - 1) // 2], v[k + (n - k - 1) // 2]
    if m1 - m0 < min_rel * m1 - 1e-9:
        return None
    g = (m1 - m0) / 4
    if np.count_nonzero((v >= m0 + g - 1e-9) & (v <= m1 - g + 1e-9)) > max_valley * n + 1e-9:
        return None
    return float(v[k])


def renumber_raster(key: np.ndarray) -> tuple[np.ndarray, int]:
    """Non-zero keys renumbered 1..m in raster order of their first pixel (0 stays 0), as the firmware."""
    flat = key.ravel()
    nz = np.flatnonzero(flat)
    values, first = np.unique(flat[nz], return_index=True)
    rank = np.empty(len(values), np.int32)
    rank[np.argsort(first, kind="stable")] = np.arange(1, len(values) + 1, dtype=np.int32)
    out = np.zeros(flat.shape, np.int32)
    out[nz] = rank[np.searchsorted(values, flat[nz])]
    return out.reshape(key.shape), len(values)


def relabel_keys(key: np.ndarray) -> tuple[np.ndarray, int]:
    """8-connected components of equal non-zero keys, numbered 1..m in raster order of their first pixel
    (as the firmware's relabel_keys)."""
    out = np.zeros(key.shape, np.int32)
    m = 0
    for k in np.unique(key[key > 0]):
        nk, lk = cv2.connectedComponents((key == k).astype(np.uint8), connectivity=8)
        for j in range(1, nk):
            m += 1
            out[lk == j] = m
    return renumber_raster(out)


def split_bimodal(comp: np.ndarray, n: int, disp: np.ndarray, min_px: int, min_rel: float, max_valley: float,
                  rounds: int) -> tuple[np.ndarray, int]:
    """Components with two disparity modes are cut at the threshold; pixels relabelled by 8-connected
    components of (label, side) (docs/detection.md "(e) Splitting"); `rounds` passes."""
    for _ in range(rounds if min_rel > 0 else 0):
        side = np.zeros(comp.shape, np.int64)
        any_split = False
        for c in range(1, n + 1):
            sel = comp == c
            if not sel.any():
                continue
            t = bimodal_threshold(disp[sel], min_px, min_rel, max_valley)
            if t is not None:
                any_split = True
                side[sel & (disp >= t - 1e-9)] = 1
        if not any_split:
            break
        comp, n = relabel_keys(np.where(comp > 0, 2 * comp.astype(np.int64) + side, 0))
    return comp, n


def merge_edges(comp: np.ndarray, disp: np.ndarray, n: int, roots: np.ndarray, gap: int, rel: float,
                columns: int) -> np.ndarray:
    """Groups side by side (gap <= max(gap, 0), boxes overlapping by <= `columns`, rows overlapping by half
    the lower box) whose facing edges (median disparity of their `columns` outermost columns) differ by
    <= rel of the larger join: a slanted surface cut where two k-means clusters meet (docs/detection.md
    "(e) Edge continuity")."""
    if rel <= 0 or columns <= 0:
        return roots
    g, box, _, _ = _group_stats(comp, disp, roots)
    joins = _Joins(box)
    lm, rm = {}, {}
    for c in box:
        ys, xs = np.nonzero(g == c)
        lm[c] = float(np.median(disp[ys[xs < xs.min() + columns], xs[xs < xs.min() + columns]]))
        rm[c] = float(np.median(disp[ys[xs > xs.max() - columns], xs[xs > xs.max() - columns]]))
    gap = max(gap, 0)
    for c1 in sorted(box):
        a = box[c1]
        for c2 in sorted(box):
            b = box[c2]
            if c2 == c1 or b[2] <= a[2]:
                continue
            gw = b[0] - a[2] - 1
            if gw > gap or gw < -columns:
                continue
            ov = min(a[3], b[3]) - max(a[1], b[1]) + 1
            if 2 * ov < min(a[3] - a[1] + 1, b[3] - b[1] + 1):
                continue
            if abs(rm[c1] - lm[c2]) > rel * max(rm[c1], lm[c2]) + 1e-9:
                continue
            joins.join(c1, c2)
    return joins.relabel(roots, n)


def merge_occluded(comp: np.ndarray, disp: np.ndarray, n: int, roots: np.ndarray, gap: int, rel: float,
                   max_gap: int, min_area: int) -> np.ndarray:
    """Groups (after merge_fragments) at the same depth (medians within rel) with the same top and
    bottom rows (within 1/20 of the taller height + 2 px), whose horizontal gap (gap < g <= max_gap) is
    covered by nearer groups' boxes (median > (1 + rel) * the larger, >= min_area px, overlapping the
    common rows) up to `gap` open columns, join (docs/detection.md "(e) Occlusion merging")."""
    if max_gap <= 0 or rel <= 0:
        return roots
    _, box, med, cnt = _group_stats(comp, disp, roots)
    joins = _Joins(box)
    gap = max(gap, 0)
    for c1 in sorted(box):
        a = box[c1]
        for c2 in sorted(box):
            b = box[c2]
            if c2 == c1 or b[0] <= a[2]:
                continue
            gw = b[0] - a[2] - 1
            if gw <= gap or gw > max_gap or abs(med[c1] - med[c2]) > rel * max(med[c1], med[c2]) + 1e-9:
                continue
            tol = max(a[3] - a[1] + 1, b[3] - b[1] + 1) // 20 + 2
            if abs(a[1] - b[1]) > tol or abs(a[3] - b[3]) > tol or joins.find(c1) == joins.find(c2):
                continue
            ry0, ry1 = max(a[1], b[1]), min(a[3], b[3])
            cover = np.zeros(gw, bool)
            for c3, o in box.items():
                if cnt[c3] >= min_area and med[c3] > max(med[c1], med[c2]) * (1 + rel) and o[3] >= ry0 and o[1] <= ry1:
                    lo, hi = max(o[0], a[2] + 1), min(o[2], b[0] - 1)
                    if hi >= lo:
                        cover[lo - a[2] - 1:hi - a[2]] = True
            if np.count_nonzero(~cover) > gap:
                continue
            joins.join(c1, c2)
    return joins.relabel(roots, n)


def resolve_contained(comp: np.ndarray, disp: np.ndarray, n: int, roots: np.ndarray, min_inside: float,
                      merge_rel: float, drop_max_px: int, nearer_only: bool, min_area: int,
                      surround: str = "opposite") -> np.ndarray:
    """Groups (after the merging) whose box lies >= min_inside inside the box of a larger group (more
    pixels, >= min_area; the one with the most pixels, ties: lowest label) join it when the medians differ
    by <= merge_rel of the larger, else are dropped (root 0) when smaller than drop_max_px pixels (and,
    with nearer_only, nearer than it). Decisions on the groups before the pass (docs/detection.md "(e)
    Contained groups"). surround: where the larger group must have pixels: "opposite" = left and right of
    the box within its rows, or above and below within its columns; "all" = all four; "off" = none."""
    if min_inside <= 0:
        return roots
    g, box, med, cnt = _group_stats(comp, disp, roots)
    host = {}
    for c1 in sorted(box):
        a = box[c1]
        area = (a[2] - a[0] + 1) * (a[3] - a[1] + 1)
        best = 0
        for c2 in sorted(box):
            b = box[c2]
            if c2 == c1 or cnt[c2] <= cnt[c1] or cnt[c2] < min_area or (best and cnt[c2] <= cnt[best]):
                continue
            iw = min(a[2], b[2]) - max(a[0], b[0]) + 1
            ih = min(a[3], b[3]) - max(a[1], b[1]) + 1
            if iw > 0 and ih > 0 and iw * ih >= min_inside * area:
                best = c2
        if best and surround != "off":
            b = box[best]
            on = g == best
            lr = on[a[1]:a[3] + 1, b[0]:a[0]].any() and on[a[1]:a[3] + 1, a[2] + 1:b[2] + 1].any()
            ud = on[b[1]:a[1], a[0]:a[2] + 1].any() and on[a[3] + 1:b[3] + 1, a[0]:a[2] + 1].any()
            best = best if ((lr and ud) if surround == "all" else (lr or ud)) else 0
        if best:
            host[c1] = best
    joins = _Joins(box)
    drop = []
    for c1, c2 in host.items():
        if abs(med[c1] - med[c2]) <= merge_rel * max(med[c1], med[c2]) + 1e-9:
            joins.join(c1, c2)
        elif cnt[c1] < drop_max_px and (not nearer_only or med[c1] > med[c2]):
            drop.append(c1)
    return joins.relabel(roots, n, {joins.find(c) for c in drop})


def extend_to_ground(obstacles: list, a: float, b: float, horizon: int, h: int, p: DetectParams) -> None:
    """Box extent, ground contact (docs/detection.md "(e) Box extent"): a box whose next row below has a
    road line value within the road band (+ foot_slack_px) below the obstacle's disparity ends at the
    last row where the line is still below that disparity (the last row if it never does)."""
    if not p.foot_extend:
        return
    for o in obstacles:
        x0, y0, x1, y1 = o.box
        below = y1 + 1
        if below >= h or below < horizon or (y1 >= horizon and a * y1 + b >= o.disparity_px):
            continue
        line = a * below + b
        if line < o.disparity_px - (p.road_tolerance_px + p.road_tolerance_rel * max(line, 0.0)) - p.foot_slack_px - 1e-9:
            continue
        foot = y1  # the last row where the line is still below d: the obstacle's lowest row
        while foot + 1 < h and a * (foot + 1) + b < o.disparity_px:
            foot += 1
        o.box = (x0, y0, x1, max(y1, foot))


def trim_sparse_columns(obstacles: list, ol: np.ndarray, calib: dict, p: DetectParams,
                        sky: np.ndarray | None = None, disp: np.ndarray | None = None) -> None:
    """Box extent, sparse and low sides: the outermost columns of each box holding fewer of the obstacle's
    pixels (ol == id + 1) than trim_col_min_share of its fullest column, or whose top (highest own pixel,
    or sky pixel within max(cc_min_step_px, cc_max_rel_step * d) of the obstacle's disparity) lies below
    y0 + trim_col_top_share * height, are cut; the cut pixels leave ol, box rows, pixel count and lateral X
    follow (distance unchanged)."""
    if p.trim_col_min_share <= 0 and p.trim_col_top_share <= 0:
        return
    for o in obstacles:
        x0, y0, x1, y1 = o.box
        on = ol[y0:y1 + 1, x0:x1 + 1] == o.id + 1
        cols = on.sum(axis=0)
        bad = cols < p.trim_col_min_share * cols.max()
        if p.trim_col_top_share > 0:
            top_on = on.copy()
            if sky is not None and disp is not None:
                tol = max(p.cc_min_step_px, p.cc_max_rel_step * o.disparity_px)
                with np.errstate(invalid="ignore"):
                    top_on |= (sky[y0:y1 + 1, x0:x1 + 1] > 0) & (np.abs(disp[y0:y1 + 1, x0:x1 + 1] - o.disparity_px) <= tol + 1e-9)
            tops = np.where(top_on.any(axis=0), top_on.argmax(axis=0), y1 - y0 + 1) + y0
            bad |= tops > y0 + p.trim_col_top_share * (y1 - y0 + 1)
        a, b = 0, len(cols) - 1
        while a < b and bad[a]:
            a += 1
        while b > a and bad[b]:
            b -= 1
        if a == 0 and b == len(cols) - 1:
            continue
        sub = ol[y0:y1 + 1, x0:x1 + 1]
        cut = on.copy()
        cut[:, a:b + 1] = False
        sub[cut] = 0
        ys, xs = np.nonzero(sub == o.id + 1)
        o.box = (x0 + a, y0 + int(ys.min()), x0 + b, y0 + int(ys.max()))
        o.pixel_count = len(xs)
        o.lateral_m = (0.5 * (o.box[0] + o.box[2]) - calib["cx"]) * o.distance_m / calib["focal_px"]


def drop_below_road(obstacles: list, ol: np.ndarray, a: float, b: float, horizon: int, p: DetectParams) -> list:
    """Below the road (docs/detection.md "(e) Below the road"): an obstacle with >= below_road_drop_share of
    its pixels in rows v >= horizon where the road line a*v + b exceeds its disparity by more than the road
    band (road_tolerance_px + road_tolerance_rel * line) is dropped; the rest are renumbered (ids, ol)."""
    if p.below_road_drop_share <= 0 or not obstacles:
        return obstacles
    h = ol.shape[0]
    v = np.arange(h, dtype=np.float64)
    line = a * v + b
    band = p.road_tolerance_px + p.road_tolerance_rel * np.maximum(line, 0.0)

    def keep(o) -> bool:
        ys, _ = np.nonzero(ol == o.id + 1)
        below = (ys >= horizon) & (line[ys] - o.disparity_px > band[ys] + 1e-9)
        return not (len(ys) and below.sum() >= p.below_road_drop_share * len(ys))

    return _keep_renumbered(obstacles, ol, keep)


def _keep_renumbered(obstacles: list, ol: np.ndarray, keep) -> list:
    """The obstacles for which keep(o) holds (decided on the labels as they are), renumbered 0..n-1 in
    order, with the label image ol (0 = none, id + 1) renumbered alike."""
    decided = [bool(keep(o)) for o in obstacles]
    kept = []
    remap = np.zeros(len(obstacles) + 1, np.int32)
    for o, k in zip(obstacles, decided):
        if not k:
            continue
        kept.append(o)
        remap[o.id + 1] = len(kept)
        o.id = len(kept) - 1
    ol[:] = remap[ol]
    return kept


def drop_seen_through(obstacles: list, ol: np.ndarray, p: DetectParams) -> list:
    """Seen through (docs/detection.md "(e) Seen through", session 8): an obstacle F is dropped when, for one
    nearer obstacle H (disparity > F's * (1 + merge_max_rel_disparity)), the columns where H has pixels above
    F's highest and below F's lowest pixel there hold >= seen_through_drop_share of F's pixels; the rest are
    renumbered (ids, ol)."""
    share = float(getattr(p, "seen_through_drop_share", 0.0))
    if share <= 0 or len(obstacles) < 2:
        return obstacles
    w = ol.shape[1]
    ext = {}
    for o in obstacles:
        ys, xs = np.nonzero(ol == o.id + 1)
        top = np.full(w, np.inf)
        bot = np.full(w, -np.inf)
        cnt = np.bincount(xs, minlength=w)
        np.minimum.at(top, xs, ys)
        np.maximum.at(bot, xs, ys)
        ext[o.id] = (top, bot, cnt)
    drop = set()
    for f in obstacles:
        tf, bf, cf = ext[f.id]
        for g in obstacles:
            if g.id == f.id or g.disparity_px <= f.disparity_px * (1.0 + p.merge_max_rel_disparity) + 1e-9:
                continue
            tg, bg, cg = ext[g.id]
            enclosed = (cf > 0) & (cg > 0) & (tg < tf) & (bg > bf)
            if cf[enclosed].sum() >= share * cf.sum() and cf.sum() > 0:
                drop.add(f.id)
                break
    return _keep_renumbered(obstacles, ol, lambda o: o.id not in drop)


def drop_inside_nearer(obstacles: list, ol: np.ndarray, p: DetectParams) -> list:
    """Inside a nearer face (docs/detection.md "(e) Inside a nearer face", session 14): an obstacle F is dropped
    when one obstacle H with more pixels and disparity > F's * (1 + merge_max_rel_disparity) has a box holding
    >= inside_drop_min_share of F's box area and the band of inside_drop_ring_px pixels around F's box (clipped
    to the image) holds >= inside_drop_min_ring of H's pixels; the rest are renumbered (ids, ol)."""
    share = float(getattr(p, "inside_drop_min_share", 0.0))
    if share <= 0 or len(obstacles) < 2:
        return obstacles
    ring = float(getattr(p, "inside_drop_min_ring", 0.0))
    m = max(0, int(getattr(p, "inside_drop_ring_px", 0)))
    h, w = ol.shape
    drop = set()
    for f in obstacles:
        fx0, fy0, fx1, fy1 = f.box
        area = (fx1 - fx0 + 1) * (fy1 - fy0 + 1)
        for g in obstacles:
            if g.id == f.id or g.pixel_count <= f.pixel_count or \
                    g.disparity_px <= f.disparity_px * (1.0 + p.merge_max_rel_disparity) + 1e-9:
                continue
            gx0, gy0, gx1, gy1 = g.box
            iw = min(fx1, gx1) - max(fx0, gx0) + 1
            ih = min(fy1, gy1) - max(fy0, gy0) + 1
            if iw <= 0 or ih <= 0 or iw * ih < share * area:
                continue
            bx0, by0, bx1, by1 = max(0, fx0 - m), max(0, fy0 - m), min(w - 1, fx1 + m), min(h - 1, fy1 + m)
            win = ol[by0:by1 + 1, bx0:bx1 + 1] == g.id + 1
            band = win.size - area  # F's box lies inside the clipped window
            of_g = int(win.sum()) - int(win[fy0 - by0:fy1 - by0 + 1, fx0 - bx0:fx1 - bx0 + 1].sum())
            if band > 0 and of_g >= ring * band:
                drop.add(f.id)
                break
    return _keep_renumbered(obstacles, ol, lambda o: o.id not in drop)


def merge_side_faces(obstacles: list, ol: np.ndarray, p: DetectParams) -> list:
    """Side faces (docs/detection.md "(e) Side faces", session 33): a narrow obstacle F (box width <=
    side_face_max_width of H's) beside a larger one H (more pixels), farther by at most side_face_max_rel
    (d_H <= d_F * (1 + rel), d_F < d_H), >= side_face_min_rows of F's box rows within H's rows, the boxes at most
    side_face_max_gap_px columns apart (overlaps allowed) and F's centre column outside H's box, joins H (the host
    with the most pixels): H takes the union of the boxes, F's pixels and labels and keeps its distance. No chains
    (a host that is itself a face keeps its faces apart); the rest are renumbered (ids, ol)."""
    rel = float(getattr(p, "side_face_max_rel", 0.0))
    if rel <= 0 or len(obstacles) < 2:
        return obstacles
    width = float(p.side_face_max_width)
    rows_share = float(p.side_face_min_rows)
    max_gap = int(p.side_face_max_gap_px)
    host = {}
    for f in obstacles:
        fx0, fy0, fx1, fy1 = f.box
        best = None
        for g in obstacles:
            if g.id == f.id or g.pixel_count <= f.pixel_count or f.disparity_px <= 0:
                continue
            if best is not None and g.pixel_count <= best.pixel_count:
                continue
            if f.disparity_px >= g.disparity_px or g.disparity_px > f.disparity_px * (1.0 + rel) + 1e-9:
                continue
            gx0, gy0, gx1, gy1 = g.box
            if fx1 - fx0 + 1 > width * (gx1 - gx0 + 1) + 1e-9:
                continue
            if min(fy1, gy1) - max(fy0, gy0) + 1 < rows_share * (fy1 - fy0 + 1) - 1e-9:
                continue
            gap = max(fx0, gx0) - min(fx1, gx1) - 1
            if gap > max_gap or 2 * gx0 <= fx0 + fx1 <= 2 * gx1:
                continue
            best = g
        if best is not None:
            host[f.id] = best
    joined = set()
    for fid, g in host.items():
        if g.id in host:
            continue  # no chains
        f = obstacles[fid]
        g.box = (min(g.box[0], f.box[0]), min(g.box[1], f.box[1]), max(g.box[2], f.box[2]), max(g.box[3], f.box[3]))
        g.pixel_count += f.pixel_count
        ol[ol == fid + 1] = g.id + 1
        joined.add(fid)
    return _keep_renumbered(obstacles, ol, lambda o: o.id not in joined)


def extend_over_gap(obstacles: list, ol: np.ndarray, a: float, b: float, horizon: int, h: int, p: DetectParams) -> None:
    """Ground contact over a gap (docs/detection.md "(e) Box extent", session 14): a box whose bottom lies above
    its foot row (the last row from its bottom on whose road line a*v + b is still below the obstacle's disparity;
    rows above the horizon have no line value) ends at the foot row when at most foot_gap_max_occluded of the gap
    (the box's columns, the rows below it to the foot) carries the label of an obstacle nearer by more than
    merge_max_rel_disparity."""
    if not bool(getattr(p, "foot_gap_extend", False)):
        return
    max_occ = float(getattr(p, "foot_gap_max_occluded", 0.0))
    for o in obstacles:
        x0, y0, x1, y1 = o.box
        foot = y1
        while foot + 1 < h and (foot + 1 < horizon or a * (foot + 1) + b < o.disparity_px):
            foot += 1
        if foot <= y1:
            continue
        nearer = [g.id + 1 for g in obstacles if g.disparity_px > o.disparity_px * (1.0 + p.merge_max_rel_disparity) + 1e-9]
        gap = ol[y1 + 1:foot + 1, x0:x1 + 1]
        occluded = int(np.isin(gap, nearer).sum()) if nearer else 0
        if occluded <= max_occ * gap.size:
            o.box = (x0, y0, x1, foot)


def measure_obstacles(comp: np.ndarray, n: int, disp: np.ndarray, calib: dict, p: DetectParams) -> tuple[list, np.ndarray]:
    """Fragment merging, edge continuity, occlusion merging, contained groups, then box, median disparity,
    Z, X and class per group (filters: area, range, height, physical area); nearest first, and the obstacle
    label image (0 none, id + 1)."""
    roots = merge_fragments(comp, disp, n, int(p.merge_gap_px), float(p.merge_max_rel_disparity),
                            float(getattr(p, "merge_group_max_rel", 0.0)), bool(getattr(p, "merge_attach", False)),
                            int(getattr(p, "merge_gap_vertical_px", 0)), int(getattr(p, "merge_bridge_max_px", 0)),
                            float(getattr(p, "merge_bridge_max_overlap", 1.0)))
    roots = merge_edges(comp, disp, n, roots, int(p.merge_gap_px), float(p.merge_edge_rel_disparity),
                        int(p.merge_edge_columns))
    roots = merge_occluded(comp, disp, n, roots, int(p.merge_gap_px), float(p.merge_max_rel_disparity),
                           int(p.merge_occluded_max_gap_px), int(p.min_area_px))
    roots = resolve_contained(comp, disp, n, roots, float(p.contain_min_inside), float(p.contain_merge_rel_disparity),
                              int(p.contain_drop_max_px), bool(p.contain_drop_nearer_only), int(p.min_area_px),
                              str(p.contain_surround))
    comp = roots[comp] * (comp > 0)
    obstacles = []
    comp_ids = []
    for c in range(1, n + 1):
        ys, xs = np.nonzero(comp == c)
        if len(xs) < p.min_area_px:
            continue
        d = max(float(np.median(disp[ys, xs])), 1.0 / 16)
        z = calib["focal_px"] * calib["baseline_m"] / d
        if p.max_distance_m > 0 and z > p.max_distance_m:
            continue  # range, docs/detection.md "(e)"
        if (ys.max() - ys.min() + 1) * z / calib["focal_px"] < p.min_height_m:
            continue
        if p.min_area_m2 > 0 and len(xs) * (z / calib["focal_px"]) ** 2 < p.min_area_m2:
            continue  # physical area (pixels * (Z/f)^2), docs/detection.md "(e)"
        x0, x1 = int(xs.min()), int(xs.max())
        cls = "near" if z < p.near_m else "far" if z >= p.far_m else "mid"
        obstacles.append(Obstacle(0, (x0, int(ys.min()), x1, int(ys.max())), len(xs), d, z,
                                  (0.5 * (x0 + x1) - calib["cx"]) * z / calib["focal_px"], cls))
        comp_ids.append(c)
    order = sorted(range(len(obstacles)), key=lambda i: -obstacles[i].disparity_px)
    ol = np.zeros(comp.shape, np.int32)
    out = []
    for rank, i in enumerate(order):
        o = obstacles[i]
        o.id = rank
        ol[comp == comp_ids[i]] = rank + 1
        out.append(o)
    return out, ol


def split_necks(comp: np.ndarray, n: int, min_width: int, max_share: float, min_px: int,
                foot_share: float = 0.0) -> tuple[np.ndarray, int]:
    """Per label, the pixel count of each column of its box; a run of >= min_width columns each holding
    <= max_share of the label's 75th-percentile (lower) column count, with >= min_px pixels and a wider
    column on each side, is dropped (with foot_share > 0 only when every column's topmost pixel lies in the
    lowest foot_share of the box rows). Each part of a cut label between the runs becomes one label (not
    necessarily connected), other labels stay whole; renumbered in raster order of first appearance
    (docs/detection.md "(e) Necks")."""
    if min_width <= 0 or n <= 0:
        return comp, n
    key = comp.astype(np.int64) * (comp.shape[1] + 2)  # (label, piece) keys; piece 0 for an uncut label
    cut_any = False
    for c in range(1, n + 1):
        ys, xs = np.nonzero(comp == c)
        if len(xs) == 0:
            continue
        x0, x1, y0, y1 = xs.min(), xs.max(), ys.min(), ys.max()
        nc = x1 - x0 + 1
        if nc < min_width + 2:
            continue
        cols = np.bincount(xs - x0, minlength=nc)
        top = np.full(nc, 1 << 30)
        np.minimum.at(top, xs - x0, ys)
        thin = max_share * float(np.sort(cols)[(3 * (nc - 1)) // 4])
        prefix = np.concatenate([[0], np.cumsum(cols)])
        piece = np.zeros(nc, np.int64)  # piece index per column, -1 = cut
        i = 0
        while i < nc:
            if cols[i] > thin:
                i += 1
                continue
            j = i
            while j < nc and cols[j] <= thin:
                j += 1
            foot = foot_share <= 0 or bool(np.all(top[i:j] >= y1 - foot_share * (y1 - y0 + 1)))
            if j - i >= min_width and i > 0 and j < nc and prefix[i] >= min_px and prefix[nc] - prefix[j] >= min_px and foot:
                piece[i:j] = -1
                piece[j:] += 1
                cut_any = True
            i = j
        if (piece != 0).any():
            sel = comp == c
            p = piece[np.clip(np.nonzero(sel)[1] - x0, 0, nc - 1)]
            key[sel] = np.where(p < 0, 0, key[sel] + p + 1)
    if not cut_any:
        return comp, n
    return renumber_raster(key)


def _chroma_q16(n: int, r: int, g: int, b: int) -> tuple[int, int, int]:
    """Regularised chromaticity of pixel sums, Q16: (C + 10 n) << 16 // (R + G + B + 30 n) (as the firmware)."""
    d = r + g + b + 30 * n
    return (((r + 10 * n) << 16) // d, ((g + 10 * n) << 16) // d, ((b + 10 * n) << 16) // d)


def split_seams(lab: np.ndarray, n: int, rgb: np.ndarray | None, min_step: float, window: int, min_width: int,
                min_px: int, max_cuts: int, min_rows: float, drop_share: float = 0.0) -> tuple[np.ndarray, int]:
    """Seams (docs/detection.md "(e) Seams", session 33): per label, the R, G, B sums of each column of its box;
    at each boundary the regularised chromaticity of the label's pixels in `window` columns each side (Q16
    integers, exactly as the firmware); the largest channel step >= min_step, >= min_width columns and
    >= min_px pixels each side and (min_rows > 0) >= min_rows of the rows agreeing (their 3 pixels left of the
    boundary nearer the left window's chromaticity, their 3 right pixels nearer the right's) cuts the label
    there, strongest candidate first (ties: leftmost), breadth first over the parts, <= max_cuts per label.
    Pieces with < drop_share of the label's pixels are dropped; labels renumbered in raster order."""
    if min_step <= 0 or n <= 0 or max_cuts <= 0 or window <= 0 or rgb is None or rgb.shape[:2] != lab.shape:
        return lab, n
    h, w = lab.shape
    threshold = int(np.floor(min_step * 65536.0 + 0.5))
    rgb64 = rgb.astype(np.int64)
    key = np.zeros(lab.shape, np.int64)
    cut_any = False
    stride = w + 2
    for c in range(1, n + 1):
        sel = lab == c
        ys, xs = np.nonzero(sel)
        if len(xs) == 0:
            continue
        x0, x1, y0, y1 = int(xs.min()), int(xs.max()), int(ys.min()), int(ys.max())
        nc = x1 - x0 + 1
        cols = np.zeros((nc, 4), np.int64)  # n, r, g, b per column
        np.add.at(cols[:, 0], xs - x0, 1)
        for k in range(3):
            np.add.at(cols[:, k + 1], xs - x0, rgb64[ys, xs, k])
        pre = np.vstack([np.zeros((1, 4), np.int64), np.cumsum(cols, axis=0)])
        rng = lambda a, b: [int(v) for v in pre[b] - pre[a]]  # noqa: E731
        starts = np.zeros(nc, bool)
        mw = max(1, min_width)

        def rows_agree(i: int, lw: list[int], rw: list[int]) -> float:
            ql, qr = _chroma_q16(*lw), _chroma_q16(*rw)
            d2 = lambda p, q: sum((a - b) ** 2 for a, b in zip(p, q))  # noqa: E731
            xb = x0 + i
            rows = agree = 0
            for y in range(y0, y1 + 1):
                lsel = [x for x in range(max(0, xb - 3), xb) if lab[y, x] == c]
                rsel = [x for x in range(xb, min(w, xb + 3)) if lab[y, x] == c]
                if not lsel or not rsel:
                    continue
                rows += 1
                a = _chroma_q16(len(lsel), *[int(rgb64[y, lsel, k].sum()) for k in range(3)])
                b = _chroma_q16(len(rsel), *[int(rgb64[y, rsel, k].sum()) for k in range(3)])
                agree += int(d2(a, ql) < d2(a, qr) and d2(b, qr) < d2(b, ql))
            return agree / rows if rows else 0.0

        parts, cuts, k = [(0, nc)], 0, 0
        if nc >= 2 * mw:
            while k < len(parts) and cuts < max_cuts:
                a, b = parts[k]
                k += 1
                if b - a < 2 * mw:
                    continue
                cand = []
                for i in range(a + mw, b - mw + 1):
                    if rng(a, i)[0] < min_px or rng(i, b)[0] < min_px:
                        continue
                    lw, rw = rng(i - min(i - a, window), i), rng(i, min(b, i + window))
                    if lw[0] == 0 or rw[0] == 0:
                        continue
                    step = max(abs(p - q) for p, q in zip(_chroma_q16(*lw), _chroma_q16(*rw)))
                    if step >= threshold:
                        cand.append((-step, i))
                for _, i in sorted(cand):
                    lw, rw = rng(i - min(i - a, window), i), rng(i, min(b, i + window))
                    if min_rows <= 0 or rows_agree(i, lw, rw) >= min_rows:
                        starts[i] = True
                        cut_any = True
                        cuts += 1
                        parts += [(a, i), (i, b)]
                        break
        piece = np.maximum.accumulate(np.where(starts, np.arange(nc), 0))  # start column of each column's piece
        kk = c * stride + piece[xs - x0] + 1
        if drop_share > 0:
            total = len(xs)
            vals, counts = np.unique(kk, return_counts=True)
            small = vals[counts < drop_share * total]
            kk = np.where(np.isin(kk, small), 0, kk)
        key[ys, xs] = kk
    if not cut_any:
        return lab, n
    return renumber_raster(key)


def detect(disp: np.ndarray, rgb: np.ndarray | None, calib: dict, p: DetectParams) -> DetectReferenceResult:
    """disp: float disparity [px], NaN = none. rgb: HxWx3 uint8 R G B, or None (mono camera).
    calib: focal_px, baseline_m, cx, cy; height_m and pitch_deg (optional) for the road slope prior."""
    h, w = disp.shape
    disp = fill_holes(disp, int(p.fill_max_run_px), bool(p.fill_left_border))
    valid = np.isfinite(disp)
    bins = int(disp_bin(disp[valid]).max()) + 1 if valid.any() else 1
    vd = v_disparity(disp, bins)
    found, a, b, horizon = False, 0.0, 0.0, -1
    lo, hi = road_slope_range(p, calib)
    if p.road_enabled and lo <= hi:
        found, a, b, horizon = fit_road_line(vd, int(valid.sum()), DetectParams({**p.values, "road_slope_min": lo,
                                                                              "road_slope_max": hi}))
    road_raw = (road_pixels(disp, a, b, horizon, p.road_tolerance_px, float(p.road_tolerance_rel)) if found
                else np.zeros((h, w), np.uint8))
    road = close_mask(road_raw, int(p.road_close_radius))
    if found:
        road = complete_road(road, disp, horizon, int(p.road_fill_invalid_px))
    skipped = rgb is None or not p.sky_enabled
    rows = 0
    if skipped:
        sky = np.zeros((h, w), np.uint8)
    else:
        rows = horizon if (p.sky_limit == "horizon" and found) else int(np.floor(p.sky_upper_fraction * h + 0.5))
        sky = sky_mask(rgb, disp, rows, p)
    with np.errstate(invalid="ignore"):
        cand = valid & (disp >= p.kmeans_min_disparity_px) & (road == 0) & (sky == 0)
    centres, lab = kmeans_1d(disp[cand], int(p.kmeans_k), int(p.kmeans_max_iterations), p.kmeans_merge_px)
    labels = np.full((h, w), -1, np.int64)
    labels[cand] = lab
    kept = u_disparity_filter(disp, labels, len(centres), bins, p)
    comp, n = components(kept, disp, p.cc_max_step_px, float(p.cc_max_rel_step), float(p.cc_min_step_px))
    comp, n = split_bimodal(comp, n, disp, int(p.split_min_px), float(p.split_min_rel), float(p.split_max_valley),
                            int(p.split_rounds))
    out, ol = measure_obstacles(comp, n, disp, calib, p)
    if int(getattr(p, "neck_min_width_px", 0)) > 0:  # docs/detection.md "(e) Necks" (session 30)
        cut, nn = split_necks(ol, len(out), int(p.neck_min_width_px), float(p.neck_max_share), int(p.neck_min_px),
                              float(getattr(p, "neck_foot_share", 0.0)))
        if not np.array_equal(cut, ol):
            out, ol = measure_obstacles(cut, nn, disp, calib, DetectParams({**p.values, "merge_gap_px": 0,
                                                                            "merge_edge_rel_disparity": 0.0,
                                                                            "contain_min_inside": 0.0}))
    if float(getattr(p, "seam_min_step", 0.0)) > 0 and rgb is not None:  # docs/detection.md "(e) Seams" (session 33)
        cut, ns = split_seams(ol, len(out), rgb, float(p.seam_min_step), int(p.seam_window_px),
                              int(p.seam_min_width_px), int(p.seam_min_px), int(p.seam_max_cuts),
                              float(p.seam_min_rows), float(getattr(p, "seam_drop_share", 0.0)))
        if ns != len(out) or not np.array_equal(cut, ol):  # a dropped piece can leave the count as it was
            out, ol = measure_obstacles(cut, ns, disp, calib, DetectParams({**p.values, "merge_gap_px": 0,
                                                                            "merge_edge_rel_disparity": 0.0,
                                                                            "contain_min_inside": 0.0}))
    if found:
        out = drop_below_road(out, ol, a, b, horizon, p)  # docs/detection.md "(e) Below the road"
    out = drop_seen_through(out, ol, p)  # docs/detection.md "(e) Seen through"
    trim_sparse_columns(out, ol, calib, p, sky, disp)  # box extent, docs/detection.md "(e) Box extent"
    if found:
        extend_to_ground(out, a, b, horizon, h, p)
    out = drop_inside_nearer(out, ol, p)  # docs/detection.md "(e) Inside a nearer face"
    out = merge_side_faces(out, ol, p)  # docs/detection.md "(e) Side faces" (session 33)
    if found:
        extend_over_gap(out, ol, a, b, horizon, h, p)  # docs/detection.md "(e) Box extent"
    return DetectReferenceResult(bins, vd, found, a, b, horizon, road_raw, road, skipped, rows, sky,
                                 cand.astype(np.uint8), centres, np.where(labels >= 0, labels, 255).astype(np.uint8),
                                 kept, out, ol)
