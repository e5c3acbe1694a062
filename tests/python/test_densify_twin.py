"""The float twin of the densify stage (reference/densify.py) and its slant-aware fill
(``[densify] interpolate_max_diff``, docs/algorithm.md 6b), alone and against a firmware dump."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from fuzzyctl import dump as dm
from fuzzyctl.reference.densify import densify, extrapolate_left_border, median_fill, occlusion_fill, seen_by_right, smooth_disparity


def _slanted_band(w: int = 61, h: int = 21) -> tuple[np.ndarray, np.ndarray]:
    """A plane whose disparity grows 1 px per row (a road), rows 5..15 without estimates."""
    plane = np.repeat((10.0 + np.arange(h, dtype=float))[:, None], w, axis=1)
    holes = plane.copy()
    holes[5:16] = np.nan
    return plane, holes


def test_interpolating_fill_puts_the_plane_into_a_band_of_holes():
    plane, holes = _slanted_band()
    inner = (slice(5, 16), slice(11, 50))  # columns where every diagonal ray meets row 4 or 16
    slant, filled = median_fill(holes, interpolate_max_diff=64.0)
    assert filled[5:16].all()
    np.testing.assert_allclose(slant[inner], plane[inner], atol=1e-9)
    plain, _ = median_fill(holes, interpolate_max_diff=0.0)
    assert np.abs(plain[inner] - plane[inner]).max() >= 4.0  # the median puts a step there
    # rows 4 and 16 differ by 12 px: an 8 px threshold interpolates nothing
    np.testing.assert_array_equal(median_fill(holes, interpolate_max_diff=8.0)[0], plain)


def test_densify_passes_the_threshold_to_the_fill():
    plane, holes = _slanted_band()
    out, changed = densify(holes, True, 0, 3.0, True, interpolate_max_diff=64.0)
    np.testing.assert_allclose(out[5:16, 11:50], plane[5:16, 11:50], atol=1e-9)
    assert (changed[5:16] == 1).all() and (changed[:5] == 0).all()


def _occluding_box(w: int = 80) -> tuple[np.ndarray, np.ndarray]:
    """Background at 10 px, a box at 20 px over left columns 40..59 (right columns 20..39).
    Left columns 30..39 see background the box hides from the right camera."""
    left = np.full((3, w), 10.0)
    left[:, 40:60] = 20.0
    right = np.full((3, w), 10.0)
    right[:, 20:40] = 20.0
    return left, right


def test_occlusion_fill_takes_the_background_of_the_occluded_run():
    truth, right = _occluding_box()
    seen = seen_by_right(right, 0)
    assert not seen[:, 30:40].any() and seen[:, 40:].all() and seen[:, 10:30].all()
    assert not seen[:, :10].any()  # the left border band: x < d has no partner
    holes = truth.copy()
    holes[:, 28:44] = np.nan  # the occluded run plus two seen pixels each side (mismatches)
    out, filled = occlusion_fill(holes, right, dilate=0, max_gap=64)
    np.testing.assert_array_equal(out[:, 30:40], 10.0)  # the background, not the box
    assert filled[:, 30:40].all() and not filled[:, 28:30].any() and not filled[:, 40:44].any()
    assert np.isnan(out[:, 28:30]).all() and np.isnan(out[:, 40:44]).all()  # left to the median fill
    # dilate 1 widens every hit by a pixel: columns 30 and 39 count as seen
    out1, filled1 = occlusion_fill(holes, right, dilate=1, max_gap=64)
    assert filled1[:, 31:39].all() and not filled1[:, 30].any() and not filled1[:, 39].any()
    # a run longer than max_gap is left alone
    assert not occlusion_fill(holes, right, dilate=0, max_gap=15)[1].any()
    # the median fill alone puts the mean of background and box into the occluded run
    plain, _ = densify(holes, True, 0, 3.0, True)
    assert np.abs(plain[:, 30:40] - 10.0).max() >= 4.0
    dense, changed = densify(holes, True, 0, 3.0, True, disp_right=right, occlusion_dilate=0)
    np.testing.assert_array_equal(dense[:, 30:40], 10.0)
    assert (changed[:, 28:44] == 1).all()


def _kitti_pair(datasets_root):
    k = datasets_root / "kitti2015" / "training"
    left, right = k / "image_2" / "000046_10.png", k / "image_3" / "000046_10.png"
    if not left.is_file() or not right.is_file():
        pytest.skip(f"{left} or {right} not found")
    return left, right


def _firmware_dump(firmware_bin, left, right, out, smooth: bool, extra: str = ""):
    # KITTI 2015 000046 at half size: a road, slanted in disparity, with holes after eq. (13).
    cfg = out.with_suffix(".toml")
    cfg.write_text(f"[densify]\nsmooth = {'true' if smooth else 'false'}\n{extra}")
    proc = subprocess.run([str(firmware_bin), "match", "--left", str(left), "--right", str(right), "--downscale", "2",
                           "--max-disparity", "80", "--config", str(cfg), "--out", str(out), "--dump"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return dm.read_dump(out)


@pytest.mark.firmware
@pytest.mark.datasets
def test_firmware_interpolating_fill_matches_the_twin(firmware_bin, datasets_root, tmp_path):
    d = _firmware_dump(firmware_bin, *_kitti_pair(datasets_root), tmp_path / "fw", smooth=False)
    esr, final = d.disp("disp_esr"), d.disp("disp_final")
    holes = np.isnan(np.where(esr == 0, np.nan, esr))
    assert holes.mean() > 0.2, "too few holes for the check to mean anything"

    def agreement(threshold: float) -> float:
        twin, _ = densify(esr, True, 100, 3.0, True, interpolate_max_diff=threshold, disp_right=d.disp("disp_right_wta"))
        ok = ~np.isnan(twin) & ~np.isnan(final)
        return float(np.mean(np.abs(twin[ok] - final[ok])[holes[ok]] <= 1.0 / 16 + 1e-9))

    # the firmware rounds each interpolation to Q4; the twin does not
    assert agreement(8.0) >= 0.995
    assert agreement(0.0) < agreement(8.0) - 0.02  # the default fill is the interpolating one


@pytest.mark.firmware
@pytest.mark.datasets
def test_firmware_smoothing_matches_the_twin(firmware_bin, datasets_root, tmp_path):
    # The smoothing alone: the twin smooths the firmware's unsmoothed final map.
    left, right = _kitti_pair(datasets_root)
    rough = _firmware_dump(firmware_bin, left, right, tmp_path / "rough", smooth=False).disp("disp_final")
    smooth = _firmware_dump(firmware_bin, left, right, tmp_path / "smooth", smooth=True).disp("disp_final")
    twin = smooth_disparity(rough, 6, 6, 8.0, 3.0, 0.1)
    diff = np.abs(twin - smooth)[~np.isnan(rough)]
    # the Q4 rounding of the mean alone is up to 1/32 px; the Q12 weights and the 1/32-sigma range table add a little
    assert float(np.mean(diff <= 1.0 / 32 + 1e-9)) >= 0.98
    assert diff.max() <= 1.0 / 16
    assert float(np.mean(np.abs(rough - smooth)[~np.isnan(rough)] > 1.0 / 16)) > 0.2  # it did change the map


def test_border_extrapolation_continues_a_receding_surface_and_leaves_flat_rows():
    # Row 0: a surface receding from the left edge (d = 50 - 0.5 x), estimates from x = 20 on; row 1 flat;
    # row 2 rising towards the border by 0.1 px per column only.
    x = np.arange(60, dtype=float)
    before = np.vstack([50 - 0.5 * x, np.full(60, 12.0), 30 - 0.1 * x])
    before[:, :20] = np.nan
    out = np.where(np.isnan(before), -1.0, before)
    assert extrapolate_left_border(out, before, 16, cap=45.0) == 2
    np.testing.assert_allclose(out[0, 10:20], 50 - 0.5 * x[10:20])
    np.testing.assert_array_equal(out[0, :10], 45.0)  # capped below the search range
    np.testing.assert_array_equal(out[1, :20], -1.0)  # flat: the fill stays
    np.testing.assert_allclose(out[2, :20], 30 - 0.1 * x[:20])
    out2 = np.where(np.isnan(before), -1.0, before)
    assert extrapolate_left_border(out2, before, 16, min_slope=0.2) == 1  # row 2 is not steep enough
    np.testing.assert_array_equal(out2[2, :20], -1.0)


@pytest.mark.firmware
@pytest.mark.datasets
def test_firmware_border_extrapolation_matches_the_twin(firmware_bin, datasets_root, tmp_path):
    # [densify] border_fit_px on the KITTI dump: the twin extends the same rows by the same lines (Q4 rounding).
    left, right = _kitti_pair(datasets_root)
    d = _firmware_dump(firmware_bin, left, right, tmp_path / "fw", smooth=False, extra="border_fit_px = 40\n")
    plain = _firmware_dump(firmware_bin, left, right, tmp_path / "plain", smooth=False)
    esr, final = d.disp("disp_esr"), d.disp("disp_final")
    twin, _ = densify(esr, True, 100, 3.0, True, interpolate_max_diff=8.0, disp_right=d.disp("disp_right_wta"),
                      border_fit=(40, 0.0, 80))
    changed = final != plain.disp("disp_final")
    assert changed.sum() > 100, "the option changed too little of the frame for the check to mean anything"
    assert float(np.mean(np.abs(twin - final)[changed] <= 1.0 / 32 + 1e-9)) >= 0.999
