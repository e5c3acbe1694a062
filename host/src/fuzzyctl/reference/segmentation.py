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


def slic(
    img: np.ndarray,
    region_size: int,
    compactness: int,
    iterations: int,
    min_segment_pct: int,
    coarse_iterations: int = 0,
) -> np.ndarray:
    """Dense labels 0 .. n-1 (int32, H x W).

    ``coarse_iterations`` > 0: that many rounds first on the image halved in both directions (2 x 2
    block means, grid step S // 2, the same compactness), the centres then scaled back (x -> 2x + 0.5)
    for the ``iterations`` full-resolution rounds, as the firmware's coarse start.
    """
    h, w = img.shape
    S = region_size
    f = img.astype(np.float64)

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

    if coarse_iterations > 0 and w >= 2 and h >= 2 and S >= 2:
        half = _halve(f)
        Ch = np.column_stack([np.floor(C[:, 0] / 2), np.floor(C[:, 1] / 2), C[:, 2]])
        _rounds(half, S // 2, compactness, Ch, coarse_iterations)
        C = np.column_stack([np.minimum(2 * Ch[:, 0] + 0.5, w - 1), np.minimum(2 * Ch[:, 1] + 0.5, h - 1), Ch[:, 2]])
    labels = _rounds(f, S, compactness, C, iterations)
    return enforce_connectivity(labels, max(1, S * S * min_segment_pct // 100))


def _halve(f: np.ndarray) -> np.ndarray:
    """Means of 2 x 2 blocks (the last column / row of an odd size repeated)."""
    h, w = f.shape
    p = np.pad(f, ((0, h % 2), (0, w % 2)), mode="edge")
    return (p[0::2, 0::2] + p[0::2, 1::2] + p[1::2, 0::2] + p[1::2, 1::2]) / 4.0


def _rounds(f: np.ndarray, S: int, compactness: int, C: np.ndarray, iterations: int) -> np.ndarray:
    """``iterations`` rounds of assignment within +-S of each centre and update by the mean (C in place)."""
    h, w = f.shape
    spatial = (compactness / S) ** 2
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
    return labels


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
