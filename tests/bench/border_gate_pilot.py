#!/usr/bin/env python3
"""Pilot of left-border-band variants on the firmware's dumps (docs/algorithm.md 6f, session 56).

For every frame of a dataset root (KITTI, Middlebury or a `sim generate` set) it runs `fuzzystereo match --dump`
once (cached in --dumps), then re-runs the densify stage with the float twin (`fuzzyctl.reference.densify`) from
the dumped ESR and right-reference maps, with the left border band filled in several ways:

* ``none``  - the defaults (nearest-estimate fill of the band);
* ``line``  - session 45's least-squares line over [x0, x0 + 80) (`border_fit_px = 80`);
* ``edge T`` - the line only from x0 - 1 leftwards up to the first intensity edge of the left image (the 5 x 1
  box-blurred grey row changes by more than T levels between two columns); left of it the nearest-estimate fill;
* ``ref T`` - the line only up to the first pixel whose grey level differs from the median of x0 .. x0 + 4 by > T.

Each with a minimum slope (px per column) below which the row keeps the fill. The twin's smoothing follows, and
each map is scored like `fuzzystereo eval` (KITTI hole filling, all ground-truth pixels). Prints the per-set mean
average error / bad-2 per variant, and with --per-frame the frames a variant changes by more than 0.002 px.

  .venv/bin/python tests/bench/border_gate_pilot.py --dataset ../shared/datasets --dumps /tmp/dumps
  .venv/bin/python tests/bench/border_gate_pilot.py --dataset /tmp/syn901 --limit 100 --dumps /tmp/dumps901 --per-frame
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from multiprocessing import Pool
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host" / "src"))

from fuzzyctl import dataset, metrics  # noqa: E402
from fuzzyctl.dump import q4_to_disp  # noqa: E402
from fuzzyctl.reference import densify as rd  # noqa: E402

WINDOW = 80
SMOOTH = (6, 6, 8.0, 3.0, 0.1)  # [densify] smooth_* defaults
VARIANTS = [("none", 0, 0.0), ("line", 0, 0.0), ("line", 0, 0.2)] + [
    (kind, t, ms) for kind, t in (("edge", 8), ("edge", 15), ("ref", 30), ("ref", 45)) for ms in (0.0, 0.1, 0.2)]


def before_band(esr: np.ndarray, right_wta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The twin's densify up to the median fill (defaults): (map before the fill, filled map)."""
    d = np.where(esr == 0, np.nan, esr)
    d, _ = rd.remove_speckles(d, 100, 3)
    d, _ = rd.occlusion_fill(d, right_wta, 1, 64)
    out, _ = rd.median_fill(d, 8)
    return d, out


def band_variant(before: np.ndarray, filled: np.ndarray, grey: np.ndarray, cap: float, kind: str, t: float,
                 min_slope: float) -> np.ndarray:
    """The band filled per ``kind``; the line is the twin's own ``extrapolate_left_border`` (session 45's option)."""
    if kind == "none":
        return filled.copy()
    line = filled.copy()
    rd.extrapolate_left_border(line, before, WINDOW, cap, min_slope)
    if kind == "line":
        return line
    out = filled.copy()
    blurred = cv2.blur(grey, (5, 1)).astype(np.float64)
    g = grey.astype(np.float64)
    valid = ~np.isnan(before)
    for y in range(before.shape[0]):
        if not valid[y].any() or valid[y, 0] or np.array_equal(line[y], filled[y], equal_nan=True):
            continue  # no band, or the line was not drawn on this row
        x0 = int(np.argmax(valid[y]))
        if kind == "edge":
            stop = np.abs(np.diff(blurred[y, :x0 + 1])) > t  # stop[x]: an edge between x and x + 1
        else:
            stop = np.abs(g[y, :x0] - np.median(g[y, x0:x0 + 5])) > t
        hits = np.nonzero(stop[::-1])[0]
        k = x0 if len(hits) == 0 else int(hits[0])  # columns x0 - k .. x0 - 1 take the line
        if k > 0:
            out[y, x0 - k:x0] = line[y, x0 - k:x0]
    return out


def score(frame: dataset.Frame, dump_dir: Path) -> tuple[str, str, dict]:
    dd = dump_dir / "dump"
    esr = q4_to_disp(np.load(dd / "disp_esr.npy"))
    right = q4_to_disp(np.load(dd / "disp_right_wta.npy"))
    grey = cv2.imread(str(dd / "left.png"), cv2.IMREAD_GRAYSCALE)
    gt = dataset.load_ground_truth(frame)
    before, filled = before_band(esr, right)
    res = {}
    for kind, t, ms in VARIANTS:
        o = rd.smooth_disparity(band_variant(before, filled, grey, frame.max_disparity - 1, kind, t, ms), *SMOOTH)
        m = metrics.evaluate_disparity(np.where(np.isnan(o), -1, o).astype(np.float32), gt)
        res[(kind, t, ms)] = (m.avg_err, m.bad2)
    return frame.set, frame.name, res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--dumps", required=True, help="cache of `match --dump` outputs")
    ap.add_argument("--binary", default=str(ROOT / "build/default/fuzzystereo"))
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--per-frame", action="store_true")
    a = ap.parse_args()
    jobs = []
    for f in dataset.select(dataset.discover(a.dataset), limit=a.limit):
        d = Path(a.dumps) / f.set / f.name
        if not (d / "dump" / "meta.json").exists():
            subprocess.run([a.binary, "match", "--left", f.left_path, "--right", f.right_path, "--out", str(d), "--dump",
                            "--max-disparity", str(f.max_disparity)], check=True, capture_output=True)
        jobs.append((f, d))
    with Pool(2) as pool:
        rows = pool.starmap(score, jobs)
    sets = sorted({r[0] for r in rows})
    print("variant".ljust(14) + "".join(s[:18].rjust(19) for s in sets) + "   (avg err px / bad-2 %)")
    for v in VARIANTS:
        cells = []
        for s in sets:
            vals = [r[2][v] for r in rows if r[0] == s]
            cells.append(f"{np.mean([x[0] for x in vals]):.3f} / {np.mean([x[1] for x in vals]):.2f}".rjust(19))
        print(f"{v[0]} {v[1]} {v[2]}".ljust(14) + "".join(cells))
    if a.per_frame:
        for s, name, res in rows:
            base = res[VARIANTS[0]][0]
            deltas = [res[v][0] - base for v in VARIANTS[1:]]
            if any(abs(x) > 0.002 for x in deltas):
                print(f"{s}/{name}: base {base:.3f}", " ".join(f"{x:+.3f}" for x in deltas))
    return 0


if __name__ == "__main__":
    sys.exit(main())
