"""`fuzzyctl calibrate`: stereo calibration from chessboard pairs, checked against a known truth.

The pairs are rendered by calib_synth.py from a known K, D, R, T (with lens distortion and noise);
the firmware then rectifies them with the written file, and the board's corners must lie on the
same rows in both rectified images.
"""

from __future__ import annotations

import shutil
import subprocess

import cv2
import numpy as np
import pytest

import calib_synth
from fuzzyctl.calibrate import Board, calibrate_folder, coverage, detect_corners, find_pairs, parse_board
from fuzzyctl.cli import main
from fuzzyctl.errors import FatalError


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    d = tmp_path_factory.mktemp("calib_shots")
    truth = calib_synth.write_pairs(d, count=12, seed=5)
    return d, truth


def test_recovers_the_known_calibration(shots):
    folder, truth = shots
    cal = calibrate_folder(folder, Board(truth.cols, truth.rows, truth.square_m))
    assert len(cal.views) == 12 and not cal.skipped
    for K, Kt in ((cal.K1, truth.K1), (cal.K2, truth.K2)):
        assert abs(K[0, 0] / Kt[0, 0] - 1) < 0.01  # focal length within 1 %
        assert abs(K[1, 1] / Kt[1, 1] - 1) < 0.01
        assert abs(K[0, 2] - Kt[0, 2]) < 3 and abs(K[1, 2] - Kt[1, 2]) < 3  # principal point [px]
    assert abs(cal.baseline_m / np.linalg.norm(truth.T) - 1) < 0.01
    rot_err = np.degrees(np.linalg.norm(cv2.Rodrigues(cal.R @ truth.R.T)[0]))
    assert rot_err < 0.2
    assert abs(cal.D1[0, 0] - truth.D1[0]) < 0.03  # k1 of the barrel distortion
    assert cal.rms_px < 0.3 and cal.epipolar_rms_px < 0.2


@pytest.mark.firmware
def test_firmware_rectifies_with_the_written_file(shots, tmp_path, firmware_bin):
    folder, truth = shots
    out = tmp_path / "stereo.yml"
    assert main([
        "calibrate", str(folder), "--board", f"{truth.cols}x{truth.rows}", "--square", str(truth.square_m),
        "--out", str(out), "--preview", str(tmp_path / "preview.png"), "--height-m", "0.3", "--pitch-deg", "4",
    ]) == 0
    fs = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    assert fs.getNode("image_width").real() == 640 and fs.getNode("height_m").real() == pytest.approx(0.3)
    assert (tmp_path / "preview.png").is_file()
    rect = tmp_path / "rect"
    subprocess.run([str(firmware_bin), "capture", "--source", f"replay:{folder}", "--calib", str(out), "--count", "4",
                    "--out", str(rect)], check=True, capture_output=True, timeout=120)
    board = Board(truth.cols, truth.rows, truth.square_m)
    dys = []
    for name in sorted(p.name for p in (rect / "left").iterdir()):
        cl = detect_corners(cv2.imread(str(rect / "left" / name), cv2.IMREAD_GRAYSCALE), board)
        cr = detect_corners(cv2.imread(str(rect / "right" / name), cv2.IMREAD_GRAYSCALE), board)
        if cl is None or cr is None:  # alpha 0 crops; a board at the edge may leave the view
            continue
        dys.append(cl[:, 0, 1] - cr[:, 0, 1])
        assert np.all(cl[:, 0, 0] - cr[:, 0, 0] > 0)  # positive disparity: left and right not swapped
    assert len(dys) >= 2
    dy = np.concatenate(dys)
    assert np.sqrt(np.mean(dy**2)) < 0.3 and np.max(np.abs(dy)) < 1.0
    rc = fs.getNode("rms_px").real()
    assert 0 < rc < 0.3


def test_uncalibrated_pairs_are_not_row_aligned(shots):
    # the check above can fail: the raw pairs (vertical offset, rotation, distortion) are far off
    folder, truth = shots
    board = Board(truth.cols, truth.rows, truth.square_m)
    pf = find_pairs(folder)[0]
    cl = detect_corners(cv2.imread(str(pf.left), cv2.IMREAD_GRAYSCALE), board)
    cr = detect_corners(cv2.imread(str(pf.right), cv2.IMREAD_GRAYSCALE), board)
    assert np.max(np.abs(cl[:, 0, 1] - cr[:, 0, 1])) > 2.0


def test_swapped_cameras_are_refused(shots, tmp_path):
    folder, truth = shots
    swapped = tmp_path / "swapped"
    shutil.copytree(folder / "left", swapped / "right")
    shutil.copytree(folder / "right", swapped / "left")
    with pytest.raises(FatalError, match=r"T\.x .* > 0"):
        calibrate_folder(swapped, Board(truth.cols, truth.rows, truth.square_m))


def test_wrong_board_size_names_the_count(shots, tmp_path):
    folder, truth = shots
    for side in ("left", "right"):  # three pairs are enough (each failed search costs ~0.5 s)
        (tmp_path / side).mkdir()
        for name in ("000000.png", "000001.png", "000002.png"):
            shutil.copy(folder / side / name, tmp_path / side / name)
    with pytest.raises(FatalError, match=r"8x5 board .* found in both views of 0 of 3 pairs; at least 8"):
        calibrate_folder(tmp_path, Board(8, 5, truth.square_m))
    cal = calibrate_folder(tmp_path, Board(truth.cols, truth.rows, truth.square_m), min_pairs=3)
    assert len(cal.views) == 3


def test_drops_a_bad_view_and_calibrates_again(shots, tmp_path):
    folder, truth = shots
    bad = tmp_path / "bad"
    shutil.copytree(folder, bad)
    # one view whose right image belongs to another pose: its corners are found but disagree
    shutil.copy(folder / "right" / "000001.png", bad / "right" / "000000.png")
    board = Board(truth.cols, truth.rows, truth.square_m)
    worse = calibrate_folder(bad, board)
    assert worse.rms_px > 1.0
    cal = calibrate_folder(bad, board, max_view_error=1.0)
    assert cal.dropped == ["000000.png"]
    assert cal.rms_px < 0.3 and abs(cal.baseline_m / np.linalg.norm(truth.T) - 1) < 0.01


@pytest.mark.parametrize(
    "board, square, message",
    [
        ("9x6", 25.0, "METRES"),
        ("7x7", 0.03, "ambiguous"),
        ("9by6", 0.03, "COLSxROWS"),
        ("2x6", 0.03, r"\[3, 60\]"),
        ("9x6", -0.01, "> 0"),
    ],
)
def test_bad_board_options(board, square, message):
    with pytest.raises(FatalError, match=message):
        parse_board(board, square)


def test_unpaired_image_is_named(tmp_path):
    for side in ("left", "right"):
        (tmp_path / side).mkdir()
    cv2.imwrite(str(tmp_path / "left" / "a.png"), np.zeros((8, 8), np.uint8))
    with pytest.raises(FatalError, match=r"left/a\.png has no partner"):
        find_pairs(tmp_path)
    with pytest.raises(FatalError, match=r"no 'left/' folder"):
        find_pairs(tmp_path / "right")


def test_cli_errors_are_one_line_with_exit_codes(shots, tmp_path, capsys):
    folder, truth = shots
    assert main(["calibrate", str(folder), "--board", "9x6", "--square", "30", "--out", str(tmp_path / "s.yml")]) == 2
    assert "METRES" in capsys.readouterr().err
    # a threshold the result cannot meet: exit 1, the file is still written for inspection
    out = tmp_path / "t.yml"
    rc = main(["calibrate", str(folder), "--board", "9x6", "--square", "0.03", "--out", str(out), "--max-epipolar", "0"])
    assert rc == 1 and out.is_file()
    assert "epipolar error" in capsys.readouterr().err


def test_coverage_counts_the_grid_cells_holding_a_corner():
    size = (640, 480)
    corners = [np.array([[[1, 1]], [[639, 1]], [[1, 479]], [[639, 479]]], np.float32)]
    assert coverage(corners, size) == pytest.approx(4 / 16)
    xs, ys = np.meshgrid(np.arange(40, 640, 160), np.arange(30, 480, 120))
    full = [np.stack([xs.ravel(), ys.ravel()], axis=1).reshape(-1, 1, 2).astype(np.float32)]
    assert coverage(full, size) == 1.0
    assert coverage([], size) == 0.0


def test_report_and_coverage_warning(shots, tmp_path, capsys):
    folder, truth = shots
    report = tmp_path / "calib.html"
    assert main(["calibrate", str(folder), "--board", "9x6", "--square", str(truth.square_m), "--out",
                 str(tmp_path / "s.yml"), "--report", str(report)]) == 0
    out = capsys.readouterr().out
    cal = calibrate_folder(folder, Board(truth.cols, truth.rows, truth.square_m))
    assert f"left {100 * cal.coverage_left:.0f} %" in out
    # the synthetic boards stay near the image centre: the warning must say so
    assert min(cal.coverage_left, cal.coverage_right) < 0.6 and "WARNING: corners cover under 60 %" in out
    page = report.read_text()
    assert "Where the corners were" in page and "A pair rectified with this calibration" in page
    assert page.count("data:image/png;base64,") == 3
