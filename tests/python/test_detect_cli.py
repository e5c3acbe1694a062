"""`fuzzystereo detect` and `detect-eval` on tiny generated frames in the simulator's layout
(tests/python/detect_synth.py): oracle mode (ground-truth disparity) and with the matcher, every
output file, calibration formats, mono input, and each kind of bad input."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

import detect_synth

pytestmark = pytest.mark.firmware


def run(binary: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True, timeout=300)


def assert_user_error(p: subprocess.CompletedProcess, *needles: str) -> None:
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, p.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return detect_synth.write_dataset(tmp_path_factory.mktemp("sim"))


def frame(dataset: Path, n: int) -> dict[str, Path]:
    tr, stem = dataset / "training", f"{n:06d}_10"
    return {"left": tr / "image_2" / f"{stem}.png", "right": tr / "image_3" / f"{stem}.png",
            "disp": tr / "disp_occ_0" / f"{stem}.png", "gt": tr / "sim_gt" / f"{stem}.json"}


def gt_obstacles(dataset: Path, n: int) -> list[dict]:
    return json.loads(frame(dataset, n)["gt"].read_text())["obstacles"]


def iou(a, b) -> float:
    ix = min(a[2], b[2]) - max(a[0], b[0]) + 1
    iy = min(a[3], b[3]) - max(a[1], b[1]) + 1
    if ix <= 0 or iy <= 0:
        return 0.0
    area = lambda r: (r[2] - r[0] + 1) * (r[3] - r[1] + 1)  # noqa: E731
    return ix * iy / (area(a) + area(b) - ix * iy)


# ---- detect -----------------------------------------------------------------------------------

def test_detect_oracle_recovers_boxes_and_distances(firmware_bin, dataset, tmp_path):
    f = frame(dataset, 0)
    p = run(firmware_bin, "detect", "--left", f["left"], "--disparity", f["disp"], "--calib", f["gt"],
            "--out", tmp_path, "--dump")
    assert p.returncode == 0, p.stderr
    out = json.loads((tmp_path / "obstacles.json").read_text())
    assert out["road"]["found"] and not out["sky_skipped"]
    dets = out["obstacles"]
    gts = gt_obstacles(dataset, 0)
    assert len(dets) == len(gts) == 2
    for g in gts:
        best = max(dets, key=lambda d: iou(d["box"], g["box"]))
        assert iou(best["box"], g["box"]) >= 0.7, (best, g)
        assert best["distance_m"] == pytest.approx(g["distance_m"], rel=0.05)
        assert best["class"] in ("near", "mid", "far")
    assert [d["id"] for d in dets] == [0, 1]
    assert dets[0]["distance_m"] <= dets[1]["distance_m"]  # nearest first
    # Every output file, with the image size.
    h, w = cv2.imread(str(f["left"])).shape[:2]
    for name in ("overlay.png", "road_mask.png", "sky_mask.png", "disp_color.png"):
        img = cv2.imread(str(tmp_path / name), cv2.IMREAD_UNCHANGED)
        assert img is not None and img.shape[:2] == (h, w), name
    road = cv2.imread(str(tmp_path / "road_mask.png"), cv2.IMREAD_GRAYSCALE)
    gt_road = cv2.imread(str(dataset / "training/sim_gt/000000_10_road.png"), cv2.IMREAD_GRAYSCALE) > 0
    assert ((road > 0) & gt_road).sum() / ((road > 0) | gt_road).sum() > 0.9
    # The dump: each stage's input and output, consistent with each other and with obstacles.json.
    d = tmp_path / "dump"
    meta = json.loads((d / "detect_meta.json").read_text())
    disp = np.load(d / "disp.npy")
    assert disp.shape == (h, w) and disp.dtype == np.int16
    assert np.load(d / "left_rgb.npy").shape == (h, w, 3)
    vd = np.load(d / "vdisp.npy")
    assert vd.shape == (h, meta["bins"]) and vd.sum() == (disp >= 0).sum()
    cand, kept = np.load(d / "candidates.npy"), np.load(d / "kept.npy")
    assert not (kept & ~cand).any()  # the u-disparity filter only removes
    assert not (cand & np.load(d / "road_mask.npy")).any()
    labels = np.load(d / "cluster_labels.npy")
    assert set(np.unique(labels[cand == 1])) <= set(range(len(meta["centres_q4"])))
    assert np.load(d / "udisp_kept.npy").shape == (len(meta["centres_q4"]), meta["bins"], w)
    ol = np.load(d / "obstacle_labels.npy")
    assert ol.max() == len(dets)
    for o in dets:
        ys, xs = np.nonzero(ol == o["id"] + 1)
        # The box is the labels' bounding box, except that ground contact (docs/detection.md "(e) Box
        # extent") may extend its bottom over the foot rows the road band removed.
        assert [xs.min(), ys.min(), xs.max()] == o["box"][:3]
        assert ys.max() <= o["box"][3] <= ys.max() + 20
        assert len(xs) == o["pixel_count"]
    assert "[detect]" in meta["config_toml"]


def test_detect_with_matcher(firmware_bin, dataset, tmp_path):
    f = frame(dataset, 0)
    p = run(firmware_bin, "detect", "--left", f["left"], "--right", f["right"], "--calib", f["gt"], "--out", tmp_path,
            "--max-disparity", "32")
    assert p.returncode == 0, p.stderr
    out = json.loads((tmp_path / "obstacles.json").read_text())
    assert out["disparity_source"] == "matcher"
    assert set(out["matcher_ms"]) == {"gradient", "segmentation", "cost", "wta", "lrcheck", "esr", "densify"}
    assert (tmp_path / "disp_left.png").is_file()
    # The near box (2 m) is found by the matcher too, within 10 %.
    near = gt_obstacles(dataset, 0)[0]
    assert any(iou(d["box"], near["box"]) >= 0.5 and abs(d["distance_m"] - near["distance_m"]) <= 0.1 * near["distance_m"]
               for d in out["obstacles"]), out["obstacles"]


def test_detect_mono_skips_sky(firmware_bin, dataset, tmp_path):
    f = frame(dataset, 0)
    grey = tmp_path / "grey.png"
    cv2.imwrite(str(grey), cv2.cvtColor(cv2.imread(str(f["left"])), cv2.COLOR_BGR2GRAY))
    p = run(firmware_bin, "detect", "--left", grey, "--disparity", f["disp"], "--calib", f["gt"], "--out", tmp_path / "o")
    assert p.returncode == 0, p.stderr
    out = json.loads((tmp_path / "o" / "obstacles.json").read_text())
    assert out["sky_skipped"] is True
    assert cv2.imread(str(tmp_path / "o" / "sky_mask.png"), cv2.IMREAD_GRAYSCALE).max() == 0
    assert len(out["obstacles"]) == 2


@pytest.mark.parametrize("kind", ["toml", "kitti", "json_flat", "opencv_yml"])
def test_detect_calibration_formats(firmware_bin, dataset, tmp_path, kind):
    f = frame(dataset, 0)
    F, B, CX, CY = detect_synth.F, detect_synth.B, detect_synth.CX, detect_synth.CY
    if kind == "toml":
        cal = tmp_path / "c.toml"
        cal.write_text(f"[calib]\nfocal_px = {F}\nbaseline_m = {B}\ncx = {CX}\ncy = {CY}\n")
    elif kind == "kitti":
        cal = tmp_path / "calib_cam_to_cam.txt"
        p2 = [F, 0, CX, 0.0, 0, F, CY, 0, 0, 0, 1, 0]
        p3 = [F, 0, CX, -F * B, 0, F, CY, 0, 0, 0, 1, 0]
        cal.write_text("calib_time: x\nP_rect_02: " + " ".join(map(str, p2)) + "\nP_rect_03: " + " ".join(map(str, p3)) + "\n")
    elif kind == "opencv_yml":  # the robot's own file (`capture`'s calib.yml, docs/capture.md)
        cal = tmp_path / "calib.yml"
        cal.write_text(f"%YAML:1.0\n---\nrectified: 1\nf: {F}\nB: {B}\ncx: {CX}\ncy: {CY}\n")
    else:
        cal = tmp_path / "c.json"
        cal.write_text(json.dumps({"focal_px": F, "baseline_m": B, "cx": CX, "cy": CY}))
    p = run(firmware_bin, "detect", "--left", f["left"], "--disparity", f["disp"], "--calib", cal, "--out", tmp_path / "o")
    assert p.returncode == 0, p.stderr
    dists = sorted(o["distance_m"] for o in json.loads((tmp_path / "o" / "obstacles.json").read_text())["obstacles"])
    assert dists == pytest.approx([2.0, 4.0], rel=0.05)


def test_detect_bad_input(firmware_bin, dataset, tmp_path):
    f = frame(dataset, 0)
    assert_user_error(run(firmware_bin, "detect", "--left", f["left"], "--disparity", f["disp"], "--out", tmp_path),
                      "--calib", "focal_px")
    assert_user_error(run(firmware_bin, "detect", "--left", f["left"], "--calib", f["gt"], "--out", tmp_path),
                      "--right", "--disparity")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"focal_px": 100, "cx": 1, "cy": 1}))
    assert_user_error(run(firmware_bin, "detect", "--left", f["left"], "--disparity", f["disp"], "--calib", bad,
                          "--out", tmp_path), "baseline_m", str(bad))
    assert_user_error(run(firmware_bin, "detect", "--left", f["left"], "--disparity", f["left"], "--calib", f["gt"],
                          "--out", tmp_path), "16-bit")
    cfg = tmp_path / "c.toml"
    cfg.write_text("[detect]\nkmeans_k = 99\n")
    p = run(firmware_bin, "detect", "--left", f["left"], "--disparity", f["disp"], "--calib", f["gt"], "--config", cfg,
            "--out", tmp_path)
    assert_user_error(p, "detect.kmeans_k")


# ---- detect-eval ------------------------------------------------------------------------------

def test_detect_eval_oracle(firmware_bin, dataset, tmp_path):
    js = tmp_path / "m.json"
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--oracle-disparity", "--json", js)
    assert p.returncode == 0, p.stderr
    assert "overall" in p.stdout and "clear" in p.stdout and "overcast" in p.stdout
    assert "4/4" in p.stderr or "[4/4]" in p.stderr  # progress
    m = json.loads(js.read_text())
    o = m["overall"]
    assert o["frames"] == 4
    # 6 GT obstacles with >= 300 visible px; the 6-m pole (frame 3) is "don't care".
    assert o["gt_obstacles"] == 6 and o["dont_care"] == 1
    # With exact disparities: 5 of 6 (the 13-row box at 5 m loses its lowest 5 rows to the 1-px road
    # band and falls below udisp_min_height_px; see the next test), no false positive.
    assert o["detected"] == 5
    assert o["false_positives_per_frame"] == 0
    assert o["road_iou"] > 0.9 and o["sky_iou"] > 0.95
    assert o["distance_rel_error_median"] < 0.02 and o["distance_rel_error_p90"] < 0.06
    assert m["per_type"]["clear"]["detection_rate"] == 1.0
    assert o["ms_per_frame"]["matcher"] is None and o["ms_per_frame"]["detect_total"] > 0
    assert len(m["frames"]) == 4
    # --limit
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--oracle-disparity", "--limit", "1", "--json", js)
    assert p.returncode == 0 and json.loads(js.read_text())["overall"]["frames"] == 1


def test_detect_eval_config_reaches_detector(firmware_bin, dataset, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[detect]\nroad_tolerance_px = 0.5\n")
    js = tmp_path / "m.json"
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--oracle-disparity", "--config", cfg, "--json", js)
    assert p.returncode == 0, p.stderr
    assert json.loads(js.read_text())["overall"]["detected"] == 6  # the short box keeps enough rows
    cfg.write_text("[detect]\nmin_area_px = 100000\n")
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--oracle-disparity", "--config", cfg, "--json", js)
    assert json.loads(js.read_text())["overall"]["detected"] == 0


def test_detect_eval_matcher(firmware_bin, dataset, tmp_path):
    js = tmp_path / "m.json"
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--json", js)
    assert p.returncode == 0, p.stderr
    o = json.loads(js.read_text())["overall"]
    ms = o["ms_per_frame"]
    assert set(ms["matcher"]) == {"gradient", "segmentation", "cost", "wta", "lrcheck", "esr", "densify"}
    assert set(ms["detect"]) == {"road", "sky", "kmeans", "udisparity", "objects"}
    assert ms["matcher_total"] > 0 and 0 < ms["detect_over_matcher"] < 1
    # The matcher's disparities on these 192x144 frames are coarser than the truth; measured 4 of 6.
    assert o["detection_rate"] >= 0.5
    assert o["sky_iou"] > 0.8


def test_detect_eval_bad_dataset(firmware_bin, tmp_path):
    assert_user_error(run(firmware_bin, "detect-eval", "--dataset", tmp_path), "fuzzystereo_sim.json")
    (tmp_path / "fuzzystereo_sim.json").write_text("{}")
    assert_user_error(run(firmware_bin, "detect-eval", "--dataset", tmp_path), "image_2")


# ---- fuzzyctl detect-report ---------------------------------------------------------------------

def test_detect_report_pictures_misses_and_changes(firmware_bin, dataset, tmp_path):
    from fuzzyctl import cli
    from fuzzyctl.detectreport import classify_miss

    base, none = tmp_path / "base.json", tmp_path / "none.json"
    assert run(firmware_bin, "detect-eval", "--dataset", dataset, "--oracle-disparity", "--json", base).returncode == 0
    cfg = tmp_path / "c.toml"
    cfg.write_text("[detect]\nmin_area_px = 100000\n")  # nothing is detected
    assert run(firmware_bin, "detect-eval", "--dataset", dataset, "--oracle-disparity", "--config", cfg,
               "--json", none).returncode == 0
    out = tmp_path / "r.html"
    assert cli.main(["detect-report", str(base), "--out", str(out)]) == 0
    page = out.read_text()
    # The one oracle miss (the 13-row box, see test_detect_eval_oracle) is pictured and classified.
    assert page.count("<div class='fr'>") == 1 and "data:image/jpeg;base64," in page
    assert "Misses by class" in page and "overall" in page
    # Against the base: the 5 detected obstacles are lost, every frame that had one is pictured first.
    out2 = tmp_path / "r2.html"
    assert cli.main(["detect-report", str(none), "--against", str(base), "--dataset", str(dataset),
                     "--out", str(out2)]) == 0
    page2 = out2.read_text()
    assert "0 obstacles gained, 5 lost" in page2 and "class='worse'>lost" in page2
    # classify_miss on made-up boxes.
    gt = [{"id": 0, "box": [10, 10, 30, 50], "visible_pixels": 800}, {"id": 1, "box": [32, 10, 50, 50],
                                                                      "visible_pixels": 700}]
    miss = {"id": 0, "box": [10, 10, 30, 50]}
    assert classify_miss(miss, [], gt) == "none"
    assert classify_miss(miss, [{"box": [8, 8, 52, 52]}], gt) == "merged, with a neighbour"
    assert classify_miss(miss, [{"box": [0, 0, 40, 70]}], gt[:1]) == "merged"
    assert classify_miss(miss, [{"box": [5, 5, 25, 40]}], gt) == "offset"
    assert classify_miss(miss, [{"box": [12, 12, 20, 40]}], gt) == "fragment"
    assert classify_miss(miss, [{"box": [10, 10, 30, 50]}], gt) == "distance"


def test_detect_report_bad_input(dataset, tmp_path):
    from fuzzyctl import cli

    assert cli.main(["detect-report", str(tmp_path / "missing.json")]) != 0
    bad = tmp_path / "bad.json"
    bad.write_text('{"sets": {}}')
    assert cli.main(["detect-report", str(bad), "--dataset", str(dataset)]) != 0
    bad.write_text("{not json")
    assert cli.main(["detect-report", str(bad)]) != 0
