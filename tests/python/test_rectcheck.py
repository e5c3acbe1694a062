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
from fuzzyctl.rectcheck import check_folder, check_pairs


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
