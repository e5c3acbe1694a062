"""Dataset layouts, GT decoding and KITTI metrics (fuzzyctl.dataset / metrics / evaluate), and the
dataset modes of the CLI: `reference eval` against the firmware's `eval`, `compare --dataset`."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from fuzzyctl import dataset, metrics
from fuzzyctl.cli import main
from fuzzyctl.errors import FatalError

# ---- metrics ----------------------------------------------------------------------------------------


def _fill_devkit(disp: np.ndarray) -> np.ndarray:
    """metrics.cpp fill_invalid_kitti written out loop by loop (the devkit's interpolateBackground)."""
    out = disp.astype(np.float32).copy()
    h, w = out.shape
    valid = [[bool(np.isfinite(out[y, x]) and out[y, x] > 0) for x in range(w)] for y in range(h)]
    for y in range(h):
        count = 0
        for x in range(w):
            if valid[y][x]:
                if count >= 1:
                    x1, x2 = x - count, x - 1
                    if x1 > 0 and x2 < w - 1:
                        fill = min(out[y, x1 - 1], out[y, x2 + 1])
                        for u in range(x1, x2 + 1):
                            out[y, u] = fill
                            valid[y][u] = True
                count = 0
            else:
                count += 1
        for x in range(w):
            if valid[y][x]:
                for u in range(x):
                    out[y, u] = out[y, x]
                    valid[y][u] = True
                break
        for x in range(w - 1, -1, -1):
            if valid[y][x]:
                for u in range(x + 1, w):
                    out[y, u] = out[y, x]
                    valid[y][u] = True
                break
    for x in range(w):
        for y in range(h):
            if valid[y][x]:
                for v in range(y):
                    out[v, x] = out[y, x]
                    valid[v][x] = True
                break
        for y in range(h - 1, -1, -1):
            if valid[y][x]:
                for v in range(y + 1, h):
                    out[v, x] = out[y, x]
                    valid[v][x] = True
                break
    return out


@pytest.mark.parametrize("seed", range(6))
def test_fill_matches_the_devkit_loops(seed):
    rng = np.random.default_rng(seed)
    h, w = 9, 13
    d = rng.uniform(0, 20, (h, w)).astype(np.float32)
    d[rng.random((h, w)) < 0.5] = -1.0
    d[rng.random((h, w)) < 0.05] = np.nan
    d[rng.random((h, w)) < 0.05] = 0.0  # 0 px is "no estimate" (the KITTI PNG cannot hold it)
    d[rng.integers(0, h)] = -1.0  # an all-invalid row
    d[:, 0] = -1.0
    np.testing.assert_array_equal(metrics.fill_invalid_kitti(d), _fill_devkit(d))


def test_fill_interior_run_takes_the_background():
    d = np.array([[5.0, -1, -1, 2.0, -1, 7.0, -1]], np.float32)
    np.testing.assert_array_equal(metrics.fill_invalid_kitti(d), [[5, 2, 2, 2, 2, 7, 7]])


def test_evaluate_disparity_by_hand():
    gt = np.array([[10.0, 0.0, 100.0, 4.0]], np.float32)  # second pixel: no GT
    est = np.array([[12.5, 3.0, 96.0, -1.0]], np.float32)  # last invalid -> filled with 96
    m = metrics.evaluate_disparity(est, gt)
    err = [2.5, 4.0, 92.0]
    assert m.gt_pixels == 3
    assert m.avg_err == pytest.approx(sum(err) / 3)
    assert m.bad2 == pytest.approx(100.0)
    assert m.bad3 == pytest.approx(200.0 / 3)
    assert m.d1 == pytest.approx(100.0 / 3)  # 4 px of 100 is under 5 %
    assert m.density == pytest.approx(200.0 / 3)


def test_evaluation_area_scores_only_its_pixels_but_fills_from_the_whole_map():
    gt = np.array([[10.0, 0.0, 100.0, 4.0]], np.float32)
    est = np.array([[12.5, 3.0, 96.0, -1.0]], np.float32)
    m = metrics.evaluate_disparity(est, gt, np.array([[True, True, False, True]]))
    assert m.gt_pixels == 2  # px 1 has no GT, px 2 is outside the area
    assert m.avg_err == pytest.approx((2.5 + 92.0) / 2)  # px 3 is still filled with px 2's 96
    assert m.density == pytest.approx(50.0)
    full = metrics.evaluate_disparity(est, gt, np.ones_like(gt, bool))
    assert full == metrics.evaluate_disparity(est, gt)
    with pytest.raises(ValueError, match="evaluation area"):
        metrics.evaluate_disparity(est, gt, np.ones((1, 3), bool))


def test_non_occluded_masks_where_the_set_ships_them(tmp_path):
    k12 = tmp_path / "kitti2012" / "training"
    for sub in ("colored_0", "colored_1"):
        _png(k12 / sub / "000001_10.png")
    _png(k12 / "disp_occ" / "000001_10.png", value=512, dtype=np.uint16)
    noc = np.full((4, 6), 512, np.uint16)
    noc[:, :2] = 0  # occluded band
    (k12 / "disp_noc").mkdir(parents=True)
    cv2.imwrite(str(k12 / "disp_noc" / "000001_10.png"), noc)
    mq = tmp_path / "MiddEval3" / "trainingQ" / "Motor"
    _png(mq / "im0.png"), _png(mq / "im1.png")
    (mq / "calib.txt").write_text("cam0=[1 0 0; 0 1 0; 0 0 1]\nbaseline=1\nndisp=70\n")
    _pfm(mq / "disp0GT.pfm", np.ones((4, 6), np.float32))
    mask = np.full((4, 6), 255, np.uint8)
    mask[0, :] = 128  # occluded
    mask[1, 0] = 0  # no GT
    cv2.imwrite(str(mq / "mask0nocc.png"), mask)
    ts = tmp_path / "mb01" / "tsukuba"
    _png(ts / "im3.png"), _png(ts / "im4.png"), _png(ts / "disp3.pgm", value=32)
    frames = {f.key: f for f in dataset.discover(tmp_path)}
    assert not frames["middlebury2001-3/tsukuba"].has_noc
    with pytest.raises(FatalError, match="no non-occlusion mask"):
        dataset.load_nonoccluded_mask(frames["middlebury2001-3/tsukuba"])
    np.testing.assert_array_equal(dataset.load_nonoccluded_mask(frames["kitti2012/000001"]), noc > 0)
    np.testing.assert_array_equal(dataset.load_nonoccluded_mask(frames["middlebury2014-Q/Motor"]), mask == 255)
    (mq / "mask0nocc.png").write_bytes(b"not a png")
    with pytest.raises(FatalError, match="mask0nocc.png"):
        dataset.load_nonoccluded_mask(frames["middlebury2014-Q/Motor"])


def test_zero_disparity_is_no_estimate():
    gt = np.full((1, 3), 4.0, np.float32)
    m = metrics.evaluate_disparity(np.array([[4.0, 0.0, 3.0]], np.float32), gt)
    assert m.density == pytest.approx(200.0 / 3)
    assert m.avg_err == pytest.approx(2.0 / 3)  # the 0 is filled with min(4, 3): errors 0, 1, 1


def test_all_invalid_scores_zero_disparity():
    m = metrics.evaluate_disparity(np.full((2, 3), -1, np.float32), np.full((2, 3), 2.0, np.float32))
    assert m.avg_err == pytest.approx(2.0) and m.density == 0.0


def test_q4_map_conversion():
    np.testing.assert_array_equal(metrics.disp_q4_to_float(np.array([[-1, 0, 24]], np.int16)), [[-1.0, 0.0, 1.5]])


# ---- layouts ------------------------------------------------------------------------------------------


def _png(path, shape=(4, 6), value=100, dtype=np.uint8):
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.full(shape, value, dtype))


def _pfm(path, a: np.ndarray, little=True):
    path.parent.mkdir(parents=True, exist_ok=True)
    h, w = a.shape
    body = a[::-1].astype("<f4" if little else ">f4").tobytes()
    path.write_bytes(f"Pf\n{w} {h}\n{-1.0 if little else 1.0}\n".encode() + body)


def test_every_layout_is_found_with_its_range_and_scale(tmp_path):
    k12 = tmp_path / "kitti2012" / "training"
    for sub in ("colored_0", "colored_1"):
        _png(k12 / sub / "000001_10.png")
    _png(k12 / "disp_occ" / "000001_10.png", value=512, dtype=np.uint16)
    k15 = tmp_path / "kitti2015" / "training"
    for sub in ("image_2", "image_3"):
        _png(k15 / sub / "000002_10.png")
        _png(k15 / sub / "000002_11.png")  # not a _10 frame
    ts = tmp_path / "mb01" / "tsukuba"
    _png(ts / "im3.png"), _png(ts / "im4.png"), _png(ts / "disp3.pgm", value=32)
    ve = tmp_path / "mb01" / "venus"
    _png(ve / "im2.png"), _png(ve / "im6.png"), _png(ve / "disp2.pgm", value=32)
    co = tmp_path / "mb01" / "cones"
    _png(co / "im2.png"), _png(co / "im6.png"), _png(co / "disp2.png", value=32)
    for size, n in (("ThirdSize", 3), ("HalfSize", 2)):
        sc = tmp_path / "mb06" / size / f"Scene{n}"
        _png(sc / "view1.png"), _png(sc / "view5.png"), _png(sc / "disp1.png", value=30)
    mq = tmp_path / "mb14" / "MiddEval3" / "trainingQ" / "Motor"
    _png(mq / "im0.png"), _png(mq / "im1.png")
    (mq / "calib.txt").write_text("cam0=[1 0 0; 0 1 0; 0 0 1]\nbaseline=1\nndisp=70\n")
    gt = np.arange(24, dtype=np.float32).reshape(4, 6) + 0.5
    gt[0, 0] = np.inf
    _pfm(mq / "disp0GT.pfm", gt)
    (tmp_path / ".hidden" / "x").mkdir(parents=True)

    frames = {f.key: f for f in dataset.discover(tmp_path)}
    expect = {  # key: (max disparity, GT value of the first pixel decoded)
        "kitti2012/000001": (160, 2.0), "kitti2015/000002": (160, None),
        "middlebury2001-3/tsukuba": (16, 2.0), "middlebury2001-3/venus": (32, 4.0),
        "middlebury2001-3/cones": (64, 8.0), "middlebury2006-third/Scene3": (80, np.float32(30) * np.float32(1 / 3)),
        "middlebury2006-half/Scene2": (128, 15.0), "middlebury2014-Q/Motor": (80, 0.0),
    }
    assert set(frames) == set(expect)
    for key, (max_disp, first) in expect.items():
        f = frames[key]
        assert f.max_disparity == max_disp, key
        if first is None:
            assert not f.has_gt
        else:
            g = dataset.load_ground_truth(f)
            assert g.dtype == np.float32 and g.shape == (4, 6)
            assert g[0, 0] == first, key
    np.testing.assert_array_equal(dataset.load_ground_truth(frames["middlebury2014-Q/Motor"])[1:], gt[1:])
    picked = dataset.select(dataset.discover(tmp_path), limit=1)  # with GT, one per set, sorted
    assert [f.key for f in picked] == ["kitti2012/000001", "middlebury2001-3/cones", "middlebury2006-half/Scene2",
                                       "middlebury2006-third/Scene3", "middlebury2014-Q/Motor"]


def test_pfm_big_endian(tmp_path):
    a = np.array([[1.0, 2.0], [3.0, np.inf]], np.float32)
    _pfm(tmp_path / "x.pfm", a, little=False)
    np.testing.assert_array_equal(dataset.read_pfm(tmp_path / "x.pfm"), a)


def test_unknown_layout_and_bad_inputs_are_clear(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    with pytest.raises(FatalError, match="unknown dataset layout.*layouts looked for: KITTI 2012"):
        dataset.discover(tmp_path)
    with pytest.raises(FatalError, match="does not exist"):
        dataset.discover(tmp_path / "missing")
    mq = tmp_path / "MiddEval3" / "trainingQ" / "M"
    _png(mq / "im0.png"), _png(mq / "im1.png")
    (mq / "calib.txt").write_text("baseline=1\n")
    with pytest.raises(FatalError, match="no ndisp=N line"):
        dataset.discover(tmp_path)
    (tmp_path / "bad.pfm").write_bytes(b"P5\n1 1\n-1\n\0\0\0\0")
    with pytest.raises(FatalError, match="not a valid PFM"):
        dataset.read_pfm(tmp_path / "bad.pfm")


def test_cli_unknown_layout_exit_code(tmp_path, capsys):
    assert main(["reference", "eval", "--dataset", str(tmp_path)]) == 2
    assert "unknown dataset layout" in capsys.readouterr().err
    assert main(["compare", "--dataset", str(tmp_path)]) == 2
    assert main(["compare"]) == 2
    assert "either RUN_DIR" in capsys.readouterr().err


# ---- against the firmware ---------------------------------------------------------------------------


def _small_frames(datasets_root, tmp_path):
    """A dataset of two small frames: tsukuba (GT /16) and a ThirdSize scene (GT /3, D = 80)."""
    tsukuba = datasets_root / "middlebury2001-3" / "tsukuba"
    third = datasets_root / "middlebury2005-6" / "ThirdSize" / "Baby1"
    for p in (tsukuba, third):
        if not p.is_dir():
            pytest.skip(f"dataset frame {p} not found")
    root = tmp_path / "ds"
    shutil.copytree(tsukuba, root / "middlebury2001-3" / "tsukuba")
    shutil.copytree(third, root / "middlebury2005-6" / "ThirdSize" / "Baby1")
    return root


@pytest.mark.firmware
@pytest.mark.datasets
def test_metric_code_agrees_with_firmware_eval(firmware_bin, datasets_root, tmp_path, monkeypatch):
    import subprocess

    root = _small_frames(datasets_root, tmp_path)
    fw_json = tmp_path / "fw.json"
    subprocess.run([str(firmware_bin), "eval", "--dataset", str(root), "--json", str(fw_json)], check=True,
                   capture_output=True, timeout=300)
    monkeypatch.setenv("FUZZYSTEREO_BIN", str(firmware_bin))
    ours_json = tmp_path / "ours.json"
    rc = main(["reference", "eval", "--dataset", str(root), "--from-firmware", "--firmware-json", str(fw_json),
               "--json", str(ours_json), "--runs", str(tmp_path / "runs")])
    assert rc == 0
    fw, ours = json.loads(fw_json.read_text()), json.loads(ours_json.read_text())
    assert set(fw["sets"]) == set(ours["sets"]) == {"middlebury2001-3", "middlebury2006-third"}
    for s in fw["sets"]:
        for fig in ("avg_err", "bad2", "bad3", "d1", "density", "frames"):
            assert ours["sets"][s]["fuzzystereo"][fig] == pytest.approx(fw["sets"][s]["fuzzystereo"][fig], abs=1e-6), (s, fig)
    # the runs are reused, and a disagreeing eval JSON fails the check
    fw["sets"]["middlebury2001-3"]["fuzzystereo"]["bad2"] += 1e-3
    fw_json.write_text(json.dumps(fw))
    assert main(["reference", "eval", "--dataset", str(root), "--from-firmware", "--firmware-json", str(fw_json),
                 "--runs", str(tmp_path / "runs")]) == 1


@pytest.mark.firmware
@pytest.mark.datasets
def test_non_occluded_figures_agree_with_firmware_eval(firmware_bin, datasets_root, tmp_path, monkeypatch):
    """MiddEval3 ships mask0nocc.png: both evals score its non-occluded pixels alike (and differently
    from all pixels, so the mask is applied)."""
    import subprocess

    motor = datasets_root / "middlebury2014" / "MiddEval3" / "trainingQ" / "Motorcycle"
    if not (motor / "mask0nocc.png").is_file():
        pytest.skip(f"dataset frame {motor} (with mask0nocc.png) not found")
    root = tmp_path / "ds"
    shutil.copytree(motor, root / "MiddEval3" / "trainingQ" / "Motorcycle")
    fw_json = tmp_path / "fw.json"
    subprocess.run([str(firmware_bin), "eval", "--dataset", str(root), "--json", str(fw_json)], check=True,
                   capture_output=True, timeout=300)
    monkeypatch.setenv("FUZZYSTEREO_BIN", str(firmware_bin))
    ours_json = tmp_path / "ours.json"
    assert main(["reference", "eval", "--dataset", str(root), "--from-firmware", "--firmware-json", str(fw_json),
                 "--json", str(ours_json), "--runs", str(tmp_path / "runs")]) == 0
    fw = json.loads(fw_json.read_text())["sets"]["middlebury2014-Q"]["fuzzystereo"]
    ours = json.loads(ours_json.read_text())["sets"]["middlebury2014-Q"]["fuzzystereo"]
    for fig in ("avg_err", "bad2", "bad3", "d1", "density", "frames"):
        assert ours["noc"][fig] == pytest.approx(fw["noc"][fig], abs=1e-6), fig
    assert fw["noc"]["frames"] == 1
    assert fw["noc"]["bad2"] < fw["bad2"]  # occluded pixels are the hard ones


@pytest.mark.firmware
@pytest.mark.datasets
@pytest.mark.slow
def test_compare_dataset_on_tsukuba(firmware_bin, datasets_root, tmp_path, monkeypatch):
    tsukuba = datasets_root / "middlebury2001-3" / "tsukuba"
    if not tsukuba.is_dir():
        pytest.skip(f"dataset frame {tsukuba} not found")
    monkeypatch.setenv("FUZZYSTEREO_BIN", str(firmware_bin))
    report = tmp_path / "report"
    rc = main(["compare", "--dataset", str(tsukuba), "--report", str(report)])
    summary = json.loads((report / "summary.json").read_text())
    frame = summary["per_frame"]["middlebury2001-3/tsukuba"]
    assert rc == 0, frame["failures"]
    assert frame["winner_pct"] >= 99.0 and frame["final_within_1px_valid_pct"] >= 99.0
    assert (report / "middlebury2001-3" / "tsukuba" / "report.html").is_file()
    assert (report / "index.html").is_file()
