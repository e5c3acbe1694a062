"""Every issue target, measured in one run: ``fuzzyctl targets``.

The measurements are the firmware's own benchmark commands, run as a user would run them —
``eval`` (clean and the four radiometric distortions), ``bench`` (KITTI 2015 and Middlebury Aloe),
``sim generate`` + ``detect-eval``, ``sim suite``, ``run`` with an injected stall (simulated and wall
clock), ``sim track-eval`` — plus the bad-input checks the issues name. Each raw result is kept under
``OUT/raw/``; the verdicts go to ``OUT/targets.json`` and a single HTML page ``OUT/index.html``.

The verdict functions (``*_targets``) are pure: loaded JSON in, :class:`Target` rows out, so the
tests check them on hand-made results. Nothing here decides a figure: each row's ``measured`` is read
from the firmware's JSON, and ``met`` compares it with the issue's number.
"""

from __future__ import annotations

import html
import json
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from . import firmware, paths
from .errors import FatalError

#: The distortions `eval --radiometric` must provide (issue 2).
RADIOMETRIC = ("gain", "gamma", "mixed", "noise")
#: Paper Table II (issue 2): KITTI average error and bad-2.
KITTI_AVG_ERR_PX = 1.34
KITTI_BAD2_PCT = 14.3
RADIOMETRIC_RATIO = 1.25
#: Issue 4.
DETECTION_RATE = 0.97
FP_PER_FRAME = 0.1
ROAD_IOU = 0.9
DISTANCE_ERR_MEDIAN = 0.05
#: Issue 5.
SUITE_SUCCESS_PCT = 98.0
WATCHDOG_MS = 100.0
TRACK_VEL_MPS = 0.1

BENCH_FRAMES = ("kitti2015/000046", "middlebury2006-third/Aloe")


@dataclass
class Target:
    issue: int
    name: str
    target: str
    measured: str
    met: bool | None  # None: not measured (skipped), with the reason in `measured`
    details: dict[str, Any] = field(default_factory=dict)


@dataclass
class Options:
    binary: Path
    datasets: Path
    out: Path
    quick: bool = False
    issues: tuple[int, ...] = (2, 4, 5)
    detect_frames: int = 300
    detect_seed: int = 64
    suite_count: int = 100
    suite_seed: int = 111
    jobs: int = 2
    bench_repeats: int = 5
    config: Path | None = None


# --------------------------------------------------------------------------------------------
# Verdicts (pure)
# --------------------------------------------------------------------------------------------

def _f(v: float, nd: int = 2) -> str:
    return f"{v:.{nd}f}"


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a proportion k / n (95 % by default), as fractions; (0, 1) for n = 0."""
    if n <= 0:
        return 0.0, 1.0
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * ((p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5) / d
    return max(0.0, c - h), min(1.0, c + h)


def _ci(k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    return f"95 % CI {100 * lo:.1f}-{100 * hi:.1f} %"


def eval_targets(clean: dict[str, Any], radiometric: dict[str, dict[str, Any]]) -> list[Target]:
    """Issue 2's accuracy rows from `eval --baseline bm,sgbm --json` (clean) and one `--radiometric NAME`
    result per distortion (missing distortions are reported as not measured)."""
    sets = clean.get("sets", {})
    rows: list[Target] = []
    for name in sorted(s for s in sets if s.startswith("kitti")):
        fz = sets[name]["fuzzystereo"]
        noc = fz.get("noc")
        extra = f"; non-occluded {_f(noc['avg_err'], 3)} px / {_f(noc['bad2'])} %" if noc else ""
        rows.append(Target(2, f"{name}: average error (all pixels)", f"<= {KITTI_AVG_ERR_PX} px",
                           f"{_f(fz['avg_err'], 3)} px{extra}", fz["avg_err"] <= KITTI_AVG_ERR_PX,
                           {"avg_err": fz["avg_err"], "noc_avg_err": noc["avg_err"] if noc else None}))
        rows.append(Target(2, f"{name}: bad-2 (all pixels)", f"<= {KITTI_BAD2_PCT} %", f"{_f(fz['bad2'])} %",
                           fz["bad2"] <= KITTI_BAD2_PCT, {"bad2": fz["bad2"]}))
    third = sets.get("middlebury2006-third")
    if third and "sgbm" in third:
        a, b = third["fuzzystereo"]["bad2"], third["sgbm"]["bad2"]
        rows.append(Target(2, "Middlebury 2006 third: bad-2 no worse than StereoSGBM", "<= SGBM",
                           f"{_f(a)} % vs SGBM {_f(b)} %", a <= b, {"fuzzystereo": a, "sgbm": b}))
    elif third:
        rows.append(Target(2, "Middlebury 2006 third: bad-2 no worse than StereoSGBM", "<= SGBM",
                           "SGBM not run", None))
    for dist in RADIOMETRIC:
        r = radiometric.get(dist)
        if r is None:
            rows.append(Target(2, f"radiometric '{dist}'", f"<= {RADIOMETRIC_RATIO}x clean and < SGBM",
                               "not measured", None))
            continue
        cells = []
        for name, clean_set in sets.items():
            dset = r.get("sets", {}).get(name)
            if not dset:
                continue
            c, d = clean_set["fuzzystereo"]["bad2"], dset["fuzzystereo"]["bad2"]
            s = dset.get("sgbm", {}).get("bad2")
            cells.append({"set": name, "clean": c, "distorted": d, "sgbm": s,
                          "ratio_ok": d <= RADIOMETRIC_RATIO * c, "sgbm_ok": None if s is None else d < s})
        n_ratio = sum(c["ratio_ok"] for c in cells)
        n_sgbm = sum(bool(c["sgbm_ok"]) for c in cells)
        missed = [f"{c['set']} {_f(c['distorted'])} % ({_f(c['distorted'] / c['clean'])}x clean"
                  f"{'' if c['sgbm'] is None else ', SGBM ' + _f(c['sgbm'])})"
                  for c in cells if not c["ratio_ok"] or c["sgbm_ok"] is False]
        rows.append(Target(
            2, f"radiometric '{dist}': bad-2 <= {RADIOMETRIC_RATIO}x clean and below SGBM",
            f"all {len(cells)} sets", f"{n_ratio}/{len(cells)} within {RADIOMETRIC_RATIO}x, {n_sgbm}/{len(cells)} below SGBM"
            + (f"; missed: {'; '.join(missed)}" if missed else ""),
            bool(cells) and n_ratio == len(cells) and n_sgbm == len(cells), {"cells": cells}))
    return rows


def eval_speed_targets(clean: dict[str, Any]) -> list[Target]:
    """Issue 2's speed target on every evaluated set: `eval` times fuzzystereo and StereoSGBM on the same
    frames in the same process (all threads, one run per frame: noisier than `bench`, but every frame)."""
    rows = []
    for name, v in clean.get("sets", {}).items():
        fz, sg = v.get("fuzzystereo"), v.get("sgbm")
        if not fz or not sg or not sg.get("ms_per_frame"):
            continue
        ratio = fz["ms_per_frame"] / sg["ms_per_frame"]
        rows.append(Target(2, f"speed {name}, every frame ({fz['frames']}), from eval (all threads, one run each)",
                           "<= 1.00x StereoSGBM 3-way",
                           f"{ratio:.2f}x ({_f(fz['ms_per_frame'], 1)} vs {_f(sg['ms_per_frame'], 1)} ms per frame)",
                           ratio <= 1.0, {"ratio": ratio}))
    return rows


def bench_targets(benches: dict[str, dict[str, Any]]) -> list[Target]:
    """Issue 2's speed rows from `bench --json` per frame: fuzzystereo / SGBM 3-way <= 1 at each thread count."""
    rows = []
    for frame, b in benches.items():
        for run in b.get("runs", []):
            ratio = run["ratio_fuzzystereo_sgbm"]
            rows.append(Target(
                2, f"speed {frame} ({b['width']}x{b['height']}, D={b['max_disparity']}), {run['threads']} thread(s)",
                "<= 1.00x StereoSGBM 3-way",
                f"{ratio:.2f}x ({_f(run['fuzzystereo_ms'], 1)} vs {_f(run['sgbm_ms'], 1)} ms, median of {b['repeats']})",
                ratio <= 1.0, {"ratio": ratio, "stages_ms": run["stages_ms"], "fuzzystereo_ms": run["fuzzystereo_ms"],
                               "sgbm_ms": run["sgbm_ms"], "bm_ms": run["bm_ms"]}))
    return rows


def detect_targets(de: dict[str, Any]) -> list[Target]:
    """Issue 4's rows from `detect-eval --json` (the matcher's disparity)."""
    o = de["overall"]
    n = o["frames"]
    rate, fp = o["detection_rate"], o["false_positives_per_frame"]
    ms = o.get("ms_per_frame", {})
    ratio = ms.get("detect_over_matcher")
    rows = [
        Target(4, f"detection rate ({n} generated frames, {o['gt_obstacles']} obstacles)", f">= {DETECTION_RATE:.0%}",
               f"{rate:.1%} (box alone {o['detection_rate_box_only']:.1%}; binomial {_ci(o['detected'], o['gt_obstacles'])}, "
               f"wider in truth: obstacles of one frame are not independent)", rate >= DETECTION_RATE,
               {"detection_rate": rate, "per_type": {k: v["detection_rate"] for k, v in de.get("per_type", {}).items()}}),
        Target(4, "false positives per frame", f"<= {FP_PER_FRAME}", _f(fp), fp <= FP_PER_FRAME, {"fp_per_frame": fp}),
        Target(4, "road-mask IoU", f">= {ROAD_IOU}", _f(o["road_iou"], 3), o["road_iou"] >= ROAD_IOU, {}),
        Target(4, "distance error of detected obstacles, median", f"<= {DISTANCE_ERR_MEDIAN:.0%}",
               f"{o['distance_rel_error_median']:.1%} (p90 {o['distance_rel_error_p90']:.1%})",
               o["distance_rel_error_median"] <= DISTANCE_ERR_MEDIAN, {}),
    ]
    if ratio is not None:
        rows.append(Target(4, "detection stages' time / the matcher's, same frames", "< 1",
                           f"{ratio:.2f} ({_f(ms['detect_total'], 1)} vs {_f(ms['matcher_total'], 1)} ms per frame)",
                           ratio < 1.0, {}))
    return rows


def oracle_target(de: dict[str, Any]) -> Target:
    """Context for issue 4: the same frames with the exact disparity (the detection stages' own limit)."""
    o = de["overall"]
    return Target(4, "detection with the exact disparity instead of the matcher's (the detector alone), same frames",
                  f">= {DETECTION_RATE:.0%} at <= {FP_PER_FRAME} FP per frame",
                  f"{o['detection_rate']:.1%} at {o['false_positives_per_frame']:.2f} FP per frame",
                  o["detection_rate"] >= DETECTION_RATE and o["false_positives_per_frame"] <= FP_PER_FRAME, {})


def suite_targets(s: dict[str, Any]) -> list[Target]:
    """Issue 5's suite rows from `sim suite --json`."""
    contacts = s["collisions"] + s["struck"]
    rows = [
        Target(5, f"closed-loop suite: goal reached ({s['solvable']} scenarios with a free path, seed {s['seed']})",
               f">= {SUITE_SUCCESS_PCT:.0f} %", f"{s['reached']}/{s['solvable']} ({_f(s['success_pct'], 1)} %, "
               f"{_ci(s['reached'], s['solvable'])})",
               s["success_pct"] >= SUITE_SUCCESS_PCT, {}),
        Target(5, "closed-loop suite: contacts (collisions + struck)", "0",
               f"{contacts} ({s['collisions']} collisions, {s['struck']} struck)", contacts == 0, {}),
        Target(5, f"closed-loop suite: safe stop without a free path ({s['blocked']} scenarios)", "100 %",
               f"{s['blocked_safe_stop']}/{s['blocked']}", s["blocked_safe_stop"] == s["blocked"], {}),
    ]
    if s.get("errors"):
        rows.append(Target(5, "closed-loop suite: scenarios that ended in an error", "0", str(s["errors"]), False, {}))
    return rows


def watchdog_targets(sim_run: dict[str, Any] | None, wall_run: dict[str, Any] | None) -> list[Target]:
    """Issue 5's watchdog rows from two `run --stall-frame ... --json` results."""
    rows = []
    # The simulated-clock run reports the stop's delay after the missed frame's deadline; the wall-clock
    # run (--realtime) after the stall began, measured by the watchdog thread.
    for label, r, key in (("simulated clock", sim_run, "watchdog_stop_after_deadline_ms"),
                          ("wall clock", wall_run, "watchdog_stop_wall_after_stall_ms")):
        if r is None:
            rows.append(Target(5, f"watchdog stop after a stall ({label})", f"<= {WATCHDOG_MS:.0f} ms", "not measured", None))
            continue
        v = r.get(key)
        if v is None or r.get("watchdog_trips", 0) < 1:
            rows.append(Target(5, f"watchdog stop after a stall ({label})", f"<= {WATCHDOG_MS:.0f} ms",
                               "the watchdog did not trip", False, {}))
            continue
        rows.append(Target(5, f"watchdog stop after a stall ({label})", f"<= {WATCHDOG_MS:.0f} ms",
                           f"{_f(v, 1)} ms after the stall began", v <= WATCHDOG_MS, {"ms": v}))
    return rows


def tracking_targets(te: dict[str, Any]) -> list[Target]:
    """Issue 5's tracking rows from `sim track-eval --json`."""
    f, r = te["filt_pos_rmse_m"], te["raw_pos_rmse_m"]
    return [
        Target(5, f"tracking: position RMSE ({te['trials']} generated trajectories x {te['frames']} frames, Gaussian "
               f"measurement noise {te['sigma_m']} m)", "< raw measurements",
               f"{f:.3f} m vs raw {r:.3f} m", f < r, {}),
        Target(5, f"tracking: velocity error after {te['settle_frames']} frames (95 % of frames)",
               f"<= {TRACK_VEL_MPS} m/s",
               f"p95 {te['vel_p95_after_mps']:.3f} m/s (RMS {te['vel_rmse_after_mps']:.3f}, max {te['vel_max_after_mps']:.3f})",
               te["vel_p95_after_mps"] <= TRACK_VEL_MPS, {}),
    ]


def vision_tracking_targets(te: dict[str, Any], runs: int) -> list[Target]:
    """Issue 5's tracking targets on the simulator's own vision measurements: `fuzzyctl track-errors` over the
    suite's run records, moving obstacles only (truth from the recorded world)."""
    m = te["movers"]
    where = f"closed-loop suite records ({runs} runs), moving obstacles"
    if not m["n"]:
        return [Target(5, f"tracking on vision measurements: {where}", "filtered < raw; p95 <= 0.1 m/s",
                       "no moving obstacle was tracked", None)]
    rows = [Target(5, f"tracking on vision measurements: position RMSE ({where}, {m['n']} updates)",
                   "< raw measurements", f"{m['filt_pos_rmse_m']:.3f} m vs raw {m['raw_pos_rmse_m']:.3f} m",
                   m["filt_pos_rmse_m"] < m["raw_pos_rmse_m"], dict(m))]
    if m["vel_after10_n"]:
        p95 = m["vel_after10_p95_mps"]
        rows.append(Target(5, f"tracking on vision measurements: velocity error from the 10th hit ({m['vel_after10_n']} updates)",
                           f"<= {TRACK_VEL_MPS} m/s (95 %)",
                           f"p95 {p95:.3f} m/s (median {m['vel_after10_median_mps']:.3f}, RMS {m['vel_after10_rms_mps']:.3f})",
                           p95 <= TRACK_VEL_MPS, {}))
    return rows


def check_target(issue: int, name: str, results: list[tuple[str, bool, str]]) -> Target:
    """One row for a set of bad-input checks: (case, passed, message seen)."""
    ok = sum(p for _, p, _ in results)
    failed = [f"{c}: {m}" for c, p, m in results if not p]
    return Target(issue, name, "non-zero exit, one line naming the field / file",
                  f"{ok}/{len(results)} cases" + (f"; failed: {'; '.join(failed)}" if failed else ""),
                  ok == len(results), {"cases": [{"case": c, "passed": p, "message": m} for c, p, m in results]})


# --------------------------------------------------------------------------------------------
# Running the measurements
# --------------------------------------------------------------------------------------------

class _Runner:
    def __init__(self, opt: Options, log: Callable[[str], None]) -> None:
        self.opt = opt
        self.log = log
        self.raw = opt.out / "raw"
        self.raw.mkdir(parents=True, exist_ok=True)
        self.commands: list[str] = []

    def fw(self, args: list[str], timeout: float = 7200.0) -> None:
        """A firmware command that must succeed (firmware.run: FatalError naming it otherwise)."""
        self.commands.append(" ".join(map(str, [self.opt.binary, *args])))
        t0 = time.monotonic()
        firmware.run(self.opt.binary, [str(a) for a in args], timeout=timeout)
        self.log(f"  {' '.join(map(str, args[:2]))} ... {time.monotonic() - t0:.0f} s")

    def fw_expect_error(self, args: list[str]) -> subprocess.CompletedProcess:
        """A firmware command given bad input on purpose: its exit code and stderr, whatever they are."""
        cmd = [str(self.opt.binary), *map(str, args)]
        self.commands.append(" ".join(cmd))
        try:
            return subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        except subprocess.TimeoutExpired as exc:
            raise FatalError(f"'{' '.join(cmd[1:])}' did not finish within 120 s") from exc

    def fw_json(self, args: list[str], name: str, timeout: float = 7200.0) -> dict[str, Any]:
        path = self.raw / name
        self.fw([*args, "--json", path], timeout)
        try:
            return json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise FatalError(f"{path}: the firmware's JSON cannot be read: {exc}") from exc

    def cfg(self) -> list[str]:
        return ["--config", str(self.opt.config)] if self.opt.config else []


def _datasets_present(d: Path) -> bool:
    return d.is_dir() and any(d.iterdir())


def _bad_input_checks_issue2(r: _Runner, tmp: Path) -> list[tuple[str, bool, str]]:
    import cv2
    import numpy as np

    a = tmp / "a.png"
    b = tmp / "b.png"
    cv2.imwrite(str(a), np.full((40, 64), 100, np.uint8))
    cv2.imwrite(str(b), np.full((40, 48), 100, np.uint8))
    junk = tmp / "junk.png"
    junk.write_bytes(b"not an image")
    bad_cfg = tmp / "bad.toml"
    bad_cfg.write_text("[segmentation]\nregion_size = 0\n")
    cases = [
        ("missing file", ["match", "--left", tmp / "none.png", "--right", a, "--out", tmp / "o"], "none.png"),
        ("size mismatch", ["match", "--left", a, "--right", b, "--out", tmp / "o"], "48x40"),
        ("unreadable image", ["match", "--left", junk, "--right", a, "--out", tmp / "o"], "junk.png"),
        ("out-of-range config", ["match", "--left", a, "--right", a, "--config", bad_cfg, "--out", tmp / "o"],
         "segmentation.region_size"),
    ]
    return _run_cases(r, cases)


def _bad_input_checks_issue4(r: _Runner, tmp: Path) -> list[tuple[str, bool, str]]:
    scene = paths.common_dir() / "sim" / "scenes" / "demo.toml"
    text = scene.read_text()
    variants = {
        "negative baseline": (text.replace("baseline_m = 0.12", "baseline_m = -0.12", 1), "camera.baseline_m"),
        "unknown texture": (text.replace('texture = "wood"', 'texture = "plaid"', 1), "obstacles[0].texture"),
        "obstacle below ground": (text.replace('texture = "wood"', 'texture = "wood"\nz_m = -0.5', 1), "obstacles[0].z_m"),
    }
    cases = []
    for name, (t, field_name) in variants.items():
        p = tmp / (name.replace(" ", "_") + ".toml")
        p.write_text(t)
        cases.append((name, ["sim", "render", p, "--out", tmp / "render"], field_name))
    return _run_cases(r, cases)


def _run_cases(r: _Runner, cases) -> list[tuple[str, bool, str]]:
    out = []
    for name, args, must_name in cases:
        proc = r.fw_expect_error(args)
        lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
        msg = lines[-1] if lines else ""
        crashed = proc.returncode < 0 or proc.returncode > 125
        passed = proc.returncode != 0 and not crashed and len(lines) == 1 and must_name in msg
        out.append((name, passed, msg or f"exit {proc.returncode}, no message"))
    return out


def measure(opt: Options, log: Callable[[str], None] = lambda s: None) -> tuple[list[Target], list[str]]:
    """Run every measurement of the selected issues; (rows, the firmware commands run)."""
    r = _Runner(opt, log)
    rows: list[Target] = []
    have_data = _datasets_present(opt.datasets)
    with tempfile.TemporaryDirectory(prefix="fuzzystereo-targets-") as tmpdir:
        tmp = Path(tmpdir)
        if 2 in opt.issues:
            if have_data:
                log("issue 2: eval, clean and four radiometric distortions")
                ds = ["--dataset", str(opt.datasets), "--baseline", "bm,sgbm", *r.cfg()]
                clean = r.fw_json(["eval", *ds], "eval_clean.json")
                rad = {d: r.fw_json(["eval", *ds, "--radiometric", d], f"eval_{d}.json") for d in RADIOMETRIC}
                rows += eval_targets(clean, rad)
                log("issue 2: bench")
                benches = {}
                for frame in BENCH_FRAMES:
                    benches[frame] = r.fw_json(["bench", "--dataset", str(opt.datasets), "--frame", frame,
                                                "--repeats", str(opt.bench_repeats), *r.cfg()],
                                               "bench_" + frame.replace("/", "_") + ".json")
                rows += bench_targets(benches)
                rows += eval_speed_targets(clean)
            else:
                why = f"datasets not found at {opt.datasets} (set FUZZYSTEREO_DATASETS or --datasets)"
                rows.append(Target(2, "accuracy, radiometric and speed targets", "see issue 2", why, None))
            log("issue 2: bad input")
            rows.append(check_target(2, "bad input (missing file, size mismatch, unreadable image, out-of-range config)",
                                     _bad_input_checks_issue2(r, tmp)))
        if 4 in opt.issues:
            log(f"issue 4: sim generate --count {opt.detect_frames} --seed {opt.detect_seed}, detect-eval")
            gen = tmp / "generated"
            r.fw(["sim", "generate", "--count", str(opt.detect_frames), "--seed", str(opt.detect_seed), "--out", gen])
            rows += detect_targets(r.fw_json(["detect-eval", "--dataset", gen, *r.cfg()], "detect_eval.json"))
            oracle = r.fw_json(["detect-eval", "--dataset", gen, "--oracle-disparity", *r.cfg()], "detect_eval_oracle.json")
            rows.append(oracle_target(oracle))
            rows.append(check_target(4, "bad scene file (negative baseline, unknown texture, obstacle below ground)",
                                     _bad_input_checks_issue4(r, tmp)))
        if 5 in opt.issues:
            log(f"issue 5: sim suite --count {opt.suite_count} --seed {opt.suite_seed} (recorded for the tracking rows)")
            records = tmp / "suite_records"
            rows += suite_targets(r.fw_json(["sim", "suite", "--count", str(opt.suite_count), "--seed",
                                             str(opt.suite_seed), "--jobs", str(opt.jobs), "--record", records,
                                             "--snapshot-every", "0", *r.cfg()], "suite.json"))
            from .trackerrors import track_errors

            runs = sorted(p for p in records.iterdir() if (p / "run.json").is_file()) if records.is_dir() else []
            if runs:
                te = track_errors(runs)
                (r.raw / "track_errors_suite.json").write_text(json.dumps(te, indent=2) + "\n")
                vision_rows = vision_tracking_targets(te, len(runs))
            else:
                vision_rows = [Target(5, "tracking on vision measurements", "filtered < raw; p95 <= 0.1 m/s",
                                      "the suite wrote no run records", None)]
            log("issue 5: watchdog (stall injected at frame 8)")
            mission = paths.common_dir() / "sim" / "scenes" / "mission.toml"
            stall = ["run", "--source", f"sim:{mission}", "--motors", "sim", "--quiet", "--stall-frame", "8",
                     "--stall-ms", "500", "--max-frames", "12", *r.cfg()]
            rows += watchdog_targets(r.fw_json(stall, "watchdog_sim.json", 600),
                                     r.fw_json([*stall, "--realtime"], "watchdog_wall.json", 600))
            log("issue 5: tracking")
            rows += tracking_targets(r.fw_json(["sim", "track-eval", *r.cfg()], "track_eval.json", 600))
            rows += vision_rows
    return rows, r.commands


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------

def load_previous(path: Path) -> dict[str, dict[str, Any]]:
    """Rows of an earlier `targets.json` by (issue, name), for the "before" column."""
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise FatalError(f"{path}: cannot read an earlier targets.json: {exc}") from exc
    if doc.get("format") != "fuzzystereo-targets":
        raise FatalError(f"{path}: not a targets.json (format {doc.get('format')!r})")
    return {f"{t['issue']}:{t['name']}": t for t in doc.get("targets", [])}


def previous_of(t: Target, prev: dict[str, dict[str, Any]] | None) -> dict[str, Any] | None:
    return None if prev is None else prev.get(f"{t.issue}:{t.name}")


def summary(rows: Iterable[Target]) -> dict[str, int]:
    rows = list(rows)
    return {"met": sum(t.met is True for t in rows), "missed": sum(t.met is False for t in rows),
            "not_measured": sum(t.met is None for t in rows), "total": len(rows)}


def write_json(rows: list[Target], commands: list[str], opt: Options, path: Path) -> None:
    doc = {"format": "fuzzystereo-targets", "version": 1, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
           "binary": str(opt.binary), "datasets": str(opt.datasets), "quick": opt.quick,
           "config": str(opt.config) if opt.config else None, "summary": summary(rows),
           "targets": [asdict(t) for t in rows], "commands": commands}
    path.write_text(json.dumps(doc, indent=2) + "\n")


def _speed_chart(rows: list[Target]) -> str | None:
    speed = [t for t in rows if t.name.startswith("speed ") and t.details.get("stages_ms")]
    if not speed:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 0.55 * len(speed) + 1.2))
    labels = [t.name.replace("speed ", "") for t in speed]
    stages = list(speed[0].details["stages_ms"].keys())
    left = [0.0] * len(speed)
    cmap = plt.get_cmap("tab10")
    for k, st in enumerate(stages):
        vals = [t.details["stages_ms"].get(st, 0.0) for t in speed]
        ax.barh(range(len(speed)), vals, left=left, color=cmap(k % 10), label=st, height=0.5)
        left = [a + b for a, b in zip(left, vals)]
    for i, t in enumerate(speed):
        ax.plot([t.details["sgbm_ms"]] * 2, [i - 0.35, i + 0.35], color="k", lw=2)
    ax.set_yticks(range(len(speed)), labels, fontsize=7)
    ax.set_xlabel("ms per frame (stacked: fuzzystereo stages; black bar: StereoSGBM 3-way)")
    ax.legend(fontsize=7, ncol=4, loc="lower right")
    ax.invert_yaxis()
    return _png(fig)


def _png(fig) -> str:
    from .report import figure_data_uri

    return figure_data_uri(fig, dpi=100, tight=True)


def _radiometric_chart(rows: list[Target]) -> str | None:
    """bad-2 per set: clean, each distortion, StereoSGBM under it, and the 1.25x line."""
    rad = [t for t in rows if t.name.startswith("radiometric '") and t.details.get("cells")]
    if not rad:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sets = [c["set"] for c in rad[0].details["cells"]]
    fig, axes = plt.subplots(1, len(rad), figsize=(3.2 * len(rad), 3.2), sharey=True, squeeze=False)
    for ax, t in zip(axes[0], rad):
        cells = {c["set"]: c for c in t.details["cells"]}
        xs = range(len(sets))
        clean = [cells[s]["clean"] if s in cells else 0 for s in sets]
        dist = [cells[s]["distorted"] if s in cells else 0 for s in sets]
        sgbm = [cells[s]["sgbm"] or 0 if s in cells else 0 for s in sets]
        ax.bar([x - 0.27 for x in xs], clean, 0.27, color="#999", label="clean")
        ax.bar(list(xs), dist, 0.27, color=["#1a7f37" if cells.get(s, {}).get("ratio_ok") and cells.get(s, {}).get("sgbm_ok")
                                            else "#cf222e" for s in sets], label="distorted")
        ax.bar([x + 0.27 for x in xs], sgbm, 0.27, color="#6e7781", alpha=0.6, label="SGBM distorted")
        for x, c in zip(xs, clean):
            ax.plot([x - 0.4, x + 0.4], [RADIOMETRIC_RATIO * c] * 2, color="k", lw=1)
        ax.set_title(t.name.split(":")[0], fontsize=9)
        ax.set_xticks(list(xs), [s.replace("middlebury", "midd") for s in sets], rotation=60, fontsize=7)
    axes[0][0].set_ylabel("bad-2 %")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("fuzzystereo bad-2 (green: within 1.25x clean (black line) and below SGBM; red: not)", fontsize=9)
    return _png(fig)


def write_html(rows: list[Target], commands: list[str], opt: Options, path: Path,
               prev: dict[str, dict[str, Any]] | None = None) -> None:
    s = summary(rows)
    badge = {True: ("met", "#1a7f37"), False: ("missed", "#cf222e"), None: ("not measured", "#6e7781")}
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>fuzzystereo targets</title><style>",
        "body{font:14px system-ui,sans-serif;margin:2em;max-width:1100px}table{border-collapse:collapse;width:100%}",
        "td,th{border-bottom:1px solid #ddd;padding:4px 8px;text-align:left;vertical-align:top}",
        ".b{color:#fff;border-radius:4px;padding:1px 6px;font-size:12px;white-space:nowrap}code{font-size:12px}",
        "</style></head><body>",
        f"<h1>fuzzystereo: every issue target, measured</h1><p>{s['met']} met, {s['missed']} missed, "
        f"{s['not_measured']} not measured, of {s['total']}. {'<b>Quick mode</b>: small samples, not the issues’ sizes. ' if opt.quick else ''}"
        f"Binary <code>{html.escape(str(opt.binary))}</code>, datasets <code>{html.escape(str(opt.datasets))}</code>"
        f"{', config <code>' + html.escape(str(opt.config)) + '</code>' if opt.config else ''}; {time.strftime('%Y-%m-%d %H:%M')}.</p>",
    ]
    for issue in sorted({t.issue for t in rows}):
        before = "<th>before</th>" if prev is not None else ""
        parts.append(f"<h2>Issue {issue}</h2><table><tr><th>target</th><th>required</th>{before}<th>measured</th><th></th></tr>")
        for t in (t for t in rows if t.issue == issue):
            label, colour = badge[t.met]
            cell = ""
            if prev is not None:
                p = previous_of(t, prev)
                cell = f"<td>{html.escape(p['measured']) + ' (' + badge[p['met']][0] + ')' if p else '-'}</td>"
            parts.append(f"<tr><td>{html.escape(t.name)}</td><td>{html.escape(t.target)}</td>{cell}"
                         f"<td>{html.escape(t.measured)}</td><td><span class='b' style='background:{colour}'>{label}</span></td></tr>")
        parts.append("</table>")
        if issue == 2:
            for chart, alt in ((_radiometric_chart(rows), "radiometric cells"), (_speed_chart(rows), "stage timings")):
                if chart:
                    parts.append(f"<p><img src='{chart}' alt='{alt}'></p>")
    parts.append("<h2>Commands run</h2><pre>" + html.escape("\n".join(commands)) + "</pre>")
    parts.append("<p>Raw results of each command: <code>raw/</code> beside this page.</p></body></html>")
    path.write_text("".join(parts))


def run_targets(opt: Options, log: Callable[[str], None] = lambda s: None,
                prev: dict[str, dict[str, Any]] | None = None) -> tuple[list[Target], Path]:
    """Measure, then write OUT/targets.json and OUT/index.html; (rows, the HTML path)."""
    opt.out.mkdir(parents=True, exist_ok=True)
    rows, commands = measure(opt, log)
    write_json(rows, commands, opt, opt.out / "targets.json")
    page = opt.out / "index.html"
    write_html(rows, commands, opt, page, prev)
    return rows, page


if __name__ == "__main__":  # pragma: no cover
    sys.exit("use: fuzzyctl targets")
