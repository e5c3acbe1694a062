"""``fuzzyctl compare --dataset``: firmware vs reference on every frame of a dataset directory.

Per frame: ``fuzzystereo match --dump`` with the layout's search range (``dataset.Frame``), then
:func:`fuzzyctl.compare.compare_run` on that dump (the reference with the firmware's labels and
config). The frame passes when every metric is within ``common/compare/tolerances.toml``. The
overall figures pool the frames: winner agreement over all segments (both sides) and within-1-px
agreement over all pixels valid in either final map.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from . import dump as dumpmod
from .compare import compare_run, reference_q4, valid_agreement_counts
from .dataset import Frame
from .evaluate import firmware_run, run_dir_of


@dataclass
class FrameSummary:
    frame: Frame
    width: int = 0
    height: int = 0
    segments: int = 0  # left + right
    segments_same: int = 0  # with the reference's winner
    winner_left_pct: float = 0.0
    winner_right_pct: float = 0.0
    valid_pixels: int = 0  # valid in either final map
    valid_within_1px: int = 0
    final_within_1px_pct: float = 0.0  # over all pixels, both invalid agreeing
    both_valid: int = 0  # valid in both final maps
    both_valid_within_1px: int = 0
    firmware_valid: int = 0  # valid in the firmware's final map
    firmware_valid_within_1px: int = 0  # ... and the reference valid within 1 px
    failures: list[str] = field(default_factory=list)  # "metric = value (needs ...)"
    seconds: float = 0.0
    report: str = ""

    @property
    def winner_pct(self) -> float:
        return 100.0 * self.segments_same / self.segments if self.segments else 100.0

    @property
    def valid_within_1px_pct(self) -> float:
        return 100.0 * self.valid_within_1px / self.valid_pixels if self.valid_pixels else 100.0

    @property
    def passed(self) -> bool:
        return not self.failures


def compare_frame(frame: Frame, binary: str | Path, runs_root: str | Path | None = None,
                  tolerances: str | Path | None = None, fis_path: str | Path | None = None, engine: str = "fast",
                  config_path: str | Path | None = None, threads: int | None = None,
                  report: bool = False) -> FrameSummary:
    """Run the firmware on the frame (into ``runs_root/<set>/<name>/``, else a temporary directory)
    and compare its dump with the reference; the HTML report lands beside the run when ``report``."""
    t0 = time.perf_counter()
    if runs_root is None:
        with tempfile.TemporaryDirectory(prefix="fuzzyctl-compare-") as tmp:
            return _compare(frame, firmware_run(frame, binary, Path(tmp), config_path, threads, reuse=False),
                            tolerances, fis_path, engine, False, t0)
    run = firmware_run(frame, binary, run_dir_of(runs_root, frame), config_path, threads, reuse=False)
    return _compare(frame, run, tolerances, fis_path, engine, report, t0)


def _compare(frame: Frame, run: Path, tolerances, fis_path, engine: str, report: bool, t0: float) -> FrameSummary:
    c = compare_run(run, tolerances, fis_path, engine=engine)
    d, r = c.dump, c.reference
    s = FrameSummary(frame, width=d.width, height=d.height)
    for side in ("left", "right"):
        fw = d[f"seg_{side}"][:, dumpmod.SEG_DISP]
        same = int(np.sum(fw == getattr(r, f"dec_{side}").disparity))
        s.segments += fw.size
        s.segments_same += same
        setattr(s, f"winner_{side}_pct", 100.0 * same / fw.size if fw.size else 100.0)
    fw_final, ref_final = d.disp("disp_final"), reference_q4(r.disp_final)
    s.valid_within_1px, s.valid_pixels = valid_agreement_counts(fw_final, ref_final, 1.0)
    fw_ok, ref_ok = ~np.isnan(fw_final), ~np.isnan(ref_final)
    with np.errstate(invalid="ignore"):
        close = fw_ok & ref_ok & (np.abs(fw_final - ref_final) <= 1.0 + 1e-9)
    s.both_valid, s.both_valid_within_1px = int((fw_ok & ref_ok).sum()), int(close.sum())
    s.firmware_valid, s.firmware_valid_within_1px = int(fw_ok.sum()), int(close.sum())
    s.final_within_1px_pct = float(c.metric("final_within_1px_pct").value or 0.0)
    s.failures = [f"{m.name} = {m.value:.4g} (needs {t.text()})" for m, t in c.failures()]
    if report:
        from .report import write_report

        s.report = str(write_report(c, run / "report.html"))
    s.seconds = time.perf_counter() - t0
    return s


def comparer(binary: str | Path, **kwargs) -> partial:
    """A picklable one-argument :func:`compare_frame` for :func:`fuzzyctl.parallel.run_frames`."""
    return partial(compare_frame, binary=binary, **kwargs)


def pct(num: int, den: int) -> float:
    return 100.0 * num / den if den else 100.0


def pooled(summaries: list[FrameSummary]) -> tuple[float, float]:
    """(winner agreement %, within-1-px % of valid pixels) over all frames' segments / pixels."""
    seg = sum(s.segments for s in summaries)
    same = sum(s.segments_same for s in summaries)
    valid = sum(s.valid_pixels for s in summaries)
    within = sum(s.valid_within_1px for s in summaries)
    return (100.0 * same / seg if seg else 100.0, 100.0 * within / valid if valid else 100.0)
