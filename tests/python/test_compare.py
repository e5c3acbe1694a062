"""fuzzyctl compare / reference match: metrics, tolerances, report, exit codes.

Without the firmware, a reference dump is compared with the reference itself (must agree
everywhere) and with doctored copies (must fail). With the firmware binary, a real dump of a
synthetic pair (and, with the datasets, of Tsukuba) must be within the default tolerances.
"""

from __future__ import annotations

import base64
import re
import shutil
import subprocess

import cv2
import numpy as np
import pytest

from fuzzyctl import compare as cmp
from fuzzyctl import dump as dm
from fuzzyctl.cli import main
from fuzzyctl.errors import FatalError
from fuzzyctl.reference import segmentation
from synthetic import two_plane_pair


@pytest.fixture(scope="module")
def pair_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    left, right, _ = two_plane_pair(32, 48, 2, 6, seed=12)
    cv2.imwrite(str(d / "left.png"), left)
    cv2.imwrite(str(d / "right.png"), right)
    cfg = d / "small.toml"
    # integer disparities: the reference's float maps survive the dump's Q4 exactly, so the
    # reference compared with its own dump agrees everywhere (see test_subpixel_self_compare)
    cfg.write_text("[cost]\nmax_disparity = 10\nsubpixel = false\n")
    return d / "left.png", d / "right.png", cfg


@pytest.fixture(scope="module")
def ref_run(pair_files, tmp_path_factory):
    """`fuzzyctl reference match` output directory (OUT/dump + KITTI PNGs)."""
    left, right, cfg = pair_files
    out = tmp_path_factory.mktemp("refrun")
    assert main(["reference", "match", "--left", str(left), "--right", str(right), "--config", str(cfg), "--out", str(out)]) == 0
    return out


def test_reference_match_writes_dump_and_disparity_pngs(ref_run):
    d = dm.read_dump(ref_run)
    assert d.meta["producer"] == "fuzzyctl reference"
    assert "max_disparity = 10" in d.config_toml
    kitti = cv2.imread(str(ref_run / "disp_left.png"), cv2.IMREAD_UNCHANGED)
    assert kitti.dtype == np.uint16 and kitti.shape == (32, 48)
    valid = d["disp_final"] != -1
    np.testing.assert_allclose(kitti[valid] / 256.0, d.disp("disp_final")[valid], atol=1 / 32 + 1 / 256)  # Q4 vs /256
    assert np.all(kitti[~valid] == 0)


def test_reference_match_labels_from(ref_run, pair_files, tmp_path):
    left, right, cfg = pair_files
    out = tmp_path / "again"
    args = ["reference", "match", "--left", str(left), "--right", str(right), "--config", str(cfg), "--labels-from", str(ref_run), "--out", str(out)]
    assert main(args) == 0
    a, b = dm.read_dump(ref_run), dm.read_dump(out)
    for name in dm.ARRAYS:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_reference_match_errors(pair_files, tmp_path, capsys):
    left, right, _ = pair_files
    assert main(["reference", "match", "--left", str(tmp_path / "x.png"), "--right", str(right), "--out", str(tmp_path)]) == 2
    assert "x.png not found" in capsys.readouterr().err
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((8, 8), np.uint8))
    assert main(["reference", "match", "--left", str(left), "--right", str(small), "--out", str(tmp_path)]) == 2
    assert "a rectified pair must match" in capsys.readouterr().err


def test_compare_reference_with_itself_agrees_everywhere(ref_run, tmp_path, capsys):
    report = tmp_path / "report.html"
    assert main(["compare", str(ref_run), "--report", str(report)]) == 0
    out = capsys.readouterr().out
    assert "all checked metrics within tolerance" in out
    c = cmp.compare_run(ref_run)
    for m in c.metrics:
        if m.unit == "%" and "valid" not in m.name:
            assert m.value == pytest.approx(100.0), m.name
    assert c.metric("fis_score_abs_error_max").value <= 1 / 65536


def test_subpixel_self_compare(pair_files, tmp_path):
    # with sub-pixel disparities the dump rounds the reference to Q4: end-to-end metrics still
    # agree; the stage-isolated ones (which re-run eq. 13-15 on the Q4 maps) only nearly
    left, right, _ = pair_files
    cfg = tmp_path / "sub.toml"
    cfg.write_text("[cost]\nmax_disparity = 10\nsubpixel = true\n")
    out = tmp_path / "ref"
    assert main(["reference", "match", "--left", str(left), "--right", str(right), "--config", str(cfg), "--out", str(out)]) == 0
    d = dm.read_dump(out)
    sub = dm.q4_to_disp(d["seg_left"][:, dm.SEG_DISP_Q4]) - d["seg_left"][:, dm.SEG_DISP]
    assert np.abs(sub).max() <= 0.5 and np.any(sub != 0)
    c = cmp.compare_run(out)
    for m in c.metrics:
        if m.unit == "%" and "valid" not in m.name:
            assert m.value >= (99.0 if "isolated" in m.name else 100.0 - 1e-9), m.name


def test_report_is_self_contained(ref_run, tmp_path):
    report = tmp_path / "r.html"
    assert main(["compare", str(ref_run), "--report", str(report)]) == 0
    text = report.read_text()
    assert text.startswith("<!DOCTYPE html>") and "PASS" in text
    srcs = re.findall(r'src="([^"]+)"', text)
    assert len(srcs) >= 12
    for s in srcs:
        assert s.startswith("data:image/png;base64,")
        assert base64.b64decode(s.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert "http" not in text.replace("http-equiv", "")
    for metric in ("seg_winner_agreement_left_pct", "final_within_1px_pct"):
        assert metric in text


def test_doctored_dump_fails_with_exit_1(ref_run, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(ref_run, run)
    d = run / "dump"
    seg = np.load(d / "seg_left.npy")
    seg[:, 0] = (seg[:, 0] + 1) % 10  # every left winner off by one
    np.save(d / "seg_left.npy", seg)
    final = np.load(d / "disp_final.npy")
    final[final >= 0] += 3 * 16  # final map off by 3 px
    np.save(d / "disp_final.npy", final)
    assert main(["compare", str(run)]) == 1
    err = capsys.readouterr().err
    assert "seg_winner_agreement_left_pct = 0" in err and "final_within_1px_pct" in err


def test_tolerances_file(ref_run, tmp_path, capsys):
    strict = tmp_path / "tol.toml"
    strict.write_text("[final_valid_reference_pct]\nmax = 99.0\n")  # the densified reference map is ~100 % valid
    assert main(["compare", str(ref_run), "--tolerances", str(strict)]) == 1
    bad = tmp_path / "bad.toml"
    bad.write_text("[final_within_9px_pct]\nmin = 1\n")
    assert main(["compare", str(ref_run), "--tolerances", str(bad)]) == 2
    assert "unknown metric 'final_within_9px_pct'" in capsys.readouterr().err
    bad.write_text("[final_within_1px_pct]\nminimum = 1\n")
    with pytest.raises(FatalError, match=r"\[final_within_1px_pct\] needs min"):
        cmp.load_tolerances(bad)


def test_default_tolerances_load():
    tol = cmp.load_tolerances()
    assert tol["seg_winner_agreement_left_pct"].min == 99.0
    assert tol["final_within_1px_pct"].min == 99.0


def test_compare_missing_dump_is_one_line(tmp_path, capsys):
    assert main(["compare", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fuzzyctl: error: no dump in") and "\n" not in err


def test_compare_own_segmentation(ref_run):
    c = cmp.compare_run(ref_run, own_segmentation=True)
    # the reference's own SLIC of the same images is the same partition
    assert c.metric("segmentation_agreement_left_pct").value == pytest.approx(100.0)


def test_map_agreement_semantics():
    n = np.nan
    a = np.array([1.0, 2.0, n, n, 5.0])
    b = np.array([1.0, 3.0, n, 4.0, 7.5])
    assert cmp.map_agreement(a, b, 0) == pytest.approx(40.0)
    assert cmp.map_agreement(a, b, 1) == pytest.approx(60.0)
    assert cmp.map_agreement(a, b, 2.5) == pytest.approx(80.0)


# ---- against the firmware ------------------------------------------------------------------------


def _firmware_dump(firmware_bin, left, right, out, *extra):
    proc = subprocess.run([str(firmware_bin), "match", "--left", str(left), "--right", str(right), "--out", str(out), "--dump", *extra],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return out


def _firmware_pair_dump(firmware_bin, pair_files, tmp_path, extra_toml):
    """Firmware dump of the small pair with its config plus ``extra_toml`` sections."""
    left, right, _ = pair_files
    cfg = tmp_path / "extra.toml"
    cfg.write_text("[cost]\nmax_disparity = 10\nsubpixel = false\n\n" + extra_toml)
    return _firmware_dump(firmware_bin, left, right, tmp_path / "fw", "--config", str(cfg))


def _assert_compare_passes(run, tmp_path, capsys):
    rc = main(["compare", str(run), "--report", str(tmp_path / "report.html")])
    out = capsys.readouterr()
    assert rc == 0, out.out + out.err


@pytest.mark.firmware
def test_firmware_dump_within_tolerance(firmware_bin, pair_files, tmp_path, capsys):
    left, right, cfg = pair_files
    run = _firmware_dump(firmware_bin, left, right, tmp_path / "fw", "--config", str(cfg))
    _assert_compare_passes(run, tmp_path, capsys)


@pytest.mark.firmware
def test_fault_injection_is_caught(firmware_bin, pair_files, tmp_path, capsys):
    # testing.inject_shift = 1 makes the firmware's cost stage look one pixel off
    run = _firmware_pair_dump(firmware_bin, pair_files, tmp_path, "[testing]\ninject_shift = 1\n")
    assert main(["compare", str(run)]) == 1
    out = capsys.readouterr()
    assert "testing.inject_shift = 1" in out.out
    assert "comparison outside tolerance" in out.err


@pytest.mark.firmware
def test_firmware_noise_equalisation_matches_the_reference(firmware_bin, tmp_path, capsys):
    # docs/algorithm.md 2c: a smooth scene whose right view carries sensor noise (std 6) makes
    # both sides smooth the pair; the dump records the decision and compare stays within tolerance.
    y, x = np.mgrid[0:48, 0:80]
    scene = 60.0 + 1.2 * x + 0.4 * y + 40.0 * (np.sin(x / 3.0) * np.sin(y / 4.0) > 0.3)
    left = np.clip(np.rint(scene), 0, 255).astype(np.uint8)
    right = np.roll(left, -4, axis=1)
    right = np.clip(np.rint(right + np.random.default_rng(5).normal(0, 6.0, right.shape)), 0, 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "l.png"), left)
    cv2.imwrite(str(tmp_path / "r.png"), right)
    cfg = tmp_path / "c.toml"
    cfg.write_text("[cost]\nmax_disparity = 10\nsubpixel = false\n")
    run = _firmware_dump(firmware_bin, tmp_path / "l.png", tmp_path / "r.png", tmp_path / "fw", "--config", str(cfg))
    meta = dm.read_meta(dm.find_dump_dir(run) / "meta.json")
    assert meta["radiometric"]["noise_equalised"] is True
    assert meta["radiometric"]["boundary_refined"] is True  # docs/algorithm.md 4b "On a mismatched pair"
    rc = main(["compare", str(run)])
    out = capsys.readouterr()
    assert rc == 0, out.out + out.err


@pytest.mark.firmware
@pytest.mark.datasets
@pytest.mark.slow
def test_firmware_tsukuba_within_tolerance(firmware_bin, datasets_root, tmp_path, capsys):
    tsukuba = datasets_root / "middlebury2001-3" / "tsukuba"
    if not (tsukuba / "im3.png").is_file():
        pytest.skip(f"{tsukuba} has no im3.png/im4.png")
    cfg = tmp_path / "c.toml"
    cfg.write_text("[cost]\nmax_disparity = 16\n")
    run = _firmware_dump(firmware_bin, tsukuba / "im3.png", tsukuba / "im4.png", tmp_path / "fw",
                         "--config", str(cfg), "--downscale", "2")
    rc = main(["compare", str(run)])
    out = capsys.readouterr()
    assert rc == 0, out.out + out.err
    # docs/algorithm.md 5b (the default since session 56): the firmware's dump records the segments the candidate
    # retry recovered, and the reference's retry (float FIS ranking) on the firmware's maps was checked above
    meta = dm.read_meta(dm.find_dump_dir(run) / "meta.json")
    assert meta["lr_check"]["retry_recovered"] > 0
    assert cmp.compare_run(run).metric("lr_retry_isolated_agreement_pct").value is not None


@pytest.mark.firmware
def test_firmware_coarse_slic_start_matches_the_reference(firmware_bin, pair_files, tmp_path, capsys):
    # docs/algorithm.md 1: with `coarse_iterations`, the firmware's integer SLIC and the reference's
    # float SLIC (each its own, from the same config) give the same partition up to rounding and ties:
    # on this 48 x 32 pair 91-92 % of the pixels (the defaults without the coarse start: 87-96 %)
    run = _firmware_pair_dump(firmware_bin, pair_files, tmp_path, "[segmentation]\ncoarse_iterations = 2\niterations = 1\n")
    _assert_compare_passes(run, tmp_path, capsys)
    own = cmp.compare_run(run, own_segmentation=True)
    assert own.metric("segmentation_agreement_left_pct").value >= 85.0
    assert own.metric("segmentation_agreement_right_pct").value >= 85.0
    # ... and the coarse start is not a no-op: one full-resolution round alone partitions differently
    d = dm.read_dump(run)
    without = segmentation.slic(d.left, 8, 20, 1, 25)
    assert segmentation.label_agreement(d["labels_left"], without) < 99.0


@pytest.mark.firmware
def test_firmware_boundary_refinement_matches_the_reference(firmware_bin, pair_files, tmp_path, capsys):
    # docs/algorithm.md 4b: the refined WTA maps of the firmware (summed-area tables per segment)
    # and of the reference (one box-filtered Hamming plane per disparity) must agree
    run = _firmware_pair_dump(firmware_bin, pair_files, tmp_path, "[boundary]\nenabled = true\nwindow = 7\nmin_jump = 1\n")
    _assert_compare_passes(run, tmp_path, capsys)
    c = cmp.compare_run(run)
    assert c.metric("wta_paint_isolated_pct").value == 100.0  # the reference refines the firmware's table bit for bit
    assert c.metric("wta_left_within_1px_pct").value >= 99.0
    d = dm.read_dump(run)  # ... and the stage did change pixels on this pair
    q4 = d["seg_left"][:, dm.SEG_DISP_Q4]
    assert np.count_nonzero(np.where(q4 < 0, -1, q4)[d["labels_left"]] != d["disp_left_wta"]) > 20
