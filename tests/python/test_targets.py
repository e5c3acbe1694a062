"""`fuzzyctl targets`: the verdicts on hand-made results, and the whole chain on small samples."""

from __future__ import annotations

import json

import pytest

from fuzzyctl.cli import main
from fuzzyctl.targets import (
    bench_targets,
    check_target,
    detect_targets,
    eval_targets,
    suite_targets,
    tracking_targets,
    watchdog_targets,
)


def _m(avg, bad2, **extra):
    return {"avg_err": avg, "bad2": bad2, **extra}


def _clean():
    return {"sets": {
        "kitti2012": {"fuzzystereo": _m(1.40, 10.0, noc=_m(1.20, 9.0)), "sgbm": _m(1.8, 12.0)},
        "kitti2015": {"fuzzystereo": _m(1.30, 15.0), "sgbm": _m(1.2, 9.0)},
        "middlebury2006-third": {"fuzzystereo": _m(1.4, 11.9), "sgbm": _m(1.5, 15.3)},
    }}


def _by_name(rows):
    return {t.name: t for t in rows}


def test_eval_verdicts_follow_each_number():
    rad = {"gain": {"sets": {
        "kitti2012": {"fuzzystereo": _m(0, 12.5), "sgbm": _m(0, 13.0)},     # 1.25x exactly, below SGBM: both met
        "kitti2015": {"fuzzystereo": _m(0, 15.5), "sgbm": _m(0, 15.0)},     # within 1.25x, above SGBM
        "middlebury2006-third": {"fuzzystereo": _m(0, 15.0), "sgbm": _m(0, 20.0)},  # 1.26x clean
    }}}
    rows = _by_name(eval_targets(_clean(), rad))
    assert rows["kitti2012: average error (all pixels)"].met is False          # 1.40 > 1.34
    assert "non-occluded 1.200 px" in rows["kitti2012: average error (all pixels)"].measured
    assert rows["kitti2015: average error (all pixels)"].met is True           # 1.30 <= 1.34
    assert rows["kitti2012: bad-2 (all pixels)"].met is True
    assert rows["kitti2015: bad-2 (all pixels)"].met is False                  # 15.0 > 14.3
    assert rows["Middlebury 2006 third: bad-2 no worse than StereoSGBM"].met is True
    gain = next(t for t in rows.values() if t.name.startswith("radiometric 'gain'"))
    assert gain.met is False
    assert gain.measured.startswith("2/3 within 1.25x, 2/3 below SGBM")
    cells = {c["set"]: c for c in gain.details["cells"]}
    assert cells["kitti2012"]["ratio_ok"] and cells["kitti2012"]["sgbm_ok"]
    assert cells["kitti2015"]["ratio_ok"] and cells["kitti2015"]["sgbm_ok"] is False
    assert not cells["middlebury2006-third"]["ratio_ok"]
    missing = [t for t in rows.values() if t.name == "radiometric 'noise'"]
    assert missing and missing[0].met is None and missing[0].measured == "not measured"


def test_eval_all_radiometric_cells_met():
    clean = _clean()
    rad = {"gamma": {"sets": {k: {"fuzzystereo": _m(0, v["fuzzystereo"]["bad2"] * 1.1), "sgbm": _m(0, 99.0)}
                              for k, v in clean["sets"].items()}}}
    gamma = next(t for t in eval_targets(clean, rad) if t.name.startswith("radiometric 'gamma'"))
    assert gamma.met is True and "missed" not in gamma.measured


def _bench(ratio1, ratio2):
    return {"width": 10, "height": 10, "max_disparity": 16, "repeats": 3, "runs": [
        {"threads": t, "ratio_fuzzystereo_sgbm": r, "fuzzystereo_ms": r * 10, "sgbm_ms": 10.0, "bm_ms": 3.0,
         "stages_ms": {"cost": 1.0}} for t, r in ((1, ratio1), (2, ratio2))]}


def test_bench_verdict_is_the_ratio_at_each_thread_count():
    rows = bench_targets({"kitti2015/000046": _bench(1.0, 1.01)})
    assert [t.met for t in rows] == [True, False]
    assert rows[1].measured.startswith("1.01x (10.1 vs 10.0 ms")


def test_detect_verdicts():
    de = {"overall": {"frames": 300, "gt_obstacles": 1000, "detected": 970, "detection_rate": 0.97, "detection_rate_box_only": 0.98,
                      "false_positives_per_frame": 0.11, "road_iou": 0.9, "distance_rel_error_median": 0.051,
                      "distance_rel_error_p90": 0.1,
                      "ms_per_frame": {"detect_over_matcher": 1.0, "detect_total": 20.0, "matcher_total": 20.0}},
          "per_type": {}}
    rows = detect_targets(de)
    assert [t.met for t in rows] == [True, False, True, False, False]
    from fuzzyctl.targets import oracle_target

    assert oracle_target(de).met is False  # 0.11 FP per frame
    de["overall"]["false_positives_per_frame"] = 0.1
    assert oracle_target(de).met is True


def test_suite_verdicts_count_struck_as_contacts():
    s = {"seed": 1, "solvable": 100, "reached": 98, "success_pct": 98.0, "collisions": 0, "struck": 1,
         "blocked": 10, "blocked_safe_stop": 10}
    rows = suite_targets(s)
    assert [t.met for t in rows] == [True, False, True]
    assert "1 struck" in rows[1].measured


def test_watchdog_verdicts_read_each_clocks_field_and_need_a_trip():
    sim = {"watchdog_trips": 1, "watchdog_stop_after_deadline_ms": 100.0}
    wall = {"watchdog_trips": 1, "watchdog_stop_wall_after_stall_ms": 100.5}
    assert [t.met for t in watchdog_targets(sim, wall)] == [True, False]
    no_trip = watchdog_targets({"watchdog_trips": 0}, None)
    assert no_trip[0].met is False and "did not trip" in no_trip[0].measured
    assert no_trip[1].met is None


def test_tracking_and_check_verdicts():
    te = {"trials": 10, "frames": 60, "settle_frames": 10, "sigma_m": 0.05, "filt_pos_rmse_m": 0.05, "raw_pos_rmse_m": 0.05,
          "vel_p95_after_mps": 0.1, "vel_rmse_after_mps": 0.05, "vel_max_after_mps": 0.2}
    assert [t.met for t in tracking_targets(te)] == [False, True]
    c = check_target(2, "bad input", [("a", True, "x"), ("b", False, "crash")])
    assert c.met is False and "failed: b: crash" in c.measured


@pytest.mark.firmware
def test_targets_without_datasets_reports_them_not_measured(firmware_bin, tmp_path, capsys):
    out = tmp_path / "t"
    rc = main(["targets", "--bin", str(firmware_bin), "--issues", "2", "--quick", "--datasets",
               str(tmp_path / "none"), "--out", str(out), "--strict"])
    assert rc == 1  # --strict: a row is not measured
    doc = json.loads((out / "targets.json").read_text())
    rows = {t["name"]: t for t in doc["targets"]}
    assert rows["accuracy, radiometric and speed targets"]["met"] is None
    assert "datasets not found" in rows["accuracy, radiometric and speed targets"]["measured"]
    bad = rows["bad input (missing file, size mismatch, unreadable image, out-of-range config)"]
    assert bad["met"] is True, bad["measured"]
    assert (out / "index.html").read_text().count("not measured") >= 1


@pytest.mark.firmware
@pytest.mark.datasets
@pytest.mark.slow
def test_targets_quick_run_measures_every_row(firmware_bin, datasets_root, tmp_path):
    out = tmp_path / "t"
    rc = main(["targets", "--bin", str(firmware_bin), "--quick", "--datasets", str(datasets_root), "--out", str(out)])
    assert rc == 0
    doc = json.loads((out / "targets.json").read_text())
    # every row measured (a 4-scenario suite may track no mover: that one row may be "not measured")
    unmeasured = [t["name"] for t in doc["targets"] if t["met"] is None]
    assert all(n.startswith("tracking on vision") for n in unmeasured), unmeasured
    names = [t["name"] for t in doc["targets"]]
    assert sum(n.startswith("speed ") and "from eval" not in n for n in names) == 4  # bench: 2 frames x 2 thread counts
    sets = json.loads((out / "raw" / "eval_clean.json").read_text())["sets"]
    assert sum("from eval" in n for n in names) == len(sets) > 0  # one per evaluated set
    assert sum(n.startswith("radiometric ") for n in names) == 4
    assert any(n.startswith("closed-loop suite: goal reached") for n in names)
    assert any(n.startswith("tracking: position RMSE") for n in names)
    assert any(n.startswith("tracking on vision measurements") for n in names)
    assert "track_errors_suite.json" in {p.name for p in (out / "raw").iterdir()}
    # every other row's verdict is a boolean computed from the raw JSON kept beside it
    assert all(isinstance(t["met"], bool) for t in doc["targets"] if t["name"] not in unmeasured)
    raw = {p.name for p in (out / "raw").iterdir()}
    assert {"eval_clean.json", "detect_eval.json", "detect_eval_oracle.json", "suite.json", "watchdog_wall.json", "track_eval.json"} <= raw
    html = (out / "index.html").read_text()
    assert "data:image/png;base64," in html  # the stage chart


def test_eval_speed_rows_and_suite_errors():
    clean = {"sets": {"kitti2015": {"fuzzystereo": {"ms_per_frame": 50.0, "frames": 1},
                                    "sgbm": {"ms_per_frame": 50.0, "frames": 1}},
                      "m": {"fuzzystereo": {"ms_per_frame": 20.0, "frames": 4}, "sgbm": {"ms_per_frame": 10.0, "frames": 4}}}}
    from fuzzyctl.targets import eval_speed_targets

    assert [t.met for t in eval_speed_targets(clean)] == [True, False]
    s = {"seed": 1, "solvable": 10, "reached": 10, "success_pct": 100.0, "collisions": 0, "struck": 0,
         "blocked": 1, "blocked_safe_stop": 1, "errors": 2}
    rows = suite_targets(s)
    assert rows[-1].name.endswith("ended in an error") and rows[-1].met is False


@pytest.mark.firmware
def test_targets_against_an_earlier_run_shows_before(firmware_bin, tmp_path, capsys):
    out1, out2 = tmp_path / "a", tmp_path / "b"
    args = ["targets", "--bin", str(firmware_bin), "--issues", "2", "--quick", "--datasets", str(tmp_path / "none")]
    assert main([*args, "--out", str(out1)]) == 0
    assert main([*args, "--out", str(out2), "--against", str(out1 / "targets.json")]) == 0
    assert "<th>before</th>" in (out2 / "index.html").read_text()
    assert "before" in capsys.readouterr().out
    (tmp_path / "x.json").write_text("{}")
    assert main([*args, "--out", str(out2), "--against", str(tmp_path / "x.json")]) == 2


def test_vision_tracking_rows():
    from fuzzyctl.targets import vision_tracking_targets

    te = {"movers": {"n": 100, "filt_pos_rmse_m": 0.21, "raw_pos_rmse_m": 0.20, "vel_after10_n": 40,
                     "vel_after10_p95_mps": 0.09, "vel_after10_median_mps": 0.05, "vel_after10_rms_mps": 0.06}}
    rows = vision_tracking_targets(te, 5)
    assert [t.met for t in rows] == [False, True]
    none = vision_tracking_targets({"movers": {"n": 0}}, 5)
    assert len(none) == 1 and none[0].met is None


def test_wilson_interval():
    from fuzzyctl.targets import wilson

    lo, hi = wilson(94, 100)
    assert lo == pytest.approx(0.8752, abs=5e-4) and hi == pytest.approx(0.9722, abs=5e-4)
    assert wilson(0, 0) == (0.0, 1.0)
    lo, hi = wilson(10, 10)
    assert hi == pytest.approx(1.0) and lo == pytest.approx(0.7225, abs=5e-4)
