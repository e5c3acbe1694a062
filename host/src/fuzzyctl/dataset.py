"""Stereo evaluation datasets: layout detection and ground-truth decoding, as the firmware does it.

A line-by-line twin of ``firmware/app/dataset.cpp`` (same layouts, detector order, scan depth,
sort order, per-layout search range and GT scale), so ``fuzzyctl`` visits the same frames with the
same ground truth as ``fuzzystereo eval``. Layouts (official archive folder names):

  KITTI 2012         training/{colored_0,colored_1 | image_0,image_1}/NNNNNN_10.png, disp_occ/
  KITTI 2015         training/{image_2,image_3}/NNNNNN_10.png, disp_occ_0/
  synthetic          fuzzystereo_sim.json + training/ in the KITTI 2015 layout (sim generate)
  Middlebury 2001-3  <scene>/{im3,im4}.png + disp3.pgm (/16, tsukuba); {im2,im6}.png + disp2.pgm
                     (/8, venus); {im2,im6}.png + disp2.png (/4, teddy, cones)
  Middlebury 2005-6  {ThirdSize,HalfSize,FullSize}/<scene>/{view1,view5}.png + disp1.png
                     (stored value = full-size disparity, so /3, /2, /1)
  Middlebury 2014    MiddEval3/training{Q,H,F}/<scene>/{im0,im1}.png + disp0GT.pfm + calib.txt

Ground-truth convention: float32 (H, W) disparity [px] of the left image, **0 = no ground truth**
(KITTI 0, Middlebury 8-bit 0 and MiddEval3 inf all map to 0). Decoding is done in float32 exactly
as OpenCV's ``convertTo(CV_32F, 1 / divisor)`` does it (value * float32(1 / divisor)).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .errors import FatalError

# Disparity search ranges per layout (dataset.cpp kMaxDisp*): fixed per scene type, never from GT.
MAX_DISP_KITTI = 160
MAX_DISP_TSUKUBA = 16
MAX_DISP_VENUS = 32
MAX_DISP_TEDDY_CONES = 64
MAX_DISP_2006_THIRD = 80
MAX_DISP_2006_HALF = 128
MAX_DISP_2006_FULL = 256

LAYOUTS_LOOKED_FOR = (
    "KITTI 2012 (colored_0|image_0, colored_1|image_1, disp_occ), "
    "KITTI 2015 (image_2, image_3, disp_occ_0), "
    "Middlebury 2001-3 (im3/im4 + disp3.pgm, im2/im6 + disp2.pgm|disp2.png), "
    "Middlebury 2005-6 ({ThirdSize,HalfSize,FullSize}/<scene>/view1, view5, disp1.png), "
    "Middlebury 2014 (MiddEval3/training{Q,H,F}/<scene>/im0, im1, calib.txt, disp0GT.pfm), "
    "synthetic (fuzzystereo_sim.json + training/image_2, image_3, disp_occ_0)"
)

MAX_SCAN_DEPTH = 6

#: GT encodings (dataset.hpp GtEncoding)
GT_NONE, GT_PNG16, GT_PNG8, GT_PFM = "none", "png16", "png8", "pfm"
NOC_NONE, NOC_KITTI, NOC_MASK = "none", "kitti", "mask"


@dataclass(frozen=True)
class Frame:
    set: str  # "kitti2012", "middlebury2001-3", "middlebury2006-third", "middlebury2014-Q" ...
    name: str  # "000046", "tsukuba", "Aloe", "Motorcycle"
    left_path: str
    right_path: str
    gt_path: str = ""
    gt_encoding: str = GT_NONE
    gt_divisor: float = 1.0
    max_disparity: int = 64  # disparities searched: 0 .. max_disparity - 1
    # Non-occluded pixels, where the set ships them: NOC_KITTI (disp_noc[_0], > 0 = non-occluded) or
    # NOC_MASK (MiddEval3 mask0nocc.png, 255 = non-occluded); NOC_NONE elsewhere.
    noc_path: str = ""
    noc_encoding: str = NOC_NONE

    @property
    def has_gt(self) -> bool:
        return self.gt_encoding != GT_NONE

    @property
    def has_noc(self) -> bool:
        return self.noc_encoding != NOC_NONE

    @property
    def key(self) -> str:
        return f"{self.set}/{self.name}"


def round_up_16(n: int) -> int:
    return max(16, (n + 15) // 16 * 16)


def _files_ending(d: Path, suffix: str) -> list[Path]:
    try:
        entries = list(d.iterdir())
    except OSError:
        return []
    return sorted(p for p in entries if p.is_file() and len(p.name) > len(suffix) and p.name.endswith(suffix))


def _png_width(p: Path) -> int:
    """Width from the PNG IHDR chunk, 0 when unreadable (tells 2005-6 resolutions apart)."""
    try:
        with open(p, "rb") as f:
            h = f.read(24)
    except OSError:
        return 0
    if len(h) < 24 or h[1:4] != b"PNG":
        return 0
    return struct.unpack(">I", h[16:20])[0]


def _frame_id(image: Path) -> str:
    stem = image.stem  # "000046_10"
    return stem[: stem.rfind("_")] if "_" in stem else stem


def _detect_kitti(d: Path, set_name: str, ldir: str, rdir: str, gtdir: str, nocdir: str) -> list[Frame]:
    frames = []
    for left in _files_ending(d / ldir, "_10.png"):
        right = d / rdir / left.name
        if not right.is_file():
            continue
        gt = d / gtdir / left.name
        has = gt.is_file()
        noc = d / nocdir / left.name
        has_noc = has and noc.is_file()
        frames.append(Frame(set_name, _frame_id(left), str(left), str(right), str(gt) if has else "",
                            GT_PNG16 if has else GT_NONE, 256.0, MAX_DISP_KITTI,
                            str(noc) if has_noc else "", NOC_KITTI if has_noc else NOC_NONE))
    return frames


def _detect_kitti2015(d: Path) -> list[Frame] | None:
    if not (d / "image_2").is_dir() or not (d / "image_3").is_dir():
        return None
    return _detect_kitti(d, "kitti2015", "image_2", "image_3", "disp_occ_0", "disp_noc_0")


def _detect_kitti2012(d: Path) -> list[Frame] | None:
    colour = (d / "colored_0").is_dir() and (d / "colored_1").is_dir()
    grey = (d / "image_0").is_dir() and (d / "image_1").is_dir()
    if not colour and not grey:
        return None
    return _detect_kitti(d, "kitti2012", "colored_0" if colour else "image_0", "colored_1" if colour else "image_1", "disp_occ",
                         "disp_noc")


def _detect_middlebury2001_3(d: Path) -> list[Frame] | None:
    variants = (
        ("im3.png", "im4.png", "disp3.pgm", 16.0, MAX_DISP_TSUKUBA),
        ("im2.png", "im6.png", "disp2.pgm", 8.0, MAX_DISP_VENUS),
        ("im2.png", "im6.png", "disp2.png", 4.0, MAX_DISP_TEDDY_CONES),
    )
    for left, right, gt, divisor, max_disp in variants:
        if (d / left).is_file() and (d / right).is_file() and (d / gt).is_file():
            return [Frame("middlebury2001-3", d.name, str(d / left), str(d / right), str(d / gt), GT_PNG8, divisor, max_disp)]
    return None


def _detect_middlebury2005_6(d: Path) -> list[Frame] | None:
    if not (d / "view1.png").is_file() or not (d / "view5.png").is_file():
        return None
    divisor = {"ThirdSize": 3, "HalfSize": 2, "FullSize": 1}.get(d.parent.name, 0)
    if divisor == 0:  # folder name does not say: ThirdSize widths 413-465, HalfSize 626-695, FullSize 1240-1390
        w = _png_width(d / "view1.png")
        divisor = 0 if w <= 0 else (3 if w < 560 else 2 if w < 1000 else 1)
    if divisor == 0:
        return None
    set_name = {3: "middlebury2006-third", 2: "middlebury2006-half", 1: "middlebury2006-full"}[divisor]
    max_disp = {3: MAX_DISP_2006_THIRD, 2: MAX_DISP_2006_HALF, 1: MAX_DISP_2006_FULL}[divisor]
    gt = d / "disp1.png"
    has = gt.is_file()
    return [Frame(set_name, d.name, str(d / "view1.png"), str(d / "view5.png"), str(gt) if has else "",
                  GT_PNG8 if has else GT_NONE, float(divisor), max_disp)]


def parse_middlebury2014_ndisp(text: str) -> int:
    """``ndisp=N`` of a MiddEval3 calib.txt (0 when absent); keys are not stripped, as in the firmware."""
    ndisp = 0
    for line in text.splitlines():
        key, eq, val = line.partition("=")
        if eq and key == "ndisp":
            m = re.match(r"\s*([+-]?\d+)", val)
            ndisp = int(m.group(1)) if m else 0
    return ndisp


def _detect_middlebury2014(d: Path) -> list[Frame] | None:
    if not all((d / f).is_file() for f in ("im0.png", "im1.png", "calib.txt")):
        return None
    ndisp = parse_middlebury2014_ndisp((d / "calib.txt").read_text(errors="replace"))
    if ndisp <= 0:
        raise FatalError(f"Middlebury 2014 calibration '{d / 'calib.txt'}' has no ndisp=N line (N > 0)")
    res = d.parent.name[-1:] or "?"
    if res not in ("Q", "H", "F"):
        w = _png_width(d / "im0.png")
        res = "Q" if w < 1000 else "H" if w < 2000 else "F"
    gt = d / "disp0GT.pfm"
    has = gt.is_file()
    noc = d / "mask0nocc.png"
    has_noc = has and noc.is_file()
    return [Frame(f"middlebury2014-{res}", d.name, str(d / "im0.png"), str(d / "im1.png"), str(gt) if has else "",
                  GT_PFM if has else GT_NONE, 1.0, round_up_16(ndisp), str(noc) if has_noc else "",
                  NOC_MASK if has_noc else NOC_NONE)]


SIM_MARKER = "fuzzystereo_sim.json"


def _detect_synthetic(d: Path) -> list[Frame] | None:
    """A set written by ``fuzzystereo sim generate``: ``d`` holds the marker (frames in its
    training/, KITTI 2015 layout) or ``d`` is that training/ folder (firmware dataset.cpp)."""
    import dataclasses
    import json

    marker, training = d / SIM_MARKER, d / "training"
    if not marker.is_file() and d.name == "training" and (d.parent / SIM_MARKER).is_file():
        marker, training = d.parent / SIM_MARKER, d
    if not marker.is_file():
        return None
    try:
        max_disp = int(json.loads(marker.read_text())["max_disparity"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise FatalError(f"synthetic set marker '{marker}' is not valid: {exc}") from exc
    if max_disp < 16 or max_disp % 16:
        raise FatalError(f"synthetic set marker '{marker}': max_disparity = {max_disp} is not valid (a multiple of 16, >= 16)")
    frames = _detect_kitti2015(training) or []
    return [dataclasses.replace(f, set="synthetic", max_disparity=max_disp) for f in frames]


_DETECTORS = (_detect_synthetic, _detect_kitti2015, _detect_kitti2012, _detect_middlebury2014, _detect_middlebury2005_6, _detect_middlebury2001_3)


def _scan(d: Path, depth: int, out: list[Frame]) -> None:
    for det in _DETECTORS:
        frames = det(d)
        if frames is not None:
            out.extend(frames)
            return  # a layout's folder is not searched further
    if depth >= MAX_SCAN_DEPTH:
        return
    try:
        subdirs = sorted(p for p in d.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError:
        return
    for s in subdirs:
        _scan(s, depth + 1, out)


def discover(root: str | Path) -> list[Frame]:
    """Every frame of every known layout under ``root`` (datasets root, one set's folder or one
    scene folder), sorted by (set, name); FatalError when ``root`` is missing or holds no known
    layout (the message lists the layouts looked for)."""
    root = Path(root)
    if not root.is_dir():
        raise FatalError(f"dataset directory '{root}' does not exist or is not a directory")
    frames: list[Frame] = []
    _scan(root, 0, frames)
    if not frames:
        raise FatalError(f"unknown dataset layout: no stereo frames found under '{root}'; layouts looked for: {LAYOUTS_LOOKED_FOR}")
    return sorted(frames, key=lambda f: (f.set, f.name))  # stable, like std::stable_sort


def select(frames: list[Frame], limit: int = 0, need_gt: bool = True, skipped: list[str] | None = None) -> list[Frame]:
    """Frames with ground truth (when ``need_gt``), at most ``limit`` per set (0 = all), as eval picks them."""
    per_set: dict[str, int] = {}
    out = []
    for f in frames:
        if need_gt and not f.has_gt:
            if skipped is not None:
                skipped.append(f"{f.key} (no ground truth)")
            continue
        if limit > 0 and per_set.get(f.set, 0) >= limit:
            continue
        per_set[f.set] = per_set.get(f.set, 0) + 1
        out.append(f)
    return out


# ---- ground truth ---------------------------------------------------------------------------------


def read_pfm(path: str | Path) -> np.ndarray:
    """PFM ("Pf" grey or "PF" colour -> first channel, either endianness) as float32, top row first;
    values as stored (inf stays inf). FatalError naming the file."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FatalError(f"cannot open PFM file '{path}': {exc.strerror}") from exc
    # header: magic, width, height, scale as whitespace-separated tokens, then one whitespace char
    m = re.match(rb"\s*(\S+)\s+(\S+)\s+(\S+)\s+(\S+)", data)
    try:
        magic, w, h, scale = m.group(1).decode(), int(m.group(2)), int(m.group(3)), float(m.group(4))  # type: ignore[union-attr]
    except (AttributeError, ValueError, UnicodeDecodeError):
        raise FatalError(f"'{path}' is not a valid PFM file (bad header)") from None
    if magic not in ("Pf", "PF") or w <= 0 or h <= 0 or scale == 0.0 or w > 1 << 16 or h > 1 << 16:
        raise FatalError(f"'{path}' is not a valid PFM file (bad header)")
    start = m.end() + 1  # type: ignore[union-attr]
    channels = 3 if magic == "PF" else 1
    count = w * h * channels
    if len(data) - start < count * 4:
        raise FatalError(f"PFM file '{path}' is truncated")
    raw = np.frombuffer(data, dtype="<f4" if scale < 0 else ">f4", count=count, offset=start)
    return np.ascontiguousarray(raw.reshape(h, w, channels)[::-1, :, 0]).astype(np.float32)


def load_ground_truth(frame: Frame) -> np.ndarray:
    """The frame's GT, float32 (H, W) [px], 0 = unknown; FatalError naming the file."""
    p = frame.gt_path
    if frame.gt_encoding == GT_NONE:
        raise FatalError(f"frame {frame.key} has no ground truth")
    if frame.gt_encoding == GT_PFM:
        gt = read_pfm(p)
        return np.where(np.isfinite(gt), gt, np.float32(0.0)).astype(np.float32)
    raw = cv2.imread(p, cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise FatalError(f"cannot read ground truth '{p}'")
    if frame.gt_encoding == GT_PNG16:
        if raw.dtype != np.uint16 or raw.ndim != 2:
            raise FatalError(f"ground truth '{p}' is not a 16-bit single-channel PNG (KITTI encoding)")
    else:
        if raw.dtype != np.uint8:
            raise FatalError(f"ground truth '{p}' is not an 8-bit image")
        if raw.ndim == 3:
            raw = raw[:, :, 0]
    # OpenCV convertTo(CV_32F, 1/divisor): float32 product with the float32 scale
    return raw.astype(np.float32) * np.float32(1.0 / frame.gt_divisor)


def load_nonoccluded_mask(frame: Frame) -> np.ndarray:
    """The frame's non-occluded pixels, bool (H, W); FatalError naming the file (as the firmware's)."""
    p = frame.noc_path
    if frame.noc_encoding == NOC_NONE:
        raise FatalError(f"frame {frame.key} has no non-occlusion mask")
    raw = cv2.imread(p, cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise FatalError(f"cannot read non-occlusion mask '{p}'")
    if raw.ndim != 2:
        raise FatalError(f"non-occlusion mask '{p}' is not a single-channel image")
    if frame.noc_encoding == NOC_KITTI:
        if raw.dtype != np.uint16:
            raise FatalError(f"non-occluded disparity '{p}' is not a 16-bit single-channel PNG (KITTI encoding)")
        return raw > 0
    if raw.dtype != np.uint8:
        raise FatalError(f"non-occlusion mask '{p}' is not an 8-bit image")
    return raw == 255


def describe(frames: list[Frame]) -> str:
    sets: dict[str, int] = {}
    for f in frames:
        sets[f.set] = sets.get(f.set, 0) + 1
    return ", ".join(f"{s} {n}" for s, n in sets.items())

