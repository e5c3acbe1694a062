"""Stereo calibration from chessboard pairs (``fuzzyctl calibrate``), with OpenCV calib3d.

Input: a ``fuzzystereo capture`` folder of *raw* (unrectified) pairs, ``DIR/left/NAME`` and
``DIR/right/NAME`` with the same file names. Output: the calibration file the firmware's
``Rectifier`` reads (docs/capture.md, "Calibration file": image size, K1, D1, K2, D2, R, T in metres,
optional mounting height and pitch).

Steps (all OpenCV; nothing here re-implements a calib3d routine):
1. chessboard corners per image: ``findChessboardCorners`` + ``cornerSubPix`` (5 x 5 window), else
   the sector-based ``findChessboardCornersSB`` (finds blurred or unevenly lit boards the classic
   detector misses); a pair counts only when both views show the whole board. The classic detector
   goes first: on the synthetic test pairs it is 15x faster and its focal lengths are closer to the
   truth (420.04 vs 421.57 px for 420; SB with CALIB_CB_ACCURACY);
2. each camera alone: ``calibrateCamera`` (5-coefficient model k1 k2 p1 p2 k3);
3. the pair: ``stereoCalibrate`` starting from those intrinsics (``CALIB_USE_INTRINSIC_GUESS``) so R, T
   and the intrinsics are refined together;
4. optionally, while a view's stereo reprojection error exceeds ``max_view_error`` px, drop the
   worst view and repeat 2-3 (a blurred or mis-detected view pulls every parameter);
5. quality: the *rectified epipolar error*, the RMS of y_left - y_right over every corner after
   ``stereoRectify`` + ``undistortPoints`` — what the matcher cares about (it searches along rows
   only); above ~0.5 px the row search starts to miss. And the *corner coverage*: the share of the
   cells of a 4 x 4 grid over each image that hold a corner of some view. The lens distortion is
   only measured where corners were; below 60 % it is extrapolated into the corners of the image,
   where rectification then errs first (a warning, not an error).

Conventions (the firmware's): X_right = R X_left + T, T in metres, the right camera on the right
(T.x < 0). The square size is in metres; a value above 0.5 is taken for millimetres and refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .errors import FatalError

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".ppm", ".pgm", ".tif", ".tiff")


@dataclass(frozen=True)
class Board:
    """A chessboard: inner corners per row (cols) and per column (rows), square side in metres."""

    cols: int
    rows: int
    square_m: float

    def object_points(self) -> np.ndarray:
        """The inner corners in board coordinates [m], row-major, z = 0 (float32, N x 3)."""
        grid = np.mgrid[0 : self.cols, 0 : self.rows].T.reshape(-1, 2)
        pts = np.zeros((self.cols * self.rows, 3), np.float32)
        pts[:, :2] = grid * self.square_m
        return pts


def parse_board(text: str, square_m: float) -> Board:
    """``"9x6"`` and the square size -> Board; FatalError naming the option and its valid range."""
    try:
        cols_s, rows_s = text.lower().split("x")
        cols, rows = int(cols_s), int(rows_s)
    except ValueError as exc:
        raise FatalError(f"--board must be COLSxROWS inner corners, e.g. 9x6 (got {text!r})") from exc
    if not (3 <= cols <= 60 and 3 <= rows <= 60):
        raise FatalError(f"--board {text}: inner corners per side must be in [3, 60]")
    if cols == rows:
        raise FatalError(
            f"--board {text}: a square board's orientation is ambiguous (the two cameras may number its "
            "corners differently); use a board with unequal sides, e.g. 9x6"
        )
    if not (square_m > 0 and math.isfinite(square_m)):
        raise FatalError(f"--square must be > 0 metres (got {square_m})")
    if square_m > 0.5:
        raise FatalError(
            f"--square is in METRES and must be in (0, 0.5] (got {square_m}; a 25 mm square is 0.025)"
        )
    return Board(cols, rows, float(square_m))


@dataclass
class PairFiles:
    name: str
    left: Path
    right: Path


def find_pairs(folder: Path) -> list[PairFiles]:
    """The image pairs of a capture folder (``left/`` and ``right/``, same names), in name order.

    FatalError when a side folder is missing, a left image has no right partner (or the reverse),
    or there is no image at all — nothing is silently skipped.
    """
    folder = Path(folder)
    sides = {}
    for side in ("left", "right"):
        d = folder / side
        if not d.is_dir():
            raise FatalError(f"{folder}: no '{side}/' folder (expected a 'fuzzystereo capture' recording)")
        sides[side] = {p.name: p for p in d.iterdir() if p.suffix.lower() in IMAGE_EXTENSIONS}
    only_left = sorted(set(sides["left"]) - set(sides["right"]))
    only_right = sorted(set(sides["right"]) - set(sides["left"]))
    if only_left:
        raise FatalError(f"{folder / 'left' / only_left[0]} has no partner in {folder / 'right'}")
    if only_right:
        raise FatalError(f"{folder / 'right' / only_right[0]} has no partner in {folder / 'left'}")
    if not sides["left"]:
        raise FatalError(f"{folder}: no images in left/ and right/ ({', '.join(IMAGE_EXTENSIONS)})")
    return [PairFiles(n, sides["left"][n], sides["right"][n]) for n in sorted(sides["left"])]


def read_grey(path: Path) -> np.ndarray:
    """An image file as 8-bit grey; FatalError naming the file when it cannot be read."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise FatalError(f"cannot read image {path}")
    return img


def detect_corners(grey: np.ndarray, board: Board) -> np.ndarray | None:
    """The board's inner corners (float32, N x 1 x 2, row-major as Board.object_points) or None."""
    import cv2

    size = (board.cols, board.rows)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(grey, size, flags=flags)
    if found:
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
        corners = cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1), crit)
    else:
        found, corners = cv2.findChessboardCornersSB(grey, size, flags=cv2.CALIB_CB_ACCURACY)
        if not found:
            return None
    corners = np.asarray(corners, np.float32).reshape(-1, 1, 2)
    # Both detectors may start the numbering at either end of the board; make it canonical (the
    # first corner is the one nearest the image's top-left) so left and right views agree.
    if corners[0, 0, 0] + corners[0, 0, 1] > corners[-1, 0, 0] + corners[-1, 0, 1]:
        corners = corners[::-1].copy()
    return corners


@dataclass
class ViewError:
    name: str
    left_px: float
    right_px: float


@dataclass
class StereoCalibration:
    image_size: tuple[int, int]  # (width, height)
    K1: np.ndarray
    D1: np.ndarray
    K2: np.ndarray
    D2: np.ndarray
    R: np.ndarray
    T: np.ndarray  # 3 x 1, metres
    rms_px: float  # stereoCalibrate's RMS reprojection error
    epipolar_rms_px: float  # rectified |y_l - y_r| RMS over all corners
    epipolar_max_px: float
    focal_rect_px: float  # P1[0, 0] of the rectified pair (alpha 0)
    views: list[ViewError] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)  # (name, reason)
    dropped: list[str] = field(default_factory=list)  # views removed by max_view_error
    rect: tuple[np.ndarray, ...] = ()  # R1, R2, P1, P2 of the rectification (alpha 0)
    corners_left: list[np.ndarray] = field(default_factory=list)  # per used view, N x 1 x 2
    corners_right: list[np.ndarray] = field(default_factory=list)
    coverage_left: float = 0.0  # share of a 4 x 4 grid's cells holding a corner
    coverage_right: float = 0.0

    @property
    def baseline_m(self) -> float:
        return float(np.linalg.norm(self.T))


COVERAGE_GRID = (4, 4)
COVERAGE_WARN = 0.6


def coverage(corners: Sequence[np.ndarray], size: tuple[int, int], grid: tuple[int, int] = COVERAGE_GRID) -> float:
    """Share of the cells of a ``grid`` (columns, rows) over an image of ``size`` (width, height) that
    hold at least one corner."""
    gx, gy = grid
    hit = np.zeros((gy, gx), bool)
    for c in corners:
        p = np.asarray(c, float).reshape(-1, 2)
        ix = np.clip((p[:, 0] * gx / size[0]).astype(int), 0, gx - 1)
        iy = np.clip((p[:, 1] * gy / size[1]).astype(int), 0, gy - 1)
        hit[iy, ix] = True
    return float(hit.mean())


def _calibrate(obj, pts_l, pts_r, size):
    import cv2

    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-9)
    _, K1, D1, _, _ = cv2.calibrateCamera(obj, pts_l, size, None, None, criteria=crit)
    _, K2, D2, _, _ = cv2.calibrateCamera(obj, pts_r, size, None, None, criteria=crit)
    rms, K1, D1, K2, D2, R, T, _, _, rvecs, tvecs, per_view = cv2.stereoCalibrateExtended(
        obj, pts_l, pts_r, K1, D1, K2, D2, size, None, None,
        flags=cv2.CALIB_USE_INTRINSIC_GUESS, criteria=crit,
    )
    return float(rms), K1, D1, K2, D2, R, T.reshape(3, 1), np.asarray(per_view, float).reshape(-1, 2)


def _rectify(K1, D1, K2, D2, R, T, size) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """R1, R2, P1, P2 of ``cv2.stereoRectify`` as the firmware's Rectifier computes them (zero
    disparity, alpha 0)."""
    import cv2

    R1, R2, P1, P2, _, _, _ = cv2.stereoRectify(K1, D1, K2, D2, size, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    return R1, R2, P1, P2


def calibrate_folder(
    folder: Path,
    board: Board,
    *,
    min_pairs: int = 8,
    max_view_error: float | None = None,
    progress: Callable[[str], None] | None = None,
) -> StereoCalibration:
    """Calibrate the stereo pair from the chessboard pairs in ``folder`` (see the module docstring)."""
    import cv2

    pairs = find_pairs(folder)
    size: tuple[int, int] | None = None
    names: list[str] = []
    pts_l: list[np.ndarray] = []
    pts_r: list[np.ndarray] = []
    skipped: list[tuple[str, str]] = []
    for pf in pairs:
        gl, gr = read_grey(pf.left), read_grey(pf.right)
        if gl.shape != gr.shape:
            raise FatalError(f"{pf.left} is {gl.shape[1]}x{gl.shape[0]} but {pf.right} is {gr.shape[1]}x{gr.shape[0]}")
        this = (gl.shape[1], gl.shape[0])
        if size is None:
            size = this
        elif this != size:
            raise FatalError(f"{pf.left} is {this[0]}x{this[1]}, the pairs before it {size[0]}x{size[1]}")
        cl = detect_corners(gl, board)
        cr = detect_corners(gr, board) if cl is not None else None  # the pair is lost anyway
        if cl is None or cr is None:
            side = "left view" if cl is None else "right view"
            skipped.append((pf.name, f"no {board.cols}x{board.rows} board in the {side}"))
        else:
            names.append(pf.name)
            pts_l.append(cl)
            pts_r.append(cr)
        if progress:
            progress(pf.name)
    assert size is not None
    if len(names) < min_pairs:
        raise FatalError(
            f"{folder}: the {board.cols}x{board.rows} board (inner corners) was found in both views of "
            f"{len(names)} of {len(pairs)} pairs; at least {min_pairs} are needed (check --board: count "
            "INNER corners; hold the whole board in both views at many poses)"
        )
    obj = [board.object_points() for _ in names]
    rms, K1, D1, K2, D2, R, T, per_view = _calibrate(obj, pts_l, pts_r, size)
    dropped: list[str] = []
    # Step 4: one bad view (a mis-detection, a pair not taken at the same instant) pulls every
    # parameter and so every view's error, so views go one at a time, the worst first.
    while max_view_error is not None and per_view.max() > max_view_error:
        worst = int(np.argmax(per_view.max(axis=1)))
        if len(names) - 1 < min_pairs:
            raise FatalError(
                f"views keep exceeding --max-view-error {max_view_error} px after dropping {len(dropped)} "
                f"({', '.join(dropped) or 'none'}); {len(names) - 1} would be left, at least {min_pairs} are needed; "
                f"the worst now: {names[worst]} {per_view[worst].max():.2f} px"
            )
        dropped.append(names.pop(worst))
        pts_l.pop(worst)
        pts_r.pop(worst)
        obj.pop()
        rms, K1, D1, K2, D2, R, T, per_view = _calibrate(obj, pts_l, pts_r, size)
    if T[0, 0] > 0:
        raise FatalError(
            f"the calibrated T.x is {T[0, 0]:+.4f} m > 0: the 'left' images come from the right camera "
            "(swap the cameras or the left/ and right/ folders)"
        )
    # Step 5: rows of every corner pair after rectification
    rect = _rectify(K1, D1, K2, D2, R, T, size)
    R1, R2, P1, P2 = rect
    dy = np.concatenate([
        cv2.undistortPoints(pl, K1, D1, R=R1, P=P1).reshape(-1, 2)[:, 1]
        - cv2.undistortPoints(pr, K2, D2, R=R2, P=P2).reshape(-1, 2)[:, 1]
        for pl, pr in zip(pts_l, pts_r)
    ])
    return StereoCalibration(
        image_size=size, K1=K1, D1=D1, K2=K2, D2=D2, R=R, T=T, rms_px=rms,
        epipolar_rms_px=float(np.sqrt(np.mean(dy**2))), epipolar_max_px=float(np.max(np.abs(dy))),
        focal_rect_px=float(P1[0, 0]),
        views=[ViewError(n, float(e[0]), float(e[1])) for n, e in zip(names, per_view)],
        skipped=skipped, dropped=dropped, corners_left=pts_l, corners_right=pts_r,
        coverage_left=coverage(pts_l, size), coverage_right=coverage(pts_r, size), rect=rect,
    )


def write_calibration(path: Path, cal: StereoCalibration, *, height_m: float | None = None,
                      pitch_deg: float | None = None) -> None:
    """Write ``cal`` as the firmware's calibration file (OpenCV FileStorage YAML, docs/capture.md)."""
    import cv2

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    if not fs.isOpened():
        raise FatalError(f"cannot write {path}")
    try:
        fs.write("image_width", int(cal.image_size[0]))
        fs.write("image_height", int(cal.image_size[1]))
        for key in ("K1", "D1", "K2", "D2", "R", "T"):
            fs.write(key, np.asarray(getattr(cal, key), np.float64))
        if height_m is not None:
            fs.write("height_m", float(height_m))
        if pitch_deg is not None:
            fs.write("pitch_deg", float(pitch_deg))
        fs.write("rms_px", cal.rms_px)
        fs.write("epipolar_rms_px", cal.epipolar_rms_px)
        fs.write("views", len(cal.views))
    finally:
        fs.release()


def rectified_preview(cal: StereoCalibration, pair: PairFiles, lines: int = 16) -> np.ndarray:
    """One pair rectified with ``cal`` side by side (BGR), with horizontal lines: a feature must sit
    on the same line in both halves."""
    import cv2

    size = cal.image_size
    R1, R2, P1, P2 = cal.rect
    halves = []
    for img_path, K, D, Rr, P in ((pair.left, cal.K1, cal.D1, R1, P1), (pair.right, cal.K2, cal.D2, R2, P2)):
        img = cv2.imread(str(img_path), cv2.IMREAD_COLOR)
        if img is None:
            raise FatalError(f"cannot read image {img_path}")
        m1, m2 = cv2.initUndistortRectifyMap(K, D, Rr, P, size, cv2.CV_16SC2)
        halves.append(cv2.remap(img, m1, m2, cv2.INTER_LINEAR))
    out = np.hstack(halves)
    h = out.shape[0]
    for i in range(1, lines):
        y = int(round(i * h / lines))
        cv2.line(out, (0, y), (out.shape[1] - 1, y), (0, 255, 0) if i % 2 else (0, 0, 255), 1)
    return out


def write_preview(path: Path, cal: StereoCalibration, pair: PairFiles) -> None:
    """``rectified_preview`` as a PNG file."""
    import cv2

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), rectified_preview(cal, pair)):
        raise FatalError(f"cannot write {path}")


def pair_by_name(folder: Path, name: str | None) -> PairFiles:
    """The pair called ``name`` (the first when None) of a capture folder."""
    pairs = find_pairs(folder)
    if name is None:
        return pairs[0]
    for p in pairs:
        if p.name == name:
            return p
    raise FatalError(f"{folder}: no pair named {name}")


def summary_lines(cal: StereoCalibration) -> Sequence[str]:
    """Human-readable figures of a calibration (what the CLI prints)."""
    fx1, fy1, cx1, cy1 = cal.K1[0, 0], cal.K1[1, 1], cal.K1[0, 2], cal.K1[1, 2]
    fx2, fy2, cx2, cy2 = cal.K2[0, 0], cal.K2[1, 1], cal.K2[0, 2], cal.K2[1, 2]
    return [
        f"image {cal.image_size[0]}x{cal.image_size[1]}, {len(cal.views)} views used, "
        f"{len(cal.skipped)} skipped, {len(cal.dropped)} dropped",
        f"left  fx {fx1:.2f} fy {fy1:.2f} cx {cx1:.2f} cy {cy1:.2f} D {np.array2string(cal.D1.ravel(), precision=4)}",
        f"right fx {fx2:.2f} fy {fy2:.2f} cx {cx2:.2f} cy {cy2:.2f} D {np.array2string(cal.D2.ravel(), precision=4)}",
        f"baseline {cal.baseline_m * 1000:.2f} mm, T {np.array2string(cal.T.ravel(), precision=4)} m, "
        f"rectified f {cal.focal_rect_px:.2f} px",
        f"RMS reprojection {cal.rms_px:.3f} px; rectified epipolar error RMS {cal.epipolar_rms_px:.3f} px, "
        f"max {cal.epipolar_max_px:.3f} px",
        f"corner coverage (4 x 4 grid): left {100 * cal.coverage_left:.0f} %, right {100 * cal.coverage_right:.0f} %",
    ] + ([
        f"WARNING: corners cover under {100 * COVERAGE_WARN:.0f} % of an image: the lens distortion is extrapolated "
        "towards its corners; add pairs with the board near the image corners and edges"
    ] if min(cal.coverage_left, cal.coverage_right) < COVERAGE_WARN else [])


def write_report(path: Path, cal: StereoCalibration, preview_pair: PairFiles | None = None) -> Path:
    """One HTML page: the figures, the per-view errors, where the corners were, a rectified pair."""
    import html

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .report import figure_data_uri, image_data_uri

    names = [v.name for v in cal.views]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.35 * len(names)), 3.2))
    x = np.arange(len(names))
    ax.bar(x - 0.2, [v.left_px for v in cal.views], 0.4, label="left")
    ax.bar(x + 0.2, [v.right_px for v in cal.views], 0.4, label="right")
    ax.set_xticks(x, names, rotation=90, fontsize=7)
    ax.set_ylabel("RMS reprojection error [px]")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", alpha=0.3)
    errors = figure_data_uri(fig)

    w, h = cal.image_size
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.9))
    for a, corners, cov, side in ((axes[0], cal.corners_left, cal.coverage_left, "left"),
                                  (axes[1], cal.corners_right, cal.coverage_right, "right")):
        for i, c in enumerate(corners):
            p = np.asarray(c).reshape(-1, 2)
            a.plot(p[:, 0], p[:, 1], ".", ms=2, color=plt.cm.tab20(i % 20))
        for k in range(1, COVERAGE_GRID[0]):
            a.axvline(k * w / COVERAGE_GRID[0], color="0.8", lw=0.8)
        for k in range(1, COVERAGE_GRID[1]):
            a.axhline(k * h / COVERAGE_GRID[1], color="0.8", lw=0.8)
        a.set_xlim(0, w)
        a.set_ylim(h, 0)
        a.set_aspect("equal")
        a.set_title(f"{side} camera: corners of every view, coverage {100 * cov:.0f} %", fontsize=9)
    cover = figure_data_uri(fig)

    preview = ""
    if preview_pair is not None:
        preview = ("<h2>A pair rectified with this calibration</h2><p>Every feature must lie on the same row in "
                   f"both halves (the lines help the eye).</p><img src='{image_data_uri(rectified_preview(cal, preview_pair))}'>")
    rows = "".join(f"<li>{html.escape(line)}</li>" for line in summary_lines(cal))
    skipped = "".join(f"<li>{html.escape(n)}: {html.escape(r)}</li>" for n, r in cal.skipped)
    parts = [
        "<!doctype html><meta charset='utf-8'><title>fuzzystereo calibration</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}img{max-width:100%}</style>",
        "<h1>Stereo calibration</h1>",
        f"<ul>{rows}</ul>",
        f"<h2>Per view</h2><img src='{errors}'>",
        f"<h2>Where the corners were</h2><img src='{cover}'>",
        preview,
    ]
    if skipped:
        parts.append(f"<h2>Skipped pairs</h2><ul>{skipped}</ul>")
    if cal.dropped:
        parts.append(f"<p>Dropped (reprojection error above --max-view-error): {html.escape(', '.join(cal.dropped))}</p>")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
