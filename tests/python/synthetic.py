"""Synthetic stereo pairs with known disparity, for testing the reference without datasets."""

from __future__ import annotations

import cv2
import numpy as np

from fuzzyctl.config import Config, load_config


def texture(h: int, w: int, seed: int, blur: float = 1.0) -> np.ndarray:
    """Random 8-bit texture, lightly blurred (so gradients and NCC are well defined)."""
    rng = np.random.default_rng(seed)
    t = cv2.GaussianBlur(rng.random((h, w)) * 255.0, (0, 0), blur)
    t = (t - t.min()) / (t.max() - t.min()) * 255.0
    return np.clip(np.rint(t), 0, 255).astype(np.uint8)


def shifted_pair(h: int, w: int, d: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """left(x) = right(x - d) everywhere: a fronto-parallel textured plane at disparity d."""
    scene = texture(h, w + d, seed)
    left = scene[:, :w].copy()  # left[x] = scene[x]
    right = scene[:, d : d + w].copy()  # right[x - d] = scene[x]
    return left, right


def two_plane_pair(h: int, w: int, d_top: int, d_bottom: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Top half at d_top, bottom half at d_bottom; returns (left, right, true left disparity)."""
    lt, rt = shifted_pair(h // 2, w, d_top, seed)
    lb, rb = shifted_pair(h - h // 2, w, d_bottom, seed + 1)
    gt = np.zeros((h, w))
    gt[: h // 2] = d_top
    gt[h // 2 :] = d_bottom
    return np.vstack([lt, lb]), np.vstack([rt, rb]), gt


def small_config(**overrides) -> Config:
    """Defaults with a small disparity range; overrides as section__key=value."""
    values = load_config().as_dict()
    values["cost"]["max_disparity"] = 16
    for key, v in overrides.items():
        section, name = key.split("__")
        values[section][name] = v
    return Config(values)


def grid_labels(h: int, w: int, step: int) -> np.ndarray:
    """Square segments of side ``step`` (dense labels, row-major)."""
    ys, xs = np.mgrid[0:h, 0:w]
    nx = (w + step - 1) // step
    return ((ys // step) * nx + xs // step).astype(np.int32)
