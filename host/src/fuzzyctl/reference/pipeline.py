"""The float64 desktop reference of the matcher: Section III up to and including ESR.

One line per stage, the same stages and order as firmware/core/src/matcher.cpp. Readable over
fast: NumPy/OpenCV, every quantity in float64, the FIS evaluated with scikit-fuzzy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..config import Config
from ..errors import FatalError
from ..fis import Fis
from . import boundary, cost, densify, esr, image, lrcheck, segmentation, wta

STAGES = ("gradient", "segmentation", "cost", "wta", "lrcheck", "esr", "densify")


@dataclass
class ReferenceResult:
    left: np.ndarray
    right: np.ndarray
    labels_left: np.ndarray
    labels_right: np.ndarray
    costs_left: cost.SegmentCosts
    costs_right: cost.SegmentCosts
    dec_left: wta.SegmentDecision
    dec_right: wta.SegmentDecision
    disp_left_wta: np.ndarray  # [px], NaN = invalid
    disp_right_wta: np.ndarray
    lr_mask: np.ndarray  # bool
    disp_lr: np.ndarray
    disp_esr: np.ndarray  # after ESR
    esr_replaced: np.ndarray  # bool
    disp_final: np.ndarray  # after densify (== disp_esr when disabled)
    densify_changed: np.ndarray  # uint8: 0 kept, 1 filled, 2 zero or speckle
    esr_maps: dict[str, np.ndarray] = field(default_factory=dict)
    timings_ms: dict[str, float] = field(default_factory=dict)
    labels_given: bool = False
    fis_check_error: float = 0.0  # max |fast engine - ControlSystemSimulation| on sampled winners
    boundary_refined: bool = False  # the [boundary] refinement ran (enabled, or on_mismatch on a mismatched pair)
    retry_recovered: int = 0  # segments recovered by the candidate retry after eq. (13) (docs/algorithm.md 5b)


class _Clock:
    def __init__(self) -> None:
        self.ms: dict[str, float] = {s: 0.0 for s in STAGES}
        self._last = time.perf_counter()

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.ms[stage] += (now - self._last) * 1e3
        self._last = now


def _check_labels(labels: np.ndarray | None, shape: tuple[int, int], name: str) -> np.ndarray | None:
    if labels is None:
        return None
    labels = np.asarray(labels)
    if labels.shape != shape:
        raise FatalError(f"{name}: labels are {labels.shape[::-1]} (W, H) but the images are {shape[::-1]}")
    if labels.size and (labels.min() < 0 or np.unique(labels).size != int(labels.max()) + 1):
        raise FatalError(f"{name}: labels must be dense 0 .. n-1")
    return labels.astype(np.int32)


def match(
    left: np.ndarray,
    right: np.ndarray,
    cfg: Config,
    fis: Fis,
    labels_left: np.ndarray | None = None,
    labels_right: np.ndarray | None = None,
    engine: str = "fast",
) -> ReferenceResult:
    """Run the whole pipeline on two rectified 8-bit grey images of equal size."""
    if left.shape != right.shape or left.ndim != 2 or left.size == 0:
        raise FatalError(f"left {left.shape[::-1]} and right {right.shape[::-1]} must be non-empty grey images of equal size")
    labels_left = _check_labels(labels_left, left.shape, "labels_left")
    labels_right = _check_labels(labels_right, left.shape, "labels_right")
    c, s, lr, e, dn = cfg.cost, cfg.segmentation, cfg.lr_check, cfg.esr, cfg.densify
    clock = _Clock()

    # not in the paper: docs/algorithm.md 2c (a pair of unequal noise is smoothed)
    left, right, gin_l, gin_r, smoothed = image.noise_equalise(left, right, c.noise_excess, c.noise_image_passes,
                                                                c.noise_gradient_passes)
    grad_l = image.gradient_magnitude(gin_l)  # eq. (5)
    grad_r = image.gradient_magnitude(gin_r)
    gain_triggered = False
    if c.gradient_gain_compensation:  # not in the paper: docs/algorithm.md 2b
        if c.gradient_gain_trigger == "gradient":
            grad_r, factor = image.compensate_gradient_gain(grad_l, grad_r, c.gradient_gain_deadband)
            gain_triggered = factor != 1.0
        elif image.grey_quantile_shift(left, right) > c.gradient_gain_grey_shift:
            grad_r, _ = image.compensate_gradient_gain(grad_l, grad_r, 0.0)
            gain_triggered = True
    clock.lap("gradient")

    seg_args = (s.region_size, s.compactness, s.iterations, s.min_segment_pct, s.coarse_iterations)
    lab_l = labels_left if labels_left is not None else segmentation.slic(left, *seg_args)
    lab_r = labels_right if labels_right is not None else segmentation.slic(right, *seg_args)
    clock.lap("segmentation")

    costs_l = cost.segment_costs(left, right, grad_l, grad_r, lab_l, +1, c.max_disparity, c.nmi_bins)  # eq. (1)-(7)
    costs_r = cost.segment_costs(right, left, grad_r, grad_l, lab_r, -1, c.max_disparity, c.nmi_bins)
    clock.lap("cost")

    wta_args = (fis, c.alpha, c.nmi_candidates, engine, c.subpixel, cfg.fis.lut_size, c.subpixel_every_segment)
    dec_l = wta.fis_winner_take_all(costs_l, *wta_args)  # eq. (8)-(12), WTA
    dec_r = wta.fis_winner_take_all(costs_r, *wta_args)
    fis_check = _cross_check(fis, dec_l, dec_r) if engine == "fast" else 0.0
    disp_l = wta.paint_segments(lab_l, dec_l.disparity_sub)
    disp_r = wta.paint_segments(lab_r, dec_r.disparity_sub)
    # not in the paper: docs/algorithm.md 4b (timed with the WTA, as in the firmware); also on a mismatched pair
    refine = cfg.boundary.enabled or (cfg.boundary.on_mismatch and (smoothed or gain_triggered))
    if refine:
        disp_l, disp_r = boundary.refine_pair(disp_l, disp_r, left, right, cfg.boundary)
    clock.lap("wta")

    disp_lr, mask = lrcheck.left_right_check(disp_l, disp_r, lr.max_diff)  # eq. (13)
    retry_recovered = 0
    if lr.retry_candidates > 0:  # not in the paper: docs/algorithm.md 5b
        disp_lr, mask, retry_recovered = lrcheck.retry_rejected_segments(
            disp_lr, mask, lab_l, dec_l.disparity, dec_l.candidates, dec_l.candidate_scores, disp_r, lr.max_diff,
            lr.retry_candidates, lr.retry_min_share)
    clock.lap("lrcheck")

    if e.enabled:  # eq. (14)-(15)
        disp_esr, replaced, maps = esr.entropy_selective_refinement(disp_lr, disp_r, e.window, e.tau, c.max_disparity)
    else:
        disp_esr, replaced, maps = disp_lr.copy(), np.zeros(left.shape, dtype=bool), {}
    clock.lap("esr")

    final, changed = densify.densify_config(disp_esr, disp_r, dn, c.max_disparity)  # not in the paper
    clock.lap("densify")

    return ReferenceResult(
        left=left, right=right, labels_left=lab_l, labels_right=lab_r,
        costs_left=costs_l, costs_right=costs_r, dec_left=dec_l, dec_right=dec_r,
        disp_left_wta=disp_l, disp_right_wta=disp_r, lr_mask=mask, disp_lr=disp_lr,
        disp_esr=disp_esr, disp_final=final, densify_changed=changed, esr_replaced=replaced, esr_maps=maps, timings_ms=clock.ms,
        labels_given=labels_left is not None and labels_right is not None, fis_check_error=fis_check,
        boundary_refined=refine, retry_recovered=retry_recovered,
    )  # fmt: skip


def _cross_check(fis: Fis, dec_l: wta.SegmentDecision, dec_r: wta.SegmentDecision, samples: int = 64) -> float:
    """The fast FIS engine against ControlSystemSimulation on a sample of the winners' inputs."""
    return fis.cross_check(np.concatenate([dec_l.dc1, dec_r.dc1]), np.concatenate([dec_l.dc2, dec_r.dc2]), samples=samples)
