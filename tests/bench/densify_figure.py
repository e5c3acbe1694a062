#!/usr/bin/env python3
"""Before / after figure of the densify stage on one KITTI frame (docs/algorithm.md 6d).

Runs `fuzzystereo match` twice on KITTI 2015 000046 — with `[densify] occlusion_fill = false,
smooth = false` (session 17's output) and with the defaults — and writes one JPEG: the colour-mapped
disparity of each beside its error map (bad-2 pixels red, the rest of the ground truth green).

  .venv/bin/python tests/bench/densify_figure.py [--dataset DIR] [--out docs/img/densify_kitti2015_000046.jpg]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def match(binary: Path, left: Path, right: Path, out: Path, config: Path | None, max_disparity: int = 160) -> np.ndarray:
    cmd = [str(binary), "match", "--left", str(left), "--right", str(right), "--max-disparity", str(max_disparity),
           "--out", str(out)]
    if config is not None:
        cmd += ["--config", str(config)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"{Path(sys.argv[0]).name}: {' '.join(cmd)} failed:\n{proc.stderr}")
    return cv2.imread(str(out / "disp_left.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 256


def colour(d: np.ndarray, vmax: float) -> np.ndarray:
    return cv2.applyColorMap(np.clip(d / vmax * 255, 0, 255).astype(np.uint8), cv2.COLORMAP_TURBO)


def errors(d: np.ndarray, gt: np.ndarray, img: np.ndarray) -> np.ndarray:
    """The left image dimmed, ground-truth pixels within 2 px green, the others red."""
    valid = gt > 0
    e = np.abs(d - gt)
    v = (img * 0.35).astype(np.uint8)
    v[valid & (e <= 2)] = (0, 170, 0)
    v[valid & (e > 2)] = (0, 0, 255)
    return v


def label(im: np.ndarray, text: str) -> np.ndarray:
    im = im.copy()
    cv2.putText(im, text, (10, 28), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (255, 255, 255), 2, cv2.LINE_AA)
    return im


def figure(rows_in: list[tuple[str, np.ndarray]], gt: np.ndarray, img: np.ndarray, out_path: str, shrink: int = 2) -> None:
    """One row per (name, disparity map): its colours beside its bad-2 map; scores printed and written."""
    valid = gt > 0
    vmax = float(np.percentile(gt[valid], 99))
    rows = []
    for name, d in rows_in:
        e = np.abs(d - gt)[valid]
        rows.append(np.hstack([label(colour(d, vmax), f"{name}: avg {e.mean():.3f} px, bad-2 {100 * (e > 2).mean():.2f} %"),
                               label(errors(d, gt, img), "bad-2 pixels red, the rest of the ground truth green")]))
        print(f"{name}: avg {e.mean():.3f} px, bad-2 {100 * (e > 2).mean():.2f} %")
    out = np.vstack(rows)
    out = cv2.resize(out, (out.shape[1] // shrink, out.shape[0] // shrink), interpolation=cv2.INTER_AREA)
    cv2.imwrite(out_path, out, [cv2.IMWRITE_JPEG_QUALITY, 80])
    print(f"wrote {out_path}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default=os.environ.get("FUZZYSTEREO_DATASETS", str(ROOT.parent / "shared" / "datasets")))
    ap.add_argument("--binary", default=str(ROOT / "build" / "default" / "fuzzystereo"))
    ap.add_argument("--out", default=str(ROOT / "docs" / "img" / "densify_kitti2015_000046.jpg"))
    a = ap.parse_args()
    k = Path(a.dataset) / "kitti2015" / "training"
    left, right, gtp = k / "image_2" / "000046_10.png", k / "image_3" / "000046_10.png", k / "disp_occ_0" / "000046_10.png"
    for p in (left, right, gtp):
        if not p.is_file():
            print(f"densify_figure: {p} not found (set --dataset or FUZZYSTEREO_DATASETS)", file=sys.stderr)
            return 2
    gt = cv2.imread(str(gtp), cv2.IMREAD_UNCHANGED).astype(np.float32) / 256
    img = cv2.imread(str(left))
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        cfg = t / "before.toml"
        cfg.write_text("[densify]\nocclusion_fill = false\nsmooth = false\n")
        before = match(Path(a.binary), left, right, t / "before", cfg)
        after = match(Path(a.binary), left, right, t / "after", None)
    figure([("median fill only (session 17)", before), ("+ occlusion fill + smoothing (defaults)", after)], gt, img, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
