"""``fuzzyctl compare``: a firmware stage dump against the float64 desktop reference.

The reference is run on the dump's own inputs (``left.png``/``right.png``, exactly as matched)
with the dump's resolved config (``meta.json: config_toml``) and, by default, the firmware's
segment labels, so every later stage is compared on the same segments. Metrics per stage:

  segmentation  label agreement (100 % when the firmware labels are reused)
  cost + WTA    per-segment winning disparity agreement; FIS score / data cost errors of the
                segments with the same winner; WTA maps within 0/1/2 px
  lrcheck       eq. (13) mask agreement, checked map within 0/1/2 px
  esr           replaced-mask agreement; final map within 0/1/2 px

Tolerances: ``common/compare/tolerances.toml`` (or ``--tolerances``).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import dump as dumpmod
from .reference import boundary
from . import paths
from .config import Config, default_values, parse_config
from .errors import FatalError
from .fis import Fis, load_definition
from .reference import STAGES, ReferenceResult, match
from .reference.densify import densify_config
from .reference.esr import entropy_selective_refinement
from .reference.lrcheck import left_right_check, retry_rejected_segments
from .reference.segmentation import label_agreement


#: config sections the reference does not model (they only alter the firmware)
REFERENCE_IGNORES = ("testing",)


def hasattr_section(cfg: Config, section: str) -> bool:
    return section in cfg.as_dict()


@dataclass
class Metric:
    name: str
    stage: str
    value: float | None  # None = not applicable (e.g. per-segment metrics with own segmentation)
    unit: str
    doc: str


@dataclass
class Tolerance:
    name: str
    min: float | None = None
    max: float | None = None
    doc: str = ""

    def passed(self, value: float | None) -> bool | None:
        if value is None:
            return None
        return (self.min is None or value >= self.min) and (self.max is None or value <= self.max)

    def text(self) -> str:
        if self.min is not None and self.max is not None:
            return f"[{self.min:g}, {self.max:g}]"
        return f">= {self.min:g}" if self.min is not None else f"<= {self.max:g}"


@dataclass
class Comparison:
    dump: dumpmod.Dump
    reference: ReferenceResult
    config: Config
    fis: Fis
    metrics: list[Metric]
    tolerances: dict[str, Tolerance]
    ignored_config: dict[str, Any] = field(default_factory=dict)

    def metric(self, name: str) -> Metric:
        for m in self.metrics:
            if m.name == name:
                return m
        raise KeyError(name)

    def failures(self) -> list[tuple[Metric, Tolerance]]:
        out = []
        for m in self.metrics:
            tol = self.tolerances.get(m.name)
            if tol is not None and tol.passed(m.value) is False:
                out.append((m, tol))
        return out

    @property
    def passed(self) -> bool:
        return not self.failures()


def load_tolerances(path: str | Path | None = None) -> dict[str, Tolerance]:
    """Metric tolerances; FatalError naming the file and metric for unknown names or bad bounds."""
    path = Path(path) if path is not None else paths.tolerances_file()
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except OSError as exc:
        raise FatalError(f"cannot read tolerances {path}: {exc.strerror}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise FatalError(f"{path}: not valid TOML: {exc}") from exc
    known = set(METRIC_DOCS)
    out: dict[str, Tolerance] = {}
    for name, spec in doc.items():
        if name not in known:
            raise FatalError(f"{path}: unknown metric '{name}' (metrics: {', '.join(sorted(known))})")
        if not isinstance(spec, dict) or not ({"min", "max"} & set(spec)):
            raise FatalError(f"{path}: [{name}] needs min = ... and/or max = ...")
        extra = sorted(set(spec) - {"min", "max", "doc"})
        if extra:
            raise FatalError(f"{path}: [{name}] has unknown key(s) {', '.join(extra)}")
        for key in ("min", "max"):
            v = spec.get(key)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
                raise FatalError(f"{path}: {name}.{key} = {v!r} must be a number")
        out[name] = Tolerance(name, spec.get("min"), spec.get("max"), str(spec.get("doc", "")))
    return out


# ---- metrics ----------------------------------------------------------------------------------

#: name -> (stage, unit, doc); the order is the report's.
METRIC_DOCS: dict[str, tuple[str, str, str]] = {}


def _doc(name: str, stage: str, unit: str, doc: str) -> None:
    METRIC_DOCS[name] = (stage, unit, doc)


for _side in ("left", "right"):
    _doc(f"segmentation_agreement_{_side}_pct", "segmentation", "%", f"{_side} labels: pixels in the majority counterpart segment (symmetrised)")
for _side in ("left", "right"):
    _doc(f"seg_winner_agreement_{_side}_pct", "wta", "%", f"{_side} segments with the same WTA disparity")
_doc("seg_subpixel_abs_error_max", "wta", "px", "max |painted disparity| difference (sub-pixel, Q4) of segments with the same winner")
_doc("seg_subpixel_abs_error_mean", "wta", "px", "mean |painted disparity| difference (sub-pixel, Q4) of segments with the same winner")
_doc("fis_score_abs_error_max", "wta", "", "max |FIS score| difference, segments with the same winner")
_doc("fis_score_abs_error_mean", "wta", "", "mean |FIS score| difference, segments with the same winner")
_doc("dc1_abs_error_max", "wta", "", "max |Data Cost 1| difference of the winners (same winner)")
_doc("dc2_abs_error_max", "wta", "", "max |Data Cost 2| difference of the winners (same winner)")
for _map, _stage in (("wta_left", "wta"), ("wta_right", "wta"), ("lr", "lrcheck"), ("final", "esr")):
    for _t in (0, 1, 2):
        _doc(f"{_map}_within_{_t}px_pct", _stage, "%", f"pixels of {_map} within {_t} px (both invalid agree)")
_doc("final_within_1px_valid_pct", "esr", "%", "pixels valid in either final map: both valid and within 1 px (a pixel valid in one map only disagrees)")
_doc("lr_mask_agreement_pct", "lrcheck", "%", "pixels with the same eq. (13) verdict")
_doc("esr_replaced_agreement_pct", "esr", "%", "pixels with the same eq. (15) replaced flag")
_doc("boundary_decision_agreement_pct", "wta", "%", "100 when the firmware (meta.json radiometric.boundary_refined) and the reference both ran the [boundary] refinement or both did not (enabled, or on_mismatch on a mismatched pair; docs/algorithm.md 4b), 0 otherwise; empty for dumps that predate the field")
_doc("wta_paint_isolated_pct", "wta", "%", "firmware WTA maps equal its segment table painted on its labels (both sides; with [boundary], refined by the reference on the same images)")
_doc("lr_mask_isolated_agreement_pct", "lrcheck", "%", "reference eq. (13) on the firmware's WTA maps vs the firmware's mask (with the candidate retry on: outside the segments eq. (13) rejects whole)")
_doc("lr_retry_isolated_agreement_pct", "lrcheck", "%", "the candidate retry (docs/algorithm.md 5b) on the firmware's WTA maps and segment winners, with the reference's candidates and FIS scores, vs the firmware's mask, over the segments eq. (13) rejects whole; empty when the retry is off")
_doc("esr_replaced_isolated_agreement_pct", "esr", "%", "reference ESR on the firmware's LR/right maps vs the firmware's replaced mask")
_doc("final_isolated_within_0px_pct", "esr", "%", "reference ESR on the firmware's LR/right maps vs the firmware's ESR map disp_esr (Q4)")
_doc("densify_isolated_within_1px_pct", "densify", "%", "reference densify on the firmware's ESR map vs the firmware's final map")
_doc("final_valid_firmware_pct", "esr", "%", "valid pixels of the firmware's final map")
_doc("final_valid_reference_pct", "esr", "%", "valid pixels of the reference's final map")
_doc("reference_fis_check_error", "wta", "", "reference: |fast FIS engine - ControlSystemSimulation| on sampled winners")


def reference_q4(disp: np.ndarray) -> np.ndarray:
    """A float reference map as the dump stores it (Q4, rounded), back in px."""
    return dumpmod.q4_to_disp(dumpmod.disp_to_q4(disp))


def map_agreement(a: np.ndarray, b: np.ndarray, tol: float) -> float:
    """% of pixels where both maps are invalid, or both valid within ``tol`` px."""
    va, vb = ~np.isnan(a), ~np.isnan(b)
    with np.errstate(invalid="ignore"):
        close = va & vb & (np.abs(np.where(va, a, 0) - np.where(vb, b, 0)) <= tol + 1e-9)
    return 100.0 * float(np.mean(close | (~va & ~vb)))


def valid_agreement_counts(a: np.ndarray, b: np.ndarray, tol: float = 1.0) -> tuple[int, int]:
    """(agreeing, compared) over the pixels valid in either map: agreeing = both valid within ``tol`` px."""
    va, vb = ~np.isnan(a), ~np.isnan(b)
    with np.errstate(invalid="ignore"):
        close = va & vb & (np.abs(np.where(va, a, 0) - np.where(vb, b, 0)) <= tol + 1e-9)
    return int(close.sum()), int((va | vb).sum())


def compute_metrics(d: dumpmod.Dump, r: ReferenceResult, cfg: Config) -> list[Metric]:
    """Every metric of METRIC_DOCS. End-to-end metrics compare the reference's own chain with the
    firmware's; *_isolated metrics run one reference stage on the firmware's inputs of that stage,
    which tells in which stage a difference starts."""
    values: dict[str, float | None] = {}
    for side in ("left", "right"):
        fw_labels = d[f"labels_{side}"]
        ref_labels = getattr(r, f"labels_{side}")
        same = fw_labels.shape == ref_labels.shape and np.array_equal(fw_labels, ref_labels)
        values[f"segmentation_agreement_{side}_pct"] = 100.0 if same else label_agreement(fw_labels, ref_labels)
        values[f"seg_winner_agreement_{side}_pct"] = None
        if same:
            fw_disp = d[f"seg_{side}"][:, dumpmod.SEG_DISP]
            values[f"seg_winner_agreement_{side}_pct"] = 100.0 * float(np.mean(fw_disp == getattr(r, f"dec_{side}").disparity))

    # FIS score and data costs of segments with the same winner (both sides pooled)
    errs: dict[str, list[np.ndarray]] = {"score": [], "dc1": [], "dc2": [], "sub": []}
    for side in ("left", "right"):
        if values[f"seg_winner_agreement_{side}_pct"] is None:
            continue
        seg = d[f"seg_{side}"]
        dec = getattr(r, f"dec_{side}")
        same = seg[:, dumpmod.SEG_DISP] == dec.disparity
        for key, col in (("score", dumpmod.SEG_SCORE), ("dc1", dumpmod.SEG_DC1), ("dc2", dumpmod.SEG_DC2)):
            errs[key].append(np.abs(dumpmod.from_q16(seg[same, col]) - getattr(dec, key)[same]))
        ref_q4 = dumpmod.disp_to_q4(dec.disparity_sub).astype(np.int64)
        errs["sub"].append(np.abs(seg[same, dumpmod.SEG_DISP_Q4] - ref_q4[same]) / dumpmod.DISP_SCALE)
    pooled = {k: np.concatenate(v) if v else np.zeros(0) for k, v in errs.items()}
    for key, name in (("score", "fis_score_abs_error"), ("dc1", "dc1_abs_error"), ("dc2", "dc2_abs_error"),
                      ("sub", "seg_subpixel_abs_error")):
        has = pooled[key].size > 0
        values[f"{name}_max"] = float(pooled[key].max()) if has else None
        if f"{name}_mean" in METRIC_DOCS:
            values[f"{name}_mean"] = float(pooled[key].mean()) if has else None

    maps = {  # the reference in the dump's Q4, so "within 0 px" means the same dump value
        "wta_left": (d.disp("disp_left_wta"), reference_q4(r.disp_left_wta)),
        "wta_right": (d.disp("disp_right_wta"), reference_q4(r.disp_right_wta)),
        "lr": (d.disp("disp_lr"), reference_q4(r.disp_lr)),
        "final": (d.disp("disp_final"), reference_q4(r.disp_final)),
    }
    for name, (fw, ref) in maps.items():
        for t in (0, 1, 2):
            values[f"{name}_within_{t}px_pct"] = map_agreement(fw, ref, t)
    agree, compared = valid_agreement_counts(*maps["final"], 1.0)
    values["final_within_1px_valid_pct"] = 100.0 * agree / compared if compared else 100.0
    values["lr_mask_agreement_pct"] = 100.0 * float(np.mean((d["lr_mask"] != 0) == r.lr_mask))
    values["esr_replaced_agreement_pct"] = 100.0 * float(np.mean((d["esr_replaced"] != 0) == r.esr_replaced))
    # stage-isolated
    painted = [
        np.where(d[f"seg_{side}"][:, dumpmod.SEG_DISP_Q4] < 0, dumpmod.INVALID_DISP, d[f"seg_{side}"][:, dumpmod.SEG_DISP_Q4])[
            d[f"labels_{side}"]
        ]
        == d[f"disp_{side}_wta"]
        for side in ("left", "right")
    ]
    fw_refined = d.meta.get("radiometric", {}).get("boundary_refined")
    values["boundary_decision_agreement_pct"] = None if fw_refined is None else 100.0 * float(bool(fw_refined) == r.boundary_refined)
    if r.boundary_refined:  # docs/algorithm.md 4b: the painted table, refined by the reference, is the WTA map
        tables = []
        for side in ("left", "right"):
            q4 = d[f"seg_{side}"][:, dumpmod.SEG_DISP_Q4]
            tables.append(np.where(q4 < 0, np.nan, q4 / dumpmod.DISP_SCALE)[d[f"labels_{side}"]])
        refined = boundary.refine_pair(tables[0], tables[1], r.left, r.right, cfg.boundary)
        painted = [dumpmod.disp_to_q4(m) == d[f"disp_{side}_wta"] for m, side in zip(refined, ("left", "right"))]
    values["wta_paint_isolated_pct"] = 100.0 * float(np.mean(np.concatenate([p.ravel() for p in painted])))
    fw_wta_l, fw_wta_r, fw_lr = d.disp("disp_left_wta"), d.disp("disp_right_wta"), d.disp("disp_lr")
    iso_lr, iso_mask = left_right_check(fw_wta_l, fw_wta_r, cfg.lr_check.max_diff)
    fw_mask = d["lr_mask"] != 0
    values["lr_retry_isolated_agreement_pct"] = None
    if cfg.lr_check.retry_candidates > 0:  # docs/algorithm.md 5b: the retry only touches wholly rejected segments
        lab = d["labels_left"]
        kept = np.zeros(int(lab.max()) + 1, dtype=bool)
        kept[np.unique(lab[iso_mask])] = True
        whole = ~kept[lab]
        values["lr_mask_isolated_agreement_pct"] = 100.0 * float(np.mean((iso_mask == fw_mask)[~whole])) if (~whole).any() else 100.0
        if r.labels_given and r.dec_left.candidate_scores is not None and whole.any():
            winner = d["seg_left"][:, dumpmod.SEG_DISP].astype(np.int64)
            _, retry_mask, _ = retry_rejected_segments(iso_lr, iso_mask, lab, winner, r.dec_left.candidates,
                                                       r.dec_left.candidate_scores, fw_wta_r, cfg.lr_check.max_diff,
                                                       cfg.lr_check.retry_candidates, cfg.lr_check.retry_min_share)
            values["lr_retry_isolated_agreement_pct"] = 100.0 * float(np.mean((retry_mask == fw_mask)[whole]))
    else:
        values["lr_mask_isolated_agreement_pct"] = 100.0 * float(np.mean(iso_mask == fw_mask))
    if cfg.esr.enabled:
        iso_final, iso_rep, _ = entropy_selective_refinement(fw_lr, fw_wta_r, cfg.esr.window, cfg.esr.tau, cfg.cost.max_disparity)
    else:
        iso_final, iso_rep = fw_lr, np.zeros(fw_lr.shape, dtype=bool)
    values["esr_replaced_isolated_agreement_pct"] = 100.0 * float(np.mean(iso_rep == (d["esr_replaced"] != 0)))
    fw_esr = d.disp("disp_esr") if "disp_esr" in d else d.disp("disp_final")  # dumps before the densify stage
    values["final_isolated_within_0px_pct"] = map_agreement(fw_esr, reference_q4(iso_final), 0)
    iso_dense, _ = densify_config(fw_esr, fw_wta_r, cfg.densify, cfg.cost.max_disparity)
    values["densify_isolated_within_1px_pct"] = map_agreement(d.disp("disp_final"), reference_q4(iso_dense), 1)
    values["reference_fis_check_error"] = r.fis_check_error
    values["final_valid_firmware_pct"] = 100.0 * float(np.mean(d["disp_final"] != dumpmod.INVALID_DISP))
    values["final_valid_reference_pct"] = 100.0 * float(np.mean(~np.isnan(r.disp_final)))

    metrics = [Metric(name, *METRIC_DOCS[name][:1], values[name], *METRIC_DOCS[name][1:]) for name in METRIC_DOCS]
    return sorted(metrics, key=lambda m: STAGES.index(m.stage))  # pipeline order (stable within a stage)


def compare_run(
    run_dir: str | Path,
    tolerances: str | Path | None = None,
    fis_path: str | Path | None = None,
    engine: str = "fast",
    own_segmentation: bool = False,
) -> Comparison:
    """Read the dump in ``run_dir``, run the reference on it, compute the metrics."""
    tol = load_tolerances(tolerances)
    d = dumpmod.read_dump(run_dir)
    meta_path = d.path / "meta.json"
    if not d.config_toml.strip():
        raise FatalError(f"{meta_path}: 'config_toml' is missing or empty; cannot run the reference with the firmware's config")
    ignored: dict[str, Any] = {}
    cfg = parse_config(d.config_toml, f"{meta_path} (config_toml)", strict=False, ignored=ignored)
    # Test-only switches (fault injection) change the firmware, never the reference: note them.
    defaults = Config(default_values())
    for section in REFERENCE_IGNORES:
        if hasattr_section(cfg, section):
            for key, value in getattr(cfg, section).as_dict().items():
                if value != defaults.get(f"{section}.{key}"):
                    ignored[f"{section}.{key}"] = value
    fis = Fis(load_definition(fis_path))
    fis_name = d.meta.get("fis_name")
    if fis_name is not None and fis_name != fis.defn.name:
        raise FatalError(f"{meta_path}: the firmware used FIS '{fis_name}' but {fis.defn.source} is '{fis.defn.name}' (pass --fis)")
    labels = (None, None) if own_segmentation else (d["labels_left"], d["labels_right"])
    r = match(d.left, d.right, cfg, fis, labels[0], labels[1], engine=engine)
    return Comparison(d, r, cfg, fis, compute_metrics(d, r, cfg), tol, ignored)
