#!/usr/bin/env python3
"""Before / after figure of the segment-boundary refinement on MiddEval3 Motorcycle (docs/algorithm.md 4b).

Runs `fuzzystereo match` twice on Motorcycle (quarter size, D = 80) — the defaults and `[boundary]
enabled = true` (window 7, min_jump 1) — and writes one JPEG: the colour-mapped disparity of each beside
its error map (bad-2 pixels red, the rest of the ground truth green). The fattened rims round the
wheels, the fork and the frame are what the stage takes back.

  .venv/bin/python tests/bench/boundary_figure.py [--dataset DIR] [--out docs/img/boundary_motorcycle.jpg]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from densify_figure import ROOT, figure, match  # noqa: E402


def read_pfm(path: Path) -> np.ndarray:
    with open(path, "rb") as f:
        f.readline()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        a = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4").reshape(h, w)[::-1]
    return np.where(np.isfinite(a), a, 0).astype(np.float32)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default=os.environ.get("FUZZYSTEREO_DATASETS", str(ROOT.parent / "shared" / "datasets")))
    ap.add_argument("--binary", default=str(ROOT / "build" / "default" / "fuzzystereo"))
    ap.add_argument("--out", default=str(ROOT / "docs" / "img" / "boundary_motorcycle.jpg"))
    a = ap.parse_args()
    m = Path(a.dataset) / "middlebury2014" / "MiddEval3" / "trainingQ" / "Motorcycle"
    left, right, gtp = m / "im0.png", m / "im1.png", m / "disp0GT.pfm"
    for p in (left, right, gtp):
        if not p.is_file():
            print(f"boundary_figure: {p} not found (set --dataset or FUZZYSTEREO_DATASETS)", file=sys.stderr)
            return 2
    gt = read_pfm(gtp)
    img = cv2.imread(str(left))
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        cfg = t / "boundary.toml"
        cfg.write_text("[boundary]\nenabled = true\nwindow = 7\nmin_jump = 1\n")
        before = match(Path(a.binary), left, right, t / "before", None, 80)
        after = match(Path(a.binary), left, right, t / "after", cfg, 80)
    figure([("defaults", before), ("[boundary] enabled", after)], gt, img, a.out, shrink=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
