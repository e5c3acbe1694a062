"""Firmware detect dump (``fuzzystereo detect --dump``) vs the float64 detection reference
(:mod:`fuzzyctl.reference.detect`), run on the dump's own inputs (``disp.npy``, ``left_rgb.npy``)
with the dump's config and calibration. Metrics (tolerances in common/compare/detect_tolerances.toml):

  road      line slope / horizon row difference; road mask agreement
  sky       sky mask agreement
  udisp     IoU of the kept (u-disparity filtered) pixels
  objects   obstacle count difference; box IoU and relative distance difference of matched pairs
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import paths
from .compare import Metric, Tolerance
from .config import parse_config
from .errors import FatalError
from .reference import detect as refdet


def find_detect_dump(run_dir: Path) -> Path | None:
    for d in (run_dir, run_dir / "dump"):
        if (d / "detect_meta.json").is_file():
            return d
    return None


@dataclass
class DetectComparison:
    dump_dir: Path
    reference: refdet.DetectReferenceResult
    metrics: list[Metric]
    tolerances: dict[str, Tolerance]

    def failures(self) -> list[tuple[Metric, Tolerance]]:
        return [(m, self.tolerances[m.name]) for m in self.metrics
                if m.name in self.tolerances and self.tolerances[m.name].passed(m.value) is False]


def load_detect_tolerances(path: Path | None = None) -> dict[str, Tolerance]:
    path = path or paths.common_file("compare", "detect_tolerances.toml")
    try:
        doc = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise FatalError(f"cannot read detect tolerances {path}: {exc}") from exc
    unknown = set(doc) - set(METRICS)
    if unknown:
        raise FatalError(f"{path}: unknown metric(s) {', '.join(sorted(unknown))} (metrics: {', '.join(METRICS)})")
    return {k: Tolerance(k, v.get("min"), v.get("max"), str(v.get("doc", ""))) for k, v in doc.items()}


#: name -> (stage, unit, doc)
METRICS = {
    "road_slope_abs_diff": ("road", "px/row", "|a_firmware - a_reference| of the road line d = a v + b"),
    "horizon_row_abs_diff": ("road", "rows", "|horizon row firmware - reference|"),
    "road_mask_agreement_pct": ("road", "%", "pixels with the same road / not-road decision"),
    "sky_mask_agreement_pct": ("sky", "%", "pixels with the same sky / not-sky decision"),
    "kept_iou": ("udisp", "", "IoU of the pixels kept by the u-disparity filter"),
    "obstacle_count_abs_diff": ("objects", "", "|number of obstacles firmware - reference|"),
    "obstacle_box_iou_min": ("objects", "", "smallest box IoU over firmware obstacles (best reference match; 0 = none)"),
    "obstacle_distance_rel_diff_max": ("objects", "", "largest |Z_fw - Z_ref| / Z_ref over matched obstacles"),
}


def _iou(a, b) -> float:
    ix = min(a[2], b[2]) - max(a[0], b[0]) + 1
    iy = min(a[3], b[3]) - max(a[1], b[1]) + 1
    if ix <= 0 or iy <= 0:
        return 0.0
    area = lambda r: (r[2] - r[0] + 1) * (r[3] - r[1] + 1)  # noqa: E731
    return ix * iy / (area(a) + area(b) - ix * iy)


def run_reference_on_dump(dump_dir: Path):
    meta = json.loads((dump_dir / "detect_meta.json").read_text())
    cfg = parse_config(meta["config_toml"], str(dump_dir / "detect_meta.json"))
    q4 = np.load(dump_dir / "disp.npy")
    disp = np.where(q4 >= 0, q4.astype(np.float64) / 16.0, np.nan)
    rgb_path = dump_dir / "left_rgb.npy"
    rgb = np.load(rgb_path) if rgb_path.is_file() else None
    return meta, refdet.detect(disp, rgb, meta["calib"], refdet.params_from_config(cfg))


def compare_detect(run_dir: Path, tolerances: Path | None = None) -> DetectComparison:
    d = find_detect_dump(run_dir)
    if d is None:
        raise FatalError(f"no detect dump in {run_dir} (run `fuzzystereo detect ... --dump`)")
    meta, r = run_reference_on_dump(d)
    fw_road, fw_sky, fw_kept = (np.load(d / f"{n}.npy") for n in ("road_mask", "sky_mask", "kept"))
    m: list[Metric] = []

    def add(name: str, value: float | None) -> None:
        stage, unit, doc = METRICS[name]
        m.append(Metric(name, stage, value, unit, doc))

    road = meta["road"]
    both = road["found"] and r.road_found
    add("road_slope_abs_diff", abs(road["a"] - r.road_a) if both else None)
    add("horizon_row_abs_diff", float(abs(road["horizon_row"] - r.horizon_row)) if both else None)
    add("road_mask_agreement_pct", 100.0 * float(np.mean(fw_road == r.road_mask)))
    add("sky_mask_agreement_pct", 100.0 * float(np.mean(fw_sky == r.sky_mask)))
    union = (fw_kept | r.kept).sum()
    add("kept_iou", float((fw_kept & r.kept).sum() / union) if union else None)
    fw_obs = meta["obstacles"]
    add("obstacle_count_abs_diff", float(abs(len(fw_obs) - len(r.obstacles))))
    ious, rel = [], []
    for o in fw_obs:
        best = max(r.obstacles, key=lambda q: _iou(o["box"], q.box), default=None)
        v = _iou(o["box"], best.box) if best else 0.0
        ious.append(v)
        if best is not None and v >= 0.5:
            rel.append(abs(o["distance_m"] - best.distance_m) / best.distance_m)
    add("obstacle_box_iou_min", min(ious) if ious else None)
    add("obstacle_distance_rel_diff_max", max(rel) if rel else None)
    return DetectComparison(d, r, m, load_detect_tolerances(tolerances))


def write_reference_outputs(out: Path, r: refdet.DetectReferenceResult) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name in ("road_raw", "road_mask", "sky_mask", "candidates", "cluster_labels", "kept", "obstacle_labels"):
        np.save(out / f"{name}.npy", getattr(r, name))
    np.save(out / "vdisp.npy", r.vdisp.astype(np.int32))
    doc = {"format": "fuzzyctl-detect-reference", "version": 1,
           "road": {"found": r.road_found, "a": r.road_a, "b": r.road_b, "horizon_row": r.horizon_row},
           "sky_skipped": r.sky_skipped, "sky_rows": r.sky_rows, "centres_px": r.centres_px,
           "obstacles": [{"id": o.id, "box": list(o.box), "pixel_count": o.pixel_count, "disparity_px": o.disparity_px,
                          "distance_m": o.distance_m, "lateral_m": o.lateral_m, "class": o.cls} for o in r.obstacles]}
    (out / "obstacles.json").write_text(json.dumps(doc, indent=2) + "\n")
