"""Superpixel segmentation (Section III, ref. [57]): SLIC on grey level and position, float64.

Mirrors the firmware's integer SLIC in structure — grid centres of step S moved to the lowest
gradient of their 3x3 neighbourhood, ``iterations`` rounds of assignment within +-S of each
centre with distance dI^2 + (dx^2 + dy^2) (m/S)^2 and centre update by the mean, then
connectivity enforcement (4-connected pieces smaller than min_segment_pct % of S^2 join the
neighbour of their first pixel) — but in floating point, so labels differ near ties; the
comparison measures that (:func:`label_agreement`).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def slic(img: np.ndarray, region_size: int, compactness: int, iterations: int, min_segment_pct: int) -> np.ndarray:
    """Dense labels 0 .. n-1 (int32, H x W)."""
    h, w = img.shape
    S = region_size
    f = img.astype(np.float64)
    spatial = (compactness / S) ** 2

    # Grid centres moved to the lowest central-difference gradient of the 3x3 neighbourhood.
    def grad(x: int, y: int) -> float:
        x = min(max(x, 1), w - 2)
        y = min(max(y, 1), h - 2)
        gx = f[y, x + 1] - f[y, x - 1]
        gy = f[y + 1, x] - f[y - 1, x]
        return gx * gx + gy * gy

    centres = []
    for cy in range(S // 2, h, S):
        for cx in range(S // 2, w, S):
            bx, by, bg = cx, cy, np.inf
            if w >= 3 and h >= 3:
                for dy in (-1, 0, 1):
                    for dx in (-1, 0, 1):
                        x, y = min(max(cx + dx, 0), w - 1), min(max(cy + dy, 0), h - 1)
                        g = grad(x, y)
                        if g < bg:
                            bx, by, bg = x, y, g
            centres.append((float(bx), float(by), f[by, bx]))
    if not centres:
        centres.append((float(w // 2), float(h // 2), f[h // 2, w // 2]))
    C = np.array(centres)

    labels = np.full((h, w), -1, dtype=np.int64)
    ys, xs = np.mgrid[0:h, 0:w]
    for _ in range(iterations):
        dist = np.full((h, w), np.inf)
        for k, (cx, cy, ci) in enumerate(C):
            x0, x1 = max(0, int(round(cx)) - S), min(w - 1, int(round(cx)) + S) + 1
            y0, y1 = max(0, int(round(cy)) - S), min(h - 1, int(round(cy)) + S) + 1
            d = (f[y0:y1, x0:x1] - ci) ** 2 + ((xs[y0:y1, x0:x1] - cx) ** 2 + (ys[y0:y1, x0:x1] - cy) ** 2) * spatial
            better = d < dist[y0:y1, x0:x1]
            dist[y0:y1, x0:x1][better] = d[better]
            labels[y0:y1, x0:x1][better] = k
        ok = labels >= 0
        lab = labels[ok]
        n = np.bincount(lab, minlength=len(C)).astype(np.float64)
        has = n > 0
        for col, v in enumerate((xs[ok], ys[ok], f[ok])):
            s = np.bincount(lab, weights=v, minlength=len(C))
            C[has, col] = s[has] / n[has]
    return enforce_connectivity(labels, max(1, S * S * min_segment_pct // 100))


def enforce_connectivity(labels: np.ndarray, min_size: int) -> np.ndarray:
    """Relabel 4-connected pieces densely in scan order; pieces < min_size join a neighbour."""
    h, w = labels.shape
    pieces = _pieces(labels)
    n_pieces = int(pieces.max()) + 1
    flat = pieces.ravel()
    first = np.full(n_pieces, flat.size, dtype=np.int64)
    np.minimum.at(first, flat, np.arange(flat.size))
    size = np.bincount(flat, minlength=n_pieces)
    out_of_piece = np.full(n_pieces, -1, dtype=np.int64)
    next_label = 0
    for p in np.argsort(first, kind="stable"):  # pieces in scan order of their first pixel
        y, x = divmod(int(first[p]), w)
        adjacent = -1
        for nx, ny in ((x - 1, y), (x, y - 1), (x + 1, y), (x, y + 1)):
            if 0 <= nx < w and 0 <= ny < h:
                q = out_of_piece[pieces[ny, nx]]
                if q >= 0:
                    adjacent = q
                    break
        if size[p] < min_size and adjacent >= 0:
            out_of_piece[p] = adjacent
        else:
            out_of_piece[p] = next_label
            next_label += 1
    return out_of_piece[pieces].astype(np.int32)


def _pieces(labels: np.ndarray) -> np.ndarray:
    """Id of the 4-connected piece of equal label of every pixel (connected components of the
    graph linking horizontally/vertically adjacent pixels with the same label)."""
    h, w = labels.shape
    idx = np.arange(h * w).reshape(h, w)
    same_h = labels[:, 1:] == labels[:, :-1]
    same_v = labels[1:, :] == labels[:-1, :]
    src = np.concatenate([idx[:, :-1][same_h], idx[:-1, :][same_v]])
    dst = np.concatenate([idx[:, 1:][same_h], idx[1:, :][same_v]])
    graph = coo_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(h * w, h * w))
    _, comp = connected_components(graph, directed=False)
    return comp.reshape(h, w).astype(np.int64)


def label_agreement(labels_a: np.ndarray, labels_b: np.ndarray) -> float:
    """% of pixels whose label in b is the majority b-label of their a-segment (100 = same partition).

    Symmetrised by taking the minimum of both directions, so neither over- nor under-segmentation
    scores 100 unless the partitions are identical up to renaming.
    """

    def one_way(a: np.ndarray, b: np.ndarray) -> float:
        a = a.ravel().astype(np.int64)
        b = b.ravel().astype(np.int64)
        pair = a * (int(b.max()) + 1) + b
        uniq, counts = np.unique(pair, return_counts=True)
        seg = uniq // (int(b.max()) + 1)
        best = np.zeros(int(a.max()) + 1, dtype=np.int64)
        np.maximum.at(best, seg, counts)
        return 100.0 * best.sum() / a.size

    return min(one_way(labels_a, labels_b), one_way(labels_b, labels_a))
