"""The firmware program's behaviour on good and bad input (issue: "Bad input ... gives one clear
error line and a non-zero exit, never a crash; tests cover each")."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

pytestmark = pytest.mark.firmware


def run(binary: Path, *args: str, stdin: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([str(binary), *args], capture_output=True, text=True, timeout=120, input=stdin)


def assert_user_error(p: subprocess.CompletedProcess, *needles: str) -> None:
    """Exit code 2 (not a signal, not an internal error) and one stderr line naming the culprit."""
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, p.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> tuple[Path, Path]:
    """A textured 96x64 pair with a constant disparity of 5 px."""
    d = tmp_path_factory.mktemp("pair")
    rng = np.random.default_rng(3)
    left = cv2.GaussianBlur(rng.integers(0, 256, (64, 96)).astype(np.uint8), (3, 3), 0)
    right = np.empty_like(left)
    right[:, :-5] = left[:, 5:]
    right[:, -5:] = left[:, -1:]
    cv2.imwrite(str(d / "l.png"), left)
    cv2.imwrite(str(d / "r.png"), right)
    return d / "l.png", d / "r.png"


def test_match_writes_kitti_pngs_and_dump(firmware_bin, pair, tmp_path):
    left, right = pair
    out = tmp_path / "out"
    p = run(firmware_bin, "match", "--left", str(left), "--right", str(right), "--max-disparity", "16",
            "--out", str(out), "--dump")
    assert p.returncode == 0, p.stderr
    disp = cv2.imread(str(out / "disp_left.png"), cv2.IMREAD_UNCHANGED)
    assert disp.dtype == np.uint16 and disp.shape == (64, 96)
    valid = disp[:, 20:] > 0
    assert valid.mean() > 0.8
    assert np.median(disp[:, 20:][valid]) / 256.0 == pytest.approx(5.0, abs=0.25)
    for f in ["meta.json", "left.png", "right.png", "labels_left.npy", "labels_right.npy", "seg_left.npy",
              "seg_right.npy", "disp_left_wta.npy", "disp_right_wta.npy", "lr_mask.npy", "disp_lr.npy",
              "esr_replaced.npy", "disp_final.npy"]:
        assert (out / "dump" / f).is_file(), f
    meta = json.loads((out / "dump" / "meta.json").read_text())
    assert meta["format"] == "fuzzystereo-dump" and meta["width"] == 96 and meta["height"] == 64
    final = np.load(out / "dump" / "disp_final.npy")
    # disp_left.png is the dumped final map (Q4 -> x256), 0 where the dump says invalid or 0 px.
    expect = np.where(final > 0, final.astype(np.int32) * 16, 0)
    assert np.array_equal(disp.astype(np.int32), expect)


def test_missing_file(firmware_bin, pair, tmp_path):
    left, _ = pair
    p = run(firmware_bin, "match", "--left", str(left), "--right", str(tmp_path / "nope.png"), "--out", str(tmp_path))
    assert_user_error(p, "nope.png", "does not exist")


def test_unreadable_image(firmware_bin, pair, tmp_path):
    left, _ = pair
    bad = tmp_path / "bad.png"
    bad.write_text("this is not a png\n")
    p = run(firmware_bin, "match", "--left", str(left), "--right", str(bad), "--out", str(tmp_path))
    assert_user_error(p, "bad.png", "could not be decoded")


def test_size_mismatch(firmware_bin, pair, tmp_path):
    left, _ = pair
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((10, 12), np.uint8))
    p = run(firmware_bin, "match", "--left", str(left), "--right", str(small), "--out", str(tmp_path))
    assert_user_error(p, "small.png", "96x64", "12x10")


def test_output_directory_that_cannot_be_created(firmware_bin, pair, tmp_path):
    left, right = pair
    blocker = tmp_path / "file"
    blocker.write_text("a file where the output directory should go\n")
    p = run(firmware_bin, "match", "--left", str(left), "--right", str(right), "--out", str(blocker / "out"))
    assert_user_error(p, "cannot create output directory", str(blocker / "out"))


def test_downscale_that_leaves_no_pixel(firmware_bin, tmp_path):
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), np.full((5, 7), 90, np.uint8))
    p = run(firmware_bin, "match", "--left", str(tiny), "--right", str(tiny), "--downscale", "8", "--out", str(tmp_path / "o"))
    assert_user_error(p, "--downscale 8", "7x5")


@pytest.mark.parametrize("toml, needles", [
    ("[cost]\nmax_disparity = 999\n", ["cost.max_disparity", "[2, 256]"]),
    ("[esr]\nwindow = 4\n", ["esr.window", "odd"]),
    ("[cost]\nalpha = -0.5\n", ["cost.alpha", "[0, 1]"]),
    ("[segmentation]\nregion_sise = 8\n", ["unknown field", "segmentation.region_sise"]),
    ("[cost\nalpha = 1\n", ["TOML syntax error"]),
])
def test_bad_config(firmware_bin, pair, tmp_path, toml, needles):
    left, right = pair
    cfg = tmp_path / "bad.toml"
    cfg.write_text(toml)
    p = run(firmware_bin, "match", "--left", str(left), "--right", str(right), "--config", str(cfg), "--out", str(tmp_path))
    assert_user_error(p, str(cfg), *needles)


def test_missing_config_file(firmware_bin, pair, tmp_path):
    left, right = pair
    p = run(firmware_bin, "match", "--left", str(left), "--right", str(right), "--config", str(tmp_path / "c.toml"),
            "--out", str(tmp_path))
    assert_user_error(p, "c.toml")


def test_eval_unknown_layout_and_radiometric(firmware_bin, tmp_path):
    (tmp_path / "empty").mkdir()
    assert_user_error(run(firmware_bin, "eval", "--dataset", str(tmp_path / "empty")), str(tmp_path / "empty"))
    assert_user_error(run(firmware_bin, "eval", "--dataset", str(tmp_path / "missing")), "missing")
    p = run(firmware_bin, "eval", "--dataset", str(tmp_path / "empty"), "--radiometric", "sepia")
    assert_user_error(p, "sepia")


def test_eval_rejects_a_negative_noise_seed(firmware_bin, tmp_path):
    (tmp_path / "empty").mkdir()
    p = run(firmware_bin, "eval", "--dataset", str(tmp_path / "empty"), "--radiometric", "noise", "--noise-seed", "-3")
    assert p.returncode != 0
    assert "--noise-seed" in p.stderr and "-3" in p.stderr, p.stderr


def test_fis_eval_rejects_out_of_range(firmware_bin):
    p = run(firmware_bin, "fis", "eval", stdin="0.5 0.5\n1.5 0.2\n")
    assert_user_error(p, "line 2")


@pytest.mark.parametrize("args", [
    ["sim", "suite", "--count", "50"],
    ["run", "--source", "sim", "--motors", "sim", "--max-frames", "50"],
    ["sim", "track-eval"],
])
def test_json_output_that_cannot_be_written_fails_before_the_run(firmware_bin, tmp_path, args):
    # A mistyped --json directory must not cost the run's minutes and then lose its results.
    import time

    t0 = time.monotonic()
    p = run(firmware_bin, *args, "--json", str(tmp_path / "no-such-dir" / "r.json"))
    assert_user_error(p, "no-such-dir")
    assert time.monotonic() - t0 < 20
