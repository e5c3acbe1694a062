"""Data costs per segment and disparity, eq. (1)-(9), in float64.

Geometry (the firmware's): with the left image as reference (``direction = +1``) the pixel x of
row y matches x - d in the right image; with the right image as reference (``direction = -1``) it
matches x + d in the left image. A partner column outside the image is clamped to the border.

Per segment s (its pixels are the matching window) and disparity d in [0, D):

* eq. (1)  NCC  = sum (l - mean l)(r - mean r) / sqrt(sum (l - mean l)^2 sum (r - mean r)^2),
  clamped below at 0 (0 when either variance is 0)           -> Data Cost 1, eq. (8);
* eq. (6)  GSAD = sum |g_l - g_r| over the gradient magnitudes of eq. (5);
* eq. (7)  IGSAD = 1 - GSAD_d / max_d GSAD_d (1 for every d when the maximum is 0);
* eq. (2)-(4) NMI = (H(X) + H(Y) - H(X, Y)) / sqrt(H(X) H(Y)) over the segment's pixels and their
  partners, intensities binned as I * bins // 256, entropies in bits; 0 when H(X) H(Y) = 0,
  clamped to [0, 1];
* eq. (9)  DC2 = alpha NMI + (1 - alpha) IGSAD.

Every sum over a segment is ``np.bincount(labels, weights)``, one per disparity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class SegmentCosts:
    """Per segment (rows) and disparity (columns)."""

    ncc: np.ndarray  # (n, D) eq. (1), clamped to [0, 1]
    igsad: np.ndarray  # (n, D) eq. (7)
    nmi: np.ndarray  # (n, D) eq. (2)
    pixels: np.ndarray  # (n,) pixel count per segment
    gsad: np.ndarray | None = None  # (n, D) eq. (6), exact integers held in float64

    def dc2(self, alpha: float) -> np.ndarray:
        """eq. (9): Data Cost 2."""
        return alpha * self.nmi + (1.0 - alpha) * self.igsad


def partner_columns(width: int, d: int, direction: int) -> np.ndarray:
    """Column of the partner of every reference column at disparity d (clamped to the image)."""
    return np.clip(np.arange(width) - direction * d, 0, width - 1)


def _entropy_bits(counts: np.ndarray, n: np.ndarray) -> np.ndarray:
    """eq. (3)/(4): -sum p log2 p over the last axes of ``counts``; n = samples per row."""
    n = n.reshape((-1,) + (1,) * (counts.ndim - 1)).astype(np.float64)
    p = counts / np.maximum(n, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
    return terms.reshape(counts.shape[0], -1).sum(axis=1)


def segment_costs(
    ref: np.ndarray,
    other: np.ndarray,
    ref_grad: np.ndarray,
    other_grad: np.ndarray,
    labels: np.ndarray,
    direction: int,
    max_disparity: int,
    nmi_bins: int,
) -> SegmentCosts:
    """NCC, IGSAD and NMI of every segment at every disparity (see the module doc)."""
    h, w = ref.shape
    lab = labels.ravel().astype(np.int64)
    n_seg = int(lab.max()) + 1
    D, B = max_disparity, nmi_bins

    def seg_sum(values: np.ndarray) -> np.ndarray:
        return np.bincount(lab, weights=values.ravel(), minlength=n_seg)

    n = np.bincount(lab, minlength=n_seg).astype(np.float64)
    l = ref.astype(np.float64)
    l_mean = seg_sum(l) / np.maximum(n, 1.0)
    l_c = l - l_mean[labels]  # l - mean l, per pixel
    var_l = seg_sum(l_c * l_c)
    g_l = ref_grad.astype(np.float64)

    bin_l = ref.astype(np.int64) * B // 256
    bin_o = other.astype(np.int64) * B // 256
    hist_l = np.bincount(lab * B + bin_l.ravel(), minlength=n_seg * B).reshape(n_seg, B)
    H_x = _entropy_bits(hist_l, n)

    ncc = np.zeros((n_seg, D))
    gsad = np.zeros((n_seg, D))
    nmi = np.zeros((n_seg, D))
    for d in range(D):
        cols = partner_columns(w, d, direction)
        r = other[:, cols].astype(np.float64)
        g_r = other_grad[:, cols].astype(np.float64)

        # eq. (1)
        r_mean = seg_sum(r) / np.maximum(n, 1.0)
        r_c = r - r_mean[labels]
        var_r = seg_sum(r_c * r_c)
        cov = seg_sum(l_c * r_c)
        den = np.sqrt(var_l * var_r)
        with np.errstate(divide="ignore", invalid="ignore"):
            ncc[:, d] = np.where((var_l > 0) & (var_r > 0), cov / np.where(den > 0, den, 1.0), 0.0)

        # eq. (6)
        gsad[:, d] = seg_sum(np.abs(g_l - g_r))

        # eq. (2)-(4)
        b_r = bin_o[:, cols].ravel()
        joint = np.bincount((lab * B + bin_l.ravel()) * B + b_r, minlength=n_seg * B * B).reshape(n_seg, B, B)
        H_y = _entropy_bits(joint.sum(axis=1), n)
        H_xy = _entropy_bits(joint, n)
        prod = H_x * H_y
        with np.errstate(divide="ignore", invalid="ignore"):
            nmi[:, d] = np.where(prod > 0, (H_x + H_y - H_xy) / np.sqrt(np.where(prod > 0, prod, 1.0)), 0.0)

    ncc = np.clip(ncc, 0.0, 1.0)  # eq. (8): Data Cost 1 is NCC clamped to [0, 1]
    nmi = np.clip(nmi, 0.0, 1.0)
    # eq. (7)
    gmax = gsad.max(axis=1, keepdims=True)
    igsad = np.where(gmax > 0, 1.0 - gsad / np.where(gmax > 0, gmax, 1.0), 1.0)
    return SegmentCosts(ncc=ncc, igsad=igsad, nmi=nmi, pixels=n.astype(np.int64), gsad=gsad)
