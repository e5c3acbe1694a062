"""Tiny generated datasets in the simulator's layout (docs/detection.md, "Evaluation"), for the
detect / detect-eval tests: a level camera over a flat textured road, textured boxes standing on it
at known depth, a sky above the horizon (blue or overcast grey). The right image is the left one
forward-warped by the integer disparity (z-buffered), so the ground truth is exact."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

W, H = 192, 144
F, B, CAM_H = 200.0, 0.1, 0.5
CX, CY = W / 2.0, H / 2.0


def render(boxes: list[dict], sky: str, seed: int):
    """boxes: [{"x0", "x1" (columns), "z" [m], "height" [m]}]. Returns left, right (BGR), disparity
    (float px, 0 = none), road mask, sky mask, obstacle id image (0 none, id+1) and the GT list."""
    rng = np.random.default_rng(seed)
    disp = np.zeros((H, W), np.float64)
    label = np.zeros((H, W), np.uint16)
    v = np.arange(H, dtype=np.float64)[:, None]
    road = (v > CY) & np.ones((1, W), bool)
    disp[road] = np.broadcast_to(np.round(B * (v - CY) / CAM_H), (H, W))[road]
    disp[road & (disp < 1)] = 1  # the first road rows: keep a valid (1 px) estimate
    # Textures: road grey noise, boxes brown noise; sky smooth.
    tex_road = rng.integers(60, 160, (H, W + 64)).astype(np.float64)
    left = np.zeros((H, W, 3), np.float64)
    if sky == "clear":
        left[:] = (230, 150, 100)  # BGR blue sky
    else:
        left[:] = (205, 200, 200)  # overcast grey
    # Road texture (same world texture in both views: indexed by x + disparity offset handled by warping).
    left[road] = np.stack([tex_road[:, :W]] * 3, -1)[road] * np.array([1.0, 1.05, 1.1])
    gt = []
    for i, b in sorted(enumerate(boxes), key=lambda t: -t[1]["z"]):
        d = round(B * F / b["z"])
        ybase = int(np.floor(CY + F * CAM_H / b["z"]))
        ytop = int(np.ceil(CY + F * (CAM_H - b["height"]) / b["z"]))
        ys, xs = slice(max(0, ytop), min(H - 1, ybase) + 1), slice(b["x0"], b["x1"] + 1)
        disp[ys, xs] = d
        label[ys, xs] = i + 1
        t = rng.integers(0, 120, (ys.stop - ys.start, xs.stop - xs.start)).astype(np.float64)
        left[ys, xs] = np.stack([t * 0.3 + 20, t * 0.6 + 40, t + 80], -1)
    left = np.clip(left, 0, 255).astype(np.uint8)
    # Forward warp with a z-buffer: right(x - d) = left(x), nearest (largest d) wins.
    right = np.zeros_like(left)
    zbuf = np.full((H, W), -1.0)
    for y in range(H):
        for x in range(W):
            d = int(disp[y, x])
            xr = x - d
            if 0 <= xr < W and d > zbuf[y, xr]:
                zbuf[y, xr] = d
                right[y, xr] = left[y, x]
    holes = zbuf < 0
    right[holes] = rng.integers(60, 160, (int(holes.sum()), 3))
    for i, b in enumerate(boxes):
        m = label == i + 1
        ys, xs = np.nonzero(m)
        if len(xs) == 0:
            continue
        gt.append({"id": i, "shape": "box", "box": [int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max())],
                   "position_world_m": [b["z"], 0.0, 0.0], "position_cam_m": [0.0, 0.0, b["z"]],
                   "distance_m": b["z"], "visible_pixels": int(m.sum()),
                   "truncated": bool(xs.min() == 0 or xs.max() == W - 1), "velocity_mps": [0.0, 0.0]})
    road_mask = road & (label == 0)
    sky_mask = (v <= CY) & (label == 0)
    return left, right, disp, road_mask, sky_mask, label, gt


SCENES = [
    ("clear", [{"x0": 20, "x1": 70, "z": 2.0, "height": 0.45}, {"x0": 120, "x1": 170, "z": 4.0, "height": 0.4}]),
    ("clear", [{"x0": 60, "x1": 120, "z": 3.0, "height": 0.45}]),
    ("overcast", [{"x0": 10, "x1": 50, "z": 2.5, "height": 0.45}, {"x0": 130, "x1": 180, "z": 5.0, "height": 0.3}]),
    ("overcast", [{"x0": 90, "x1": 150, "z": 1.6, "height": 0.45}, {"x0": 30, "x1": 36, "z": 6.0, "height": 0.1}]),
]


def write_dataset(root: Path) -> Path:
    tr = root / "training"
    for sub in ("image_2", "image_3", "disp_occ_0", "sim_gt"):
        (tr / sub).mkdir(parents=True, exist_ok=True)
    (root / "fuzzystereo_sim.json").write_text(json.dumps({"count": len(SCENES), "seed": 1, "max_disparity": 32}))
    for n, (kind, boxes) in enumerate(SCENES):
        stem = f"{n:06d}_10"
        left, right, disp, road, sky, label, gt = render(boxes, kind, seed=n + 1)
        cv2.imwrite(str(tr / "image_2" / f"{stem}.png"), left)
        cv2.imwrite(str(tr / "image_3" / f"{stem}.png"), right)
        cv2.imwrite(str(tr / "disp_occ_0" / f"{stem}.png"), (disp * 256).astype(np.uint16))
        cv2.imwrite(str(tr / "sim_gt" / f"{stem}_road.png"), road.astype(np.uint8) * 255)
        cv2.imwrite(str(tr / "sim_gt" / f"{stem}_sky.png"), sky.astype(np.uint8) * 255)
        cv2.imwrite(str(tr / "sim_gt" / f"{stem}_obstacles.png"), label)
        meta = {"type": kind, "seed": n + 1,
                "calib": {"focal_px": F, "cx": CX, "cy": CY, "baseline_m": B, "height_m": CAM_H, "pitch_deg": 0.0},
                "obstacles": gt}
        (tr / "sim_gt" / f"{stem}.json").write_text(json.dumps(meta, indent=1))
    return root
