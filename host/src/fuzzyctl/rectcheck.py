"""Rectification check on ordinary scenes (``fuzzyctl rectcheck``): has the stereo rig drifted?

The matcher searches along rows only, so a rectified pair must put every scene point on the same
row in both images. A camera knocked on its mount, a loose lens or a calibration made at another
resolution breaks that silently: the disparity maps just get worse. This check needs no chessboard:
SIFT features of each rectified pair (OpenCV), matched left -> right with Lowe's ratio test and a
right -> left cross-check, kept when their disparity is plausible (x_l - x_r in [-1, max_disparity]);
then the row differences dy = y_l - y_r. A rig in order gives |dy| of a few tenths of a pixel
(feature localisation); a shift, roll or scale difference between the cameras shows up as a trend.

The trend is the least-squares fit dy = a + b (x - cx) + c (y - cy) over all pairs (two rounds, the
second without the matches beyond 3 robust standard deviations), reported as the right image's
error relative to the left: offset -a [px] (positive: the right image's content sits lower), roll b
[rad, shown in deg] (positive: the right image is turned counter-clockwise as displayed, the sign of
cv2.getRotationMatrix2D's angle; a point at x - cx then moves up by b (x - cx)), and vertical scale -c
(positive: the right image is larger, e.g. a focal-length mismatch).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .calibrate import find_pairs, read_grey
from .errors import FatalError


@dataclass
class PairCheck:
    name: str
    matches: int
    median_abs_dy: float


@dataclass
class RectCheck:
    pairs: list[PairCheck] = field(default_factory=list)
    matches: int = 0
    median_dy: float = 0.0
    median_abs_dy: float = 0.0
    p90_abs_dy: float = 0.0
    offset_px: float = 0.0  # -a: the right image's content lower than the left's at the centre [px]
    roll_deg: float = 0.0  # b: the right image turned counter-clockwise (as displayed) [deg]
    scale_pct: float = 0.0  # -c: the right image vertically larger [%]

    def lines(self) -> list[str]:
        return [
            f"{len(self.pairs)} pairs, {self.matches} matches: dy = y_left - y_right median {self.median_dy:+.2f} px, "
            f"|dy| median {self.median_abs_dy:.2f} px, 90th percentile {self.p90_abs_dy:.2f} px",
            f"right image vs left: {self.offset_px:+.2f} px lower at the centre, turned {self.roll_deg:+.3f} deg "
            f"counter-clockwise, vertically {self.scale_pct:+.2f} % larger",
        ]


def _matches(left: np.ndarray, right: np.ndarray, max_disparity: float) -> tuple[np.ndarray, np.ndarray]:
    """Matched keypoint positions (N x 2 each) of a rectified grey pair."""
    import cv2

    sift = cv2.SIFT_create(nfeatures=3000)
    kl, dl = sift.detectAndCompute(left, None)
    kr, dr = sift.detectAndCompute(right, None)
    if dl is None or dr is None or len(kl) < 2 or len(kr) < 2:
        return np.zeros((0, 2)), np.zeros((0, 2))
    bf = cv2.BFMatcher(cv2.NORM_L2)
    fwd = bf.knnMatch(dl, dr, k=2)
    back = {m.queryIdx: m.trainIdx for m in bf.match(dr, dl)}
    pl, pr = [], []
    for pair in fwd:
        if len(pair) < 2:
            continue
        m, n = pair
        if m.distance >= 0.75 * n.distance or back.get(m.trainIdx) != m.queryIdx:
            continue
        a, b = kl[m.queryIdx].pt, kr[m.trainIdx].pt
        if -1.0 <= a[0] - b[0] <= max_disparity:
            pl.append(a)
            pr.append(b)
    return np.asarray(pl, float).reshape(-1, 2), np.asarray(pr, float).reshape(-1, 2)


def check_pairs(pairs: list[tuple[str, np.ndarray, np.ndarray]], max_disparity: float = 256.0,
                min_matches: int = 30) -> RectCheck:
    """Row differences of the matched features of rectified grey pairs ``(name, left, right)``."""
    out = RectCheck()
    xs, ys, dys = [], [], []
    size = None
    for name, left, right in pairs:
        if left.shape != right.shape:
            raise FatalError(f"{name}: left is {left.shape[1]}x{left.shape[0]}, right {right.shape[1]}x{right.shape[0]}")
        size = left.shape
        pl, pr = _matches(left, right, max_disparity)
        dy = pl[:, 1] - pr[:, 1]
        keep = np.abs(dy) < 20.0  # a row error this large is a wrong match, not a rig
        pl, dy = pl[keep], dy[keep]
        out.pairs.append(PairCheck(name, int(dy.size), float(np.median(np.abs(dy))) if dy.size else math.nan))
        xs.append(pl[:, 0])
        ys.append(pl[:, 1])
        dys.append(dy)
    x, y, dy = (np.concatenate(v) if v else np.zeros(0) for v in (xs, ys, dys))
    if dy.size < min_matches:
        raise FatalError(
            f"only {dy.size} feature matches in {len(pairs)} pair(s) (at least {min_matches} needed): "
            "point the cameras at a textured scene, or check that the pairs are rectified stereo pairs"
        )
    assert size is not None
    cx, cy = (size[1] - 1) / 2.0, (size[0] - 1) / 2.0
    A = np.column_stack([np.ones_like(x), x - cx, y - cy])
    keep = np.ones(dy.size, bool)
    for _ in range(2):
        coef, *_ = np.linalg.lstsq(A[keep], dy[keep], rcond=None)
        res = dy - A @ coef
        sigma = 1.4826 * np.median(np.abs(res[keep] - np.median(res[keep]))) + 1e-6
        keep = np.abs(res) <= 3.0 * sigma
    out.matches = int(dy.size)
    out.median_dy = float(np.median(dy))
    out.median_abs_dy = float(np.median(np.abs(dy)))
    out.p90_abs_dy = float(np.percentile(np.abs(dy), 90))
    out.offset_px = float(-coef[0])
    out.roll_deg = float(math.degrees(coef[1]))
    out.scale_pct = float(-100.0 * coef[2])
    return out


def check_folder(folder: Path, max_disparity: float = 256.0, limit: int = 0) -> RectCheck:
    """``check_pairs`` over a capture folder (left/, right/), at most ``limit`` pairs spread evenly."""
    files = find_pairs(folder)
    if limit and len(files) > limit:
        idx = np.linspace(0, len(files) - 1, limit).round().astype(int)
        files = [files[i] for i in sorted(set(idx))]
    pairs = [(pf.name, read_grey(pf.left), read_grey(pf.right)) for pf in files]
    return check_pairs(pairs, max_disparity=max_disparity)
