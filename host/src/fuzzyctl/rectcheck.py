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


# ---- photometry: do the two cameras see the scene alike? ----------------------------------------
#
# The matcher compares the two views' grey levels, so cameras that differ in exposure, gain, tone
# curve or noise cost it accuracy. It has two detectors for such pairs (docs/algorithm.md 2b, 2c:
# the grey-level quantile shift and the noise excess), and on a pair either fires it compensates and
# runs the census boundary refinement, about 1.5x the matcher's time (4b "On a mismatched pair"). The
# check runs the same detectors (the reference twins, exact) on the captured pairs, so a rig whose
# cameras are set up differently is found at bring-up, not from a slow or noisy robot.


@dataclass
class PhotoPair:
    name: str
    grey_shift: float  # mean |quantile difference| [grey levels], after noise equalisation as in the matcher
    brightness: float  # right / left, the ratio of the sums of the 5 %, ..., 95 % quantiles
    noise_left: float  # [grey levels]
    noise_right: float
    noise_excess: float  # the noisier camera's noise beyond the other's [grey levels]
    equalised: bool  # noise equalisation fires (excess > cost.noise_excess)
    gain_triggered: bool  # the grey-level gain trigger fires (shift > cost.gradient_gain_grey_shift)

    @property
    def mismatched(self) -> bool:
        return self.equalised or self.gain_triggered


@dataclass
class PhotoCheck:
    pairs: list[PhotoPair]
    grey_shift_limit: float  # cost.gradient_gain_grey_shift (0 when the grey trigger is not in use)
    noise_excess_limit: float  # cost.noise_excess (0 = noise equalisation off)
    on_mismatch: bool  # boundary.on_mismatch

    def median(self, key: str) -> float:
        return float(np.median([getattr(p, key) for p in self.pairs])) if self.pairs else math.nan

    @property
    def mismatched(self) -> int:
        return sum(p.mismatched for p in self.pairs)

    def lines(self) -> list[str]:
        n = len(self.pairs)
        shift = f"grey-level shift median {self.median('grey_shift'):.1f} levels"
        shift += (f" (gain trigger above {self.grey_shift_limit:g}: {sum(p.gain_triggered for p in self.pairs)} of {n} pairs)"
                  if self.grey_shift_limit > 0 else " (gain trigger not in use)")
        noise = (f"noise left {self.median('noise_left'):.2f} / right {self.median('noise_right'):.2f} grey levels, "
                 f"excess median {self.median('noise_excess'):.2f}")
        noise += (f" (equalised above {self.noise_excess_limit:g}: {sum(p.equalised for p in self.pairs)} of {n} pairs)"
                  if self.noise_excess_limit > 0 else " (noise equalisation off)")
        return [f"photometry: right image x{self.median('brightness'):.2f} the left's brightness, {shift}", noise]

    def advice(self) -> str | None:
        """A sentence for the operator when most pairs read as mismatched, else None."""
        n = len(self.pairs)
        if not n or 2 * self.mismatched <= n:
            return None
        what = []
        if sum(p.gain_triggered for p in self.pairs) * 2 > n:
            b = self.median("brightness")
            what.append(f"the right camera is {abs(1 - b) * 100:.0f} % {'darker' if b < 1 else 'brighter'} or has another tone curve")
        if sum(p.equalised for p in self.pairs) * 2 > n:
            noisier = "right" if self.median("noise_right") > self.median("noise_left") else "left"
            what.append(f"the {noisier} camera is noisier")
        cost = ("the matcher compensates and runs the boundary refinement on such pairs, about 1.5x its time per frame"
                if self.on_mismatch else "the matcher compensates (the boundary refinement is off for them: on_mismatch = false)")
        return (f"{self.mismatched} of {n} pairs read as mismatched ({'; '.join(what) or 'see above'}): {cost}. "
                "Give both cameras the same fixed exposure, gain and white balance (docs/capture.md), or accept the cost")


def photometric_check(pairs: list[tuple[str, np.ndarray, np.ndarray]], cfg=None) -> PhotoCheck:
    """The matcher's camera-difference detectors (docs/algorithm.md 2b, 2c) on grey pairs ``(name, left, right)``,
    with the thresholds of ``cfg`` (a fuzzyctl.config.Config; default: common/config/default.toml)."""
    from .config import load_config
    from .reference import image

    cfg = cfg if cfg is not None else load_config(None)
    c = cfg.cost
    grey = c.gradient_gain_compensation and c.gradient_gain_trigger == "grey"
    out = PhotoCheck([], c.gradient_gain_grey_shift if grey else 0.0, c.noise_excess, bool(cfg.boundary.on_mismatch))
    for name, left, right in pairs:
        if left.shape != right.shape:
            raise FatalError(f"{name}: left is {left.shape[1]}x{left.shape[0]}, right {right.shape[1]}x{right.shape[0]}")
        sl, sr = image.estimate_noise_sigma(left), image.estimate_noise_sigma(right)
        excess = image.noise_excess(sl, sr, image.grey_spread(left), image.grey_spread(right))
        l2, r2, _, _, equalised = image.noise_equalise(left, right, c.noise_excess, c.noise_image_passes,
                                                       c.noise_gradient_passes)
        shift = image.grey_quantile_shift(l2, r2)  # the matcher reads the images the costs see
        ql, qr = image.grey_quantiles(left).sum(), image.grey_quantiles(right).sum()
        out.pairs.append(PhotoPair(name, shift, float(qr) / float(ql) if ql > 0 else math.nan, sl, sr, excess,
                                   bool(equalised), bool(grey and shift > c.gradient_gain_grey_shift)))
    return out


def folder_pairs(folder: Path, limit: int = 0) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The grey pairs ``(name, left, right)`` of a capture folder (left/, right/), at most ``limit`` spread evenly."""
    files = find_pairs(folder)
    if limit and len(files) > limit:
        idx = np.linspace(0, len(files) - 1, limit).round().astype(int)
        files = [files[i] for i in sorted(set(idx))]
    return [(pf.name, read_grey(pf.left), read_grey(pf.right)) for pf in files]


def check_folder(folder: Path, max_disparity: float = 256.0, limit: int = 0) -> RectCheck:
    """``check_pairs`` over a capture folder (left/, right/), at most ``limit`` pairs spread evenly."""
    return check_pairs(folder_pairs(folder, limit), max_disparity=max_disparity)
