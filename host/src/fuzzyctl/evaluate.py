"""``fuzzyctl reference eval``: the firmware eval's figures, recomputed on the host.

Same frames (``dataset.discover`` / ``select``: frames with ground truth, ``--limit`` per set), same
GT decoding, same KITTI hole filling and metrics (``metrics``), same JSON shape
``{"sets": {SET: {METHOD: {avg_err, bad2, bad3, d1, density, ms_per_frame, frames[, noc]}}}}`` with a
set's figures the means of its per-frame figures; ``noc`` (the same figures over the non-occluded
pixels) where the set's frames ship a non-occlusion mask (KITTI disp_noc, MiddEval3 mask0nocc). The map scored per frame is either

* ``source = "reference"`` (method ``reference``): the float64 reference pipeline's final left map
  (with its own SLIC; float px, invalid = NaN), or
* ``source = "firmware"`` (method ``fuzzystereo``, the firmware eval's name): the firmware's final
  left map from ``fuzzystereo match --dump`` with the layout's search range — ``dump/disp_final.npy``
  (Q4, exactly the map ``fuzzystereo eval`` scores), else ``disp_left.png`` (KITTI 16-bit; it holds
  the same map since the metrics count 0 px as "no estimate", as the PNG does).

Firmware runs are kept in ``runs/<set>/<name>/`` when a runs directory is given (and reused when
already there), so ``fuzzyctl compare --dataset --report DIR`` outputs can be scored again.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import cv2
import numpy as np

from . import firmware
from .config import Config, load_config
from .dataset import Frame, load_ground_truth, load_nonoccluded_mask
from .errors import FatalError, load_json
from .metrics import FIGURES, DispMetrics, disp_q4_to_float, evaluate_disparity, fill_invalid_kitti, set_means

SOURCES = ("reference", "firmware")
METHOD = {"reference": "reference", "firmware": "fuzzystereo"}  # method names in the JSON


@dataclass
class FrameScore:
    frame: Frame
    metrics: DispMetrics
    ms: float  # time to produce the map (reference pipeline, or 0 for a reused firmware run)
    noc: DispMetrics | None = None  # over the non-occluded pixels, where the frame has a mask


def frame_config(config_path: str | Path | None, frame: Frame) -> Config:
    """The config with the layout's search range, as eval builds its Matcher per frame."""
    cfg = load_config(config_path)
    values = cfg.as_dict()
    values["cost"]["max_disparity"] = frame.max_disparity
    return Config(values, cfg.source)


def run_dir_of(runs_root: str | Path, frame: Frame) -> Path:
    return Path(runs_root) / frame.set / frame.name


def firmware_run(frame: Frame, binary: str | Path, out: Path, config_path: str | Path | None = None,
                 threads: int | None = None, reuse: bool = True) -> Path:
    """``fuzzystereo match --dump`` of the frame into ``out`` (skipped when a dump is already there)."""
    if reuse and (out / "dump" / "disp_final.npy").is_file() and (out / "dump" / "meta.json").is_file():
        return out
    return firmware.match(binary, frame.left_path, frame.right_path, out, frame.max_disparity, config_path, threads)


def firmware_disparity(run_dir: str | Path) -> np.ndarray:
    """The firmware's final left map of a match run as float32 px (-1 = invalid)."""
    run_dir = Path(run_dir)
    npy = run_dir / "dump" / "disp_final.npy"
    if npy.is_file():
        return disp_q4_to_float(np.load(npy, allow_pickle=False))
    png = run_dir / "disp_left.png"
    img = cv2.imread(str(png), cv2.IMREAD_UNCHANGED) if png.is_file() else None
    if img is None or img.dtype != np.uint16 or img.ndim != 2:
        raise FatalError(f"no firmware disparity in {run_dir}: neither dump/disp_final.npy nor a 16-bit disp_left.png")
    return np.where(img == 0, np.float32(-1.0), img.astype(np.float32) / np.float32(256.0))


def reference_disparity(frame: Frame, cfg: Config, fis_path: str | Path | None, engine: str) -> np.ndarray:
    """The reference pipeline's final left map of the frame as float32 px (-1 = invalid)."""
    from .fis import get_fis
    from .reference import match
    from .reference.image import load_grey

    left, right = load_grey(frame.left_path), load_grey(frame.right_path)
    if left.shape != right.shape:
        raise FatalError(f"left {frame.left_path} and right {frame.right_path} differ in size")
    r = match(left, right, cfg, get_fis(fis_path), engine=engine)
    return np.where(np.isnan(r.disp_final), -1.0, r.disp_final).astype(np.float32)


def score_frame(frame: Frame, source: str, config_path: str | Path | None = None, fis_path: str | Path | None = None,
                engine: str = "fast", binary: str | Path | None = None, runs_root: str | Path | None = None,
                threads: int | None = None) -> FrameScore:
    """Metrics of one frame's map (``source``) against its ground truth."""
    gt = load_ground_truth(frame)
    t0 = time.perf_counter()
    if source == "reference":
        disp = reference_disparity(frame, frame_config(config_path, frame), fis_path, engine)
    elif source == "firmware":
        if binary is None:
            raise FatalError("scoring firmware maps needs the firmware binary")
        if runs_root is not None:
            disp = firmware_disparity(firmware_run(frame, binary, run_dir_of(runs_root, frame), config_path, threads))
        else:
            with tempfile.TemporaryDirectory(prefix="fuzzyctl-eval-") as tmp:
                disp = firmware_disparity(firmware_run(frame, binary, Path(tmp), config_path, threads))
    else:
        raise ValueError(f"unknown source {source!r} (sources: {', '.join(SOURCES)})")
    ms = (time.perf_counter() - t0) * 1e3
    if gt.shape != disp.shape:
        raise FatalError(f"ground truth '{frame.gt_path}' is {gt.shape[1]}x{gt.shape[0]} but the disparity map of "
                         f"{frame.key} is {disp.shape[1]}x{disp.shape[0]}")
    filled = fill_invalid_kitti(disp)  # once for both areas
    noc = None
    if frame.has_noc:
        mask = load_nonoccluded_mask(frame)
        if mask.shape != gt.shape:
            raise FatalError(f"non-occlusion mask '{frame.noc_path}' is {mask.shape[1]}x{mask.shape[0]} but ground truth "
                             f"'{frame.gt_path}' is {gt.shape[1]}x{gt.shape[0]}")
        noc = evaluate_disparity(disp, gt, mask, filled=filled)
    return FrameScore(frame, evaluate_disparity(disp, gt, filled=filled), ms, noc)


def scorer(source: str, **kwargs) -> partial:
    """A picklable one-argument ``score_frame`` for :func:`fuzzyctl.parallel.run_frames`."""
    return partial(score_frame, source=source, **kwargs)


def summarise(scores: list[FrameScore], method: str) -> dict:
    """The firmware eval JSON: sets in first-seen order of the (sorted) frames, per-frame means."""
    by_set: dict[str, list[FrameScore]] = {}
    for s in sorted(scores, key=lambda s: (s.frame.set, s.frame.name)):
        by_set.setdefault(s.frame.set, []).append(s)
    sets = {}
    for name, group in by_set.items():
        fig = set_means([s.metrics for s in group])
        fig["ms_per_frame"] = sum(s.ms for s in group) / len(group)
        fig["frames"] = len(group)
        with_noc = [s for s in group if s.noc is not None]
        if with_noc:
            noc = set_means([s.noc for s in with_noc])
            noc["ms_per_frame"] = sum(s.ms for s in with_noc) / len(with_noc)
            noc["frames"] = len(with_noc)
            fig["noc"] = noc
        sets[name] = {method: fig}
    return {"sets": sets}


def read_eval_json(path: str | Path) -> dict:
    """A firmware ``eval --json`` file; FatalError naming it when it does not have the eval shape."""
    path = Path(path)
    doc = load_json(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("sets"), dict):
        raise FatalError(f"{path}: expected {{\"sets\": {{SET: {{METHOD: {{...}}}}}}}} (fuzzystereo eval --json)")
    return doc


@dataclass
class FigureDiff:
    set: str
    figure: str
    ours: float
    theirs: float | None

    @property
    def abs_diff(self) -> float | None:
        return None if self.theirs is None else abs(self.ours - self.theirs)


def diff_figures(ours: dict, theirs: dict, method: str, their_method: str = "fuzzystereo") -> list[FigureDiff]:
    """Figure by figure, our set means against the firmware eval JSON's (``theirs``)."""
    out = []
    for set_name, methods in ours["sets"].items():
        mine = methods[method]
        other = theirs["sets"].get(set_name, {}).get(their_method)
        for f in (*FIGURES, "frames"):
            value = None if other is None or f not in other else float(other[f])
            out.append(FigureDiff(set_name, f, float(mine[f]), value))
        if "noc" in mine:  # the non-occluded figures, named "noc.FIGURE"
            other_noc = None if other is None else other.get("noc")
            for f in (*FIGURES, "frames"):
                value = None if other_noc is None or f not in other_noc else float(other_noc[f])
                out.append(FigureDiff(set_name, f"noc.{f}", float(mine["noc"][f]), value))
    return out
