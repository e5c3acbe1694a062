"""`fuzzyctl rectcheck`: row differences of feature matches reveal a rig that is no longer rectified.

The simulator renders exactly rectified pairs; known shifts, rotations and zooms of the right image
must be measured with their sign, and an intact pair must pass.
"""

from __future__ import annotations

import subprocess

import cv2
import numpy as np
import pytest

from fuzzyctl.cli import main
from fuzzyctl.errors import FatalError
from fuzzyctl.rectcheck import check_folder, check_pairs, photometric_check


@pytest.fixture(scope="module")
def sim_pair(tmp_path_factory, firmware_bin, repo_root):
    out = tmp_path_factory.mktemp("rect_sim")
    subprocess.run([str(firmware_bin), "sim", "render", str(repo_root / "common/sim/scenes/example.toml"), "--out", str(out)],
                   check=True, capture_output=True, timeout=120)
    return cv2.imread(str(out / "left.png"), cv2.IMREAD_GRAYSCALE), cv2.imread(str(out / "right.png"), cv2.IMREAD_GRAYSCALE)


def _warp(img, angle_deg=0.0, scale=1.0, dy=0.0):
    h, w = img.shape
    M = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), angle_deg, scale)
    M[1, 2] += dy
    return cv2.warpAffine(img, M, (w, h), flags=cv2.INTER_LINEAR)


@pytest.mark.firmware
def test_rectified_pair_passes(sim_pair):
    left, right = sim_pair
    r = check_pairs([("sim", left, right)])
    assert r.matches >= 100
    assert r.median_abs_dy < 0.15 and abs(r.offset_px) < 0.15 and abs(r.roll_deg) < 0.02 and abs(r.scale_pct) < 0.2


@pytest.mark.firmware
@pytest.mark.parametrize(
    "kw, field, value, tol",
    [({"dy": 2.0}, "offset_px", 2.0, 0.15), ({"dy": -1.0}, "offset_px", -1.0, 0.15),
     ({"angle_deg": 0.3}, "roll_deg", 0.3, 0.03), ({"angle_deg": -0.5}, "roll_deg", -0.5, 0.05),
     ({"scale": 1.01}, "scale_pct", 1.0, 0.15)],
)
def test_measures_the_right_images_error_with_its_sign(sim_pair, kw, field, value, tol):
    left, right = sim_pair
    r = check_pairs([("sim", left, _warp(right, **kw))])
    assert getattr(r, field) == pytest.approx(value, abs=tol)


@pytest.mark.firmware
def test_cli_exit_codes(sim_pair, tmp_path, capsys):
    left, right = sim_pair
    for side, img in (("left", left), ("right", right)):
        (tmp_path / "ok" / side).mkdir(parents=True)
        (tmp_path / "bad" / side).mkdir(parents=True)
        cv2.imwrite(str(tmp_path / "ok" / side / "000000.png"), img)
        cv2.imwrite(str(tmp_path / "bad" / side / "000000.png"), img if side == "left" else _warp(img, dy=1.5))
    assert main(["rectcheck", str(tmp_path / "ok")]) == 0
    assert "rectification OK" in capsys.readouterr().out
    assert main(["rectcheck", str(tmp_path / "bad")]) == 1
    assert "no longer rectified" in capsys.readouterr().err
    assert main(["rectcheck", "--left", str(tmp_path / "ok/left/000000.png")]) == 2
    assert check_folder(tmp_path / "ok").pairs[0].name == "000000.png"


def test_textureless_pair_is_refused():
    flat = np.full((120, 160), 128, np.uint8)
    with pytest.raises(FatalError, match="feature matches"):
        check_pairs([("flat", flat, flat)])


# ---- photometry (the matcher's camera-difference detectors, docs/algorithm.md 2b, 2c, 4b) ----------

@pytest.mark.firmware
def test_photometry_of_a_matched_pair_reads_as_matched(sim_pair):
    left, right = sim_pair
    ph = photometric_check([("sim", left, right)])
    (p,) = ph.pairs
    assert not p.mismatched and p.grey_shift < 5.0 and p.brightness == pytest.approx(1.0, abs=0.05)
    assert ph.advice() is None


@pytest.mark.firmware
def test_photometry_finds_a_darker_and_a_noisier_right_camera(sim_pair):
    left, right = sim_pair
    dark = np.clip(np.rint(right * 0.6), 0, 255).astype(np.uint8)
    noisy = np.clip(np.rint(right + np.random.default_rng(3).normal(0.0, 6.0, right.shape)), 0, 255).astype(np.uint8)
    ph = photometric_check([("dark", left, dark), ("noisy", left, noisy), ("dark2", left, dark)])
    d, n, _ = ph.pairs
    assert d.gain_triggered and not d.equalised and d.brightness == pytest.approx(0.6, abs=0.05)
    assert n.equalised and n.noise_right > n.noise_left + 3.0
    assert ph.mismatched == 3
    advice = ph.advice()
    assert advice is not None and "darker" in advice and "1.5x" in advice
    # the thresholds are the config's: a config that raises them takes the same pairs as matched
    from fuzzyctl.config import parse_config

    lenient = parse_config("[cost]\ngradient_gain_grey_shift = 200.0\nnoise_excess = 0.0\n", "lenient.toml")
    assert photometric_check([("dark", left, dark), ("noisy", left, noisy)], lenient).mismatched == 0


@pytest.mark.firmware
def test_cli_prints_the_photometry_and_warns(sim_pair, tmp_path, capsys):
    left, right = sim_pair
    for side, img in (("left", left), ("right", np.clip(np.rint(right * 0.6), 0, 255).astype(np.uint8))):
        (tmp_path / "d" / side).mkdir(parents=True)
        cv2.imwrite(str(tmp_path / "d" / side / "000000.png"), img)
    assert main(["rectcheck", str(tmp_path / "d")]) == 0  # advice, not a failure
    out = capsys.readouterr().out
    assert "photometry: right image x0.6" in out and "warning:" in out and "darker" in out
