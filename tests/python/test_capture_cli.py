"""`fuzzystereo capture`: record from a source, replay the recording (round trip), rectify with a
calibration file, and one clear error line for each kind of bad input (docs/capture.md)."""

from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

pytestmark = pytest.mark.firmware


def run(binary: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(binary), *args], capture_output=True, text=True, timeout=120)


def assert_user_error(p: subprocess.CompletedProcess, *needles: str) -> None:
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, p.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.fixture()
def sequence(tmp_path) -> tuple[Path, list[tuple[np.ndarray, np.ndarray]]]:
    """Four random colour pairs named frame<N>_left/right.png (N = 1, 2, 3, 10: natural order)."""
    d = tmp_path / "seq"
    d.mkdir()
    rng = np.random.default_rng(5)
    pairs = []
    for n in (1, 2, 3, 10):
        left = rng.integers(0, 256, (48, 80, 3), dtype=np.uint8)
        right = rng.integers(0, 256, (48, 80, 3), dtype=np.uint8)
        cv2.imwrite(str(d / f"frame{n}_left.png"), left)
        cv2.imwrite(str(d / f"frame{n}_right.png"), right)
        pairs.append((left, right))
    return d, pairs


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_capture_then_replay_round_trip(firmware_bin, sequence, tmp_path):
    src, pairs = sequence
    out1, out2 = tmp_path / "rec1", tmp_path / "rec2"
    p = run(firmware_bin, "capture", "--source", f"replay:{src}", "--out", str(out1))
    assert p.returncode == 0, p.stderr
    assert "captured 4 pairs (80x48)" in p.stdout
    for i, (left, right) in enumerate(pairs):  # lossless, in natural order
        assert np.array_equal(cv2.imread(str(out1 / "left" / f"{i:06d}.png")), left)
        assert np.array_equal(cv2.imread(str(out1 / "right" / f"{i:06d}.png")), right)
    rows1 = read_rows(out1 / "timestamps.csv")
    assert [r["frame"] for r in rows1] == ["0", "1", "2", "3"]
    assert [r["left"] for r in rows1] == [f"left/{i:06d}.png" for i in range(4)]
    stamps = [int(r["timestamp_ns"]) for r in rows1]
    assert stamps == sorted(stamps)
    assert not (out1 / "calib.yml").exists()  # nothing was rectified

    # The recording replays: same images, and the recorded timestamps are kept.
    p = run(firmware_bin, "capture", "--source", f"replay:{out1}", "--count", "3", "--out", str(out2))
    assert p.returncode == 0, p.stderr
    assert "captured 3 pairs" in p.stdout
    rows2 = read_rows(out2 / "timestamps.csv")
    assert [int(r["timestamp_ns"]) for r in rows2] == stamps[:3]
    for i in range(3):
        for side in ("left", "right"):
            a = cv2.imread(str(out1 / side / f"{i:06d}.png"))
            b = cv2.imread(str(out2 / side / f"{i:06d}.png"))
            assert np.array_equal(a, b)


def write_calibration(path: Path, width: int, height: int) -> None:
    f = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    f.write("image_width", width)
    f.write("image_height", height)
    k = np.array([[90.0, 0, width / 2], [0, 90.0, height / 2], [0, 0, 1]])
    f.write("K1", k)
    f.write("D1", np.array([[-0.05, 0.01, 0, 0, 0]]))
    f.write("K2", k)
    f.write("D2", np.array([[-0.04, 0.0, 0, 0, 0]]))
    f.write("R", cv2.Rodrigues(np.array([0.0, 0.02, 0.01]))[0])
    f.write("T", np.array([[-0.1], [0.002], [0.0]]))
    f.release()


def test_capture_rectifies_and_records_the_rectified_calibration(firmware_bin, sequence, tmp_path):
    src, pairs = sequence
    calib = tmp_path / "stereo.yml"
    write_calibration(calib, 80, 48)
    out = tmp_path / "rect"
    p = run(firmware_bin, "capture", "--source", f"replay:{src}", "--calib", str(calib), "--count", "2", "--out", str(out))
    assert p.returncode == 0, p.stderr
    assert ", rectified" in p.stdout
    left0 = cv2.imread(str(out / "left" / "000000.png"))
    assert left0.shape == pairs[0][0].shape
    assert not np.array_equal(left0, pairs[0][0])  # remapped
    fs = cv2.FileStorage(str(out / "calib.yml"), cv2.FILE_STORAGE_READ)
    assert int(fs.getNode("rectified").real()) == 1
    assert abs(fs.getNode("B").real() - np.linalg.norm([-0.1, 0.002, 0.0])) < 1e-9
    assert fs.getNode("f").real() > 0
    assert int(fs.getNode("image_width").real()) == 80
    fs.release()
    # The recording's own calibration (pre-rectified) applies to its replay without remapping.
    out2 = tmp_path / "rect2"
    p = run(firmware_bin, "capture", "--source", f"replay:{out}", "--calib", str(out / "calib.yml"), "--out", str(out2))
    assert p.returncode == 0, p.stderr
    assert ", rectified" not in p.stdout
    assert np.array_equal(cv2.imread(str(out2 / "left" / "000001.png")), cv2.imread(str(out / "left" / "000001.png")))


def test_bad_source_strings(firmware_bin, tmp_path):
    out = tmp_path / "o"
    assert_user_error(run(firmware_bin, "capture", "--source", "webcam:0", "--out", str(out)), "unknown kind 'webcam'")
    assert_user_error(run(firmware_bin, "capture", "--source", "uvc:a,b,c", "--count", "1", "--out", str(out)), "got 3")
    cfg = tmp_path / "oakd.toml"
    cfg.write_text('[camera]\noakd_python = "/nonexistent/python3"\n')
    assert_user_error(run(firmware_bin, "capture", "--source", "oakd", "--config", str(cfg), "--count", "1",
                          "--out", str(out)), "camera.oakd_python")
    assert_user_error(run(firmware_bin, "capture", "--source", "uvc:/dev/video_fs_none", "--count", "1", "--out", str(out)),
                      "'/dev/video_fs_none' does not exist")
    assert_user_error(run(firmware_bin, "capture", "--source", "uvc:/dev/video0", "--out", str(out)), "--count N is needed")
    assert_user_error(run(firmware_bin, "capture", "--source", f"replay:{tmp_path / 'none'}", "--out", str(out)),
                      "is not a directory")
    assert not out.exists()  # a source that cannot open leaves nothing behind


def test_bad_calibration_and_size_mismatch(firmware_bin, sequence, tmp_path):
    src, _ = sequence
    big = tmp_path / "big.yml"
    write_calibration(big, 640, 480)
    assert_user_error(run(firmware_bin, "capture", "--source", f"replay:{src}", "--calib", str(big), "--out",
                          str(tmp_path / "o1")), "80x48", "640x480", str(big))
    broken = tmp_path / "broken.yml"
    broken.write_text("%YAML:1.0\n---\nimage_width: 80\nimage_height: 48\n")
    assert_user_error(run(firmware_bin, "capture", "--source", f"replay:{src}", "--calib", str(broken), "--out",
                          str(tmp_path / "o2")), str(broken), "'K1' is missing")
    assert not (tmp_path / "o2").exists()


def test_never_overwrites_a_recording(firmware_bin, sequence, tmp_path):
    src, _ = sequence
    out = tmp_path / "rec"
    assert run(firmware_bin, "capture", "--source", f"replay:{src}", "--count", "1", "--out", str(out)).returncode == 0
    before = (out / "left" / "000000.png").read_bytes()
    assert_user_error(run(firmware_bin, "capture", "--source", f"replay:{src}", "--out", str(out)), "already holds images")
    assert (out / "left" / "000000.png").read_bytes() == before
    assert len(read_rows(out / "timestamps.csv")) == 1


def test_oakd_capture_through_the_fake_bridge_writes_the_device_calibration(firmware_bin, tmp_path):
    """`capture --source oakd` with the bridge's simulated twin (camera.oakd_bridge_args = --fake): the
    pairs arrive through the child process's pipe and the device-reported (pre-rectified) calibration
    is written as calib.yml, which replay then reads."""
    cfg = tmp_path / "oakd.toml"
    cfg.write_text('[camera]\nwidth = 96\nheight = 64\noakd_bridge_args = "--fake --fps 0 --fake-disparity 7"\n')
    out = tmp_path / "rec"
    p = run(firmware_bin, "capture", "--source", "oakd", "--config", str(cfg), "--count", "3", "--out", str(out))
    assert p.returncode == 0, p.stderr
    assert "captured 3 pairs (96x64) from oakd" in p.stdout
    left = cv2.imread(str(out / "left" / "000002.png"), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(out / "right" / "000002.png"), cv2.IMREAD_GRAYSCALE)
    assert np.array_equal(right[:, :89], left[:, 7:])
    fsr = cv2.FileStorage(str(out / "calib.yml"), cv2.FILE_STORAGE_READ)
    assert fsr.getNode("rectified").real() == 1
    assert fsr.getNode("f").real() == 400.0 and abs(fsr.getNode("B").real() - 0.075) < 1e-12
    p = run(firmware_bin, "capture", "--source", f"replay:{out}", "--calib", str(out / "calib.yml"),
            "--out", str(tmp_path / "again"))
    assert p.returncode == 0, p.stderr
