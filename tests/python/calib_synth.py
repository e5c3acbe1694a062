"""Synthetic chessboard pairs with a known stereo calibration, for the `fuzzyctl calibrate` tests.

Each view is rendered exactly: the board's plane is mapped into an ideal (distortion-free) image by
the homography K [r1 r2 t], then the lens distortion of the camera is applied by remapping (every
distorted pixel samples the ideal image at K * undistort(pixel)), at 2x and then averaged down
(anti-aliasing), with Gaussian noise. The truth (K, D, R, T) is returned with the files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

SIZE = (640, 480)


@dataclass
class Truth:
    K1: np.ndarray
    D1: np.ndarray
    K2: np.ndarray
    D2: np.ndarray
    R: np.ndarray
    T: np.ndarray
    cols: int
    rows: int
    square_m: float


def default_truth() -> Truth:
    K1 = np.array([[420.0, 0, 322.0], [0, 421.0, 236.0], [0, 0, 1]])
    K2 = np.array([[415.0, 0, 316.0], [0, 416.5, 243.0], [0, 0, 1]])
    D1 = np.array([-0.12, 0.03, 0.0, 0.0, 0.0])
    D2 = np.array([-0.09, 0.02, 0.0, 0.0, 0.0])
    R, _ = cv2.Rodrigues(np.array([0.012, -0.02, 0.006]))
    T = np.array([[-0.10], [0.0015], [-0.002]])
    return Truth(K1, D1, K2, D2, R, T, cols=9, rows=6, square_m=0.03)


def _board_image(cols: int, rows: int, px: int) -> np.ndarray:
    """(cols + 1) x (rows + 1) squares of px pixels with a white margin of one square."""
    w, h = (cols + 3) * px, (rows + 3) * px
    img = np.full((h, w), 255, np.uint8)
    for j in range(rows + 1):
        for i in range(cols + 1):
            if (i + j) % 2 == 0:
                y0, x0 = (j + 1) * px, (i + 1) * px
                img[y0 : y0 + px, x0 : x0 + px] = 0
    return img


def _render(board: np.ndarray, px: int, square_m: float, K: np.ndarray, D: np.ndarray, rvec, tvec, ss: int = 2) -> np.ndarray:
    """The board seen by camera (K, D) at pose (rvec, tvec) of the board frame, SIZE, uint8."""
    W, H = SIZE
    pad = 200
    # board pixel centre (u, v) -> board metres: inner corner (0, 0) is at the pixel boundary 2 px-squares in
    s = square_m / px
    A = np.array([[s, 0, -(2 * px - 0.5) * s], [0, s, -(2 * px - 0.5) * s], [0, 0, 1]])
    Rb, _ = cv2.Rodrigues(rvec)
    M = np.column_stack([Rb[:, 0], Rb[:, 1], np.ravel(tvec)])
    # ideal image at ss x resolution, padded so barrel distortion samples inside it
    Ks = np.diag([ss, ss, 1.0]) @ K
    Ks[0, 2] += (pad + 0.5) * ss - 0.5
    Ks[1, 2] += (pad + 0.5) * ss - 0.5
    Hm = Ks @ M @ A
    ideal = cv2.warpPerspective(board, Hm, ((W + 2 * pad) * ss, (H + 2 * pad) * ss), flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=160)
    # distorted output pixel (at ss x) -> ideal pixel
    xs, ys = np.meshgrid((np.arange(W * ss) + 0.5) / ss - 0.5, (np.arange(H * ss) + 0.5) / ss - 0.5)
    pts = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.float64).reshape(-1, 1, 2)
    und = cv2.undistortPoints(pts, K, D, P=K).reshape(-1, 2)
    mapx = ((und[:, 0] + pad + 0.5) * ss - 0.5).reshape(H * ss, W * ss).astype(np.float32)
    mapy = ((und[:, 1] + pad + 0.5) * ss - 0.5).reshape(H * ss, W * ss).astype(np.float32)
    big = cv2.remap(ideal, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=160)
    return cv2.resize(big, SIZE, interpolation=cv2.INTER_AREA)


def _visible(truth: Truth, rvec, tvec, K, D, margin: float = 12.0) -> bool:
    obj = np.zeros(((truth.cols + 2) * (truth.rows + 2), 3))
    g = np.mgrid[-1 : truth.cols + 1, -1 : truth.rows + 1].T.reshape(-1, 2)
    obj[:, :2] = g * truth.square_m
    p, _ = cv2.projectPoints(obj, rvec, tvec, K, D)
    p = p.reshape(-1, 2)
    return bool(np.all(p[:, 0] > margin) and np.all(p[:, 0] < SIZE[0] - margin) and np.all(p[:, 1] > margin)
                and np.all(p[:, 1] < SIZE[1] - margin))


def write_pairs(out: Path, count: int = 14, seed: int = 5, truth: Truth | None = None, noise: float = 2.0) -> Truth:
    """``count`` pairs in out/left, out/right (PNG, same names); returns the truth."""
    truth = truth or default_truth()
    rng = np.random.default_rng(seed)
    px = 40
    board = _board_image(truth.cols, truth.rows, px)
    (out / "left").mkdir(parents=True, exist_ok=True)
    (out / "right").mkdir(parents=True, exist_ok=True)
    centre = np.array([(truth.cols - 1) * truth.square_m / 2, (truth.rows - 1) * truth.square_m / 2, 0.0])
    k = 0
    while k < count:
        ang = rng.uniform([-0.5, -0.5, -0.25], [0.5, 0.5, 0.25])
        Rb, _ = cv2.Rodrigues(ang)
        z = rng.uniform(0.32, 0.6)
        pos = np.array([rng.uniform(-0.12, 0.08), rng.uniform(-0.08, 0.08), z])
        tvec = pos - Rb @ centre  # the board centre at pos
        rvec = ang.reshape(3, 1)
        rvec_r, _ = cv2.Rodrigues(truth.R @ Rb)
        tvec_r = truth.R @ tvec.reshape(3, 1) + truth.T
        if not (_visible(truth, rvec, tvec, truth.K1, truth.D1) and _visible(truth, rvec_r, tvec_r, truth.K2, truth.D2)):
            continue
        for side, K, D, rv, tv in (("left", truth.K1, truth.D1, rvec, tvec), ("right", truth.K2, truth.D2, rvec_r, tvec_r)):
            img = _render(board, px, truth.square_m, K, D, rv, tv).astype(np.float32)
            img += rng.normal(0.0, noise, img.shape)
            cv2.imwrite(str(out / side / f"{k:06d}.png"), np.clip(np.rint(img), 0, 255).astype(np.uint8))
        k += 1
    return truth
