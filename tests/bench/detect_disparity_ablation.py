#!/usr/bin/env python3
"""What the matcher's disparity errors cost the detector (docs/results-detection.md, session 16).

Runs `fuzzystereo detect-eval` on a generated set with disparity maps built from the ground truth
and the matcher's cached ESR maps, one property at a time:

  gt             the ground truth (= --oracle-disparity)
  round          the ground truth rounded to whole pixels (no sub-pixel)
  noise05        the ground truth + Gaussian noise, sigma 0.5 px
  gt_on_valid    the ground truth only where the matcher has a value (the matcher's density)
  m_err_lt1      the matcher where it is within 1 px of the truth, the truth elsewhere on its mask
  m_err_lt3      ... within 3 px
  matcher        the matcher's own maps
  holes_gt       the matcher's maps with the truth in their holes (what a perfect hole fill would give)
  holes_gt_road  ... the truth only in holes on the ground-truth road mask
  holes_gt_obst  ... only in holes on ground-truth obstacle pixels
  vfill32        the matcher's maps with vertical hole runs of <= 32 px filled with the smaller
                 of the two bounding values when they differ by <= 5 % (upright obstacles have
                 one disparity down a column; a prototype of a detector fill, session 17)

--variants picks some (comma-separated); default all.

Usage (after `fuzzystereo detect-eval --dataset SET --disparity-cache CACHE` has filled CACHE):
  .venv/bin/python tests/bench/detect_disparity_ablation.py --dataset SET --cache CACHE --work DIR
"""
from __future__ import annotations

import argparse
import glob
import os
import shutil
import subprocess
import sys

import cv2
import numpy as np


def vertical_fill(d: np.ndarray, max_run: int, rel_tol: float) -> np.ndarray:
    """Holes (d <= 0) in a column, at most max_run long, bounded above and below by valid values that
    differ by at most rel_tol of the larger, take the smaller bound."""
    d = d.copy()
    for x in range(d.shape[1]):
        col = d[:, x]
        idx = np.flatnonzero(col > 0)
        if len(idx) < 2:
            continue
        gaps = np.diff(idx)
        for i in np.flatnonzero((gaps > 1) & (gaps - 1 <= max_run)):
            a, b = idx[i], idx[i + 1]
            if abs(col[a] - col[b]) <= rel_tol * max(col[a], col[b]):
                col[a + 1:b] = min(col[a], col[b])
    return d


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", required=True, help="generated set (sim generate --out)")
    ap.add_argument("--cache", required=True, help="detect-eval --disparity-cache directory of the matcher's maps")
    ap.add_argument("--work", required=True, help="scratch directory for the variant caches")
    ap.add_argument("--binary", default="build/default/fuzzystereo")
    ap.add_argument("--seed", type=int, default=0, help="noise seed")
    ap.add_argument("--variants", default="", help="comma-separated subset of the variants (default: all)")
    a = ap.parse_args()

    maps = sorted(glob.glob(os.path.join(a.cache, "*.png")))
    if not maps:
        print(f"error: no cached maps in '{a.cache}' (run detect-eval --disparity-cache first)", file=sys.stderr)
        return 2
    rng = np.random.default_rng(a.seed)
    variants = {
        "gt": lambda g, m: g,
        "round": lambda g, m: np.round(g),
        "noise05": lambda g, m: np.where(g > 0, g + rng.normal(0, 0.5, g.shape), 0),
        "gt_on_valid": lambda g, m: np.where(m >= 0, g, 0),
        "m_err_lt1": lambda g, m: np.where((m >= 0) & (np.abs(m - g) < 1), m, np.where(m >= 0, g, 0)),
        "m_err_lt3": lambda g, m: np.where((m >= 0) & (np.abs(m - g) < 3), m, np.where(m >= 0, g, 0)),
        "matcher": lambda g, m: np.where(m >= 0, m, 0),
        "holes_gt": lambda g, m: np.where(m >= 0, m, g),
        "holes_gt_road": lambda g, m: np.where(m >= 0, m, np.where(masks["road"], g, 0)),
        "holes_gt_obst": lambda g, m: np.where(m >= 0, m, np.where(masks["obstacles"], g, 0)),
        "vfill32": lambda g, m: vertical_fill(np.where(m >= 0, m, 0), 32, 0.05),
    }
    if a.variants:
        unknown = [v for v in a.variants.split(",") if v not in variants]
        if unknown:
            print(f"error: unknown variant(s) {', '.join(unknown)}; known: {', '.join(variants)}", file=sys.stderr)
            return 2
        variants = {k: variants[k] for k in a.variants.split(",")}
    masks: dict[str, np.ndarray] = {}
    gt_dir = os.path.join(a.dataset, "training", "disp_occ_0")
    for name, fn in variants.items():
        out = os.path.join(a.work, name)
        shutil.rmtree(out, ignore_errors=True)
        os.makedirs(out)
        for f in glob.glob(os.path.join(a.cache, "*.txt")) + glob.glob(os.path.join(a.cache, "*.toml")):
            shutil.copy(f, out)
        for f in maps:
            s = os.path.basename(f)
            gt = cv2.imread(os.path.join(gt_dir, s), cv2.IMREAD_UNCHANGED).astype(float) / 256.0
            for kind in ("road", "obstacles"):
                mf = os.path.join(a.dataset, "training", "sim_gt", s[:-4] + f"_{kind}.png")
                masks[kind] = cv2.imread(mf, cv2.IMREAD_UNCHANGED) > 0 if os.path.isfile(mf) else np.zeros(gt.shape, bool)
            m = (cv2.imread(f, cv2.IMREAD_UNCHANGED).astype(int) - 1) / 16.0  # cache: Q4 + 1, 0 = invalid
            d = fn(gt, m)
            q = np.where(d > 0, np.round(d * 16) + 1, 0).astype(np.uint16)
            cv2.imwrite(os.path.join(out, s), q)
        r = subprocess.run([a.binary, "detect-eval", "--dataset", a.dataset, "--disparity-cache", out],
                           capture_output=True, text=True)
        line = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.startswith("overall")]
        print(f"{name:12s} {line[0] if line else r.stderr.strip()[-200:]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
