"""`fuzzystereo sim`: scene validation errors (exit 2, one line naming the field), render outputs and
determinism, and a tiny generated set in the KITTI-2015-like layout that `fuzzystereo eval` scores."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

pytestmark = pytest.mark.firmware


def run(binary: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(binary), *args], capture_output=True, text=True, timeout=300)


def scene_error(binary: Path, tmp_path: Path, text: str) -> str:
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    p = run(binary, "sim", "render", str(scene), "--out", str(tmp_path / "out"))
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, p.stderr
    assert str(scene) in lines[0]
    assert not (tmp_path / "out").exists(), "nothing is written for a bad scene"
    return lines[0]


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("[camera]\nbaseline_m = -0.1\n", "camera.baseline_m = -0.1 is out of range: float in (0, 2] m"),
        ("[[obstacles]]\nx_m = 2\ntexture = \"foo\"\n", 'obstacles[0].texture = "foo" is not valid: one of "bricks"'),
        ("[[obstacles]]\nx_m = 2\n[[obstacles]]\nz_m = -0.5\n",
         "obstacles[1].z_m = -0.5: obstacle below ground (must be >= 0)"),
        ("[camera]\nfocal = 400\n", "unknown field 'camera.focal'"),
        ("[ground]\nscale_m = \"big\"\n", 'ground.scale_m = "big" has the wrong type'),
        ("[sky]\nkind = \"foggy\"\n", 'sky.kind = "foggy" is not valid: one of "clear", "overcast", "sunset"'),
    ],
)
def test_bad_scene_is_one_line_exit_2(firmware_bin, tmp_path, text, needle):
    assert needle in scene_error(firmware_bin, tmp_path, text)


def test_missing_scene_file(firmware_bin, tmp_path):
    p = run(firmware_bin, "sim", "render", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o"))
    assert p.returncode == 2 and "nope.toml" in p.stderr


def test_render_example_writes_ground_truth_and_is_deterministic(firmware_bin, repo_root, tmp_path):
    scene = repo_root / "common" / "sim" / "scenes" / "example.toml"
    outs = []
    for k in range(2):
        out = tmp_path / f"r{k}"
        p = run(firmware_bin, "sim", "render", str(scene), "--out", str(out), "--threads", str(k + 1))
        assert p.returncode == 0, p.stderr
        outs.append(out)
    for f in ["left.png", "right.png", "disp_gt.png", "road_mask.png", "sky_mask.png", "obstacles.png"]:
        a = cv2.imread(str(outs[0] / f), cv2.IMREAD_UNCHANGED)
        b = cv2.imread(str(outs[1] / f), cv2.IMREAD_UNCHANGED)
        assert a is not None and np.array_equal(a, b), f
    left = cv2.imread(str(outs[0] / "left.png"), cv2.IMREAD_UNCHANGED)
    assert left.shape == (360, 640, 3)
    disp = cv2.imread(str(outs[0] / "disp_gt.png"), cv2.IMREAD_UNCHANGED)
    assert disp.dtype == np.uint16
    road = cv2.imread(str(outs[0] / "road_mask.png"), cv2.IMREAD_UNCHANGED)
    sky = cv2.imread(str(outs[0] / "sky_mask.png"), cv2.IMREAD_UNCHANGED)
    ids = cv2.imread(str(outs[0] / "obstacles.png"), cv2.IMREAD_UNCHANGED)
    # Partition: each pixel is road, sky or an obstacle; GT disparity exactly where not sky.
    assert np.all((road == 255).astype(int) + (sky == 255) + (ids > 0) == 1)
    assert np.array_equal(disp > 0, sky == 0)
    truth = json.loads((outs[0] / "obstacles.json").read_text())
    assert truth["calib"]["focal_px"] == 420 and truth["calib"]["baseline_m"] == 0.12
    assert len(truth["obstacles"]) == 4
    for o in truth["obstacles"]:
        x0, y0, x1, y1 = o["box"]
        mask = ids == o["id"] + 1
        assert mask.sum() == o["visible_pixels"] > 0
        ys, xs = np.nonzero(mask)
        assert (xs.min(), ys.min(), xs.max(), ys.max()) == (x0, y0, x1, y1)
        # distance = median depth over the visible pixels, depth = f*B/d
        depth = 420 * 0.12 / (disp[mask] / 256.0)
        assert o["distance_m"] == pytest.approx(float(np.median(depth)), rel=0.01)
    assert (outs[0] / "preview.png").is_file() and (outs[0] / "disp_gt_color.png").is_file()


def test_generate_layout_reproduce_and_eval(firmware_bin, tmp_path):
    out = tmp_path / "set"
    p = run(firmware_bin, "sim", "generate", "--count", "3", "--seed", "11", "--out", str(out),
            "--width", "320", "--height", "180", "--threads", "2")
    assert p.returncode == 0, p.stderr
    assert "[3/3]" in p.stderr
    marker = json.loads((out / "fuzzystereo_sim.json").read_text())
    assert marker["count"] == 3 and marker["seed"] == 11
    tr = out / "training"
    max_gt = 0.0
    for i in range(3):
        n = f"{i:06d}"
        for f in [f"image_2/{n}_10.png", f"image_3/{n}_10.png", f"disp_occ_0/{n}_10.png",
                  f"calib_cam_to_cam/{n}.txt", f"sim_gt/{n}_10.json", f"sim_gt/{n}_10_road.png",
                  f"sim_gt/{n}_10_sky.png", f"sim_gt/{n}_10_obstacles.png", f"scenes/{n}.toml"]:
            assert (tr / f).is_file(), f
        gt = json.loads((tr / f"sim_gt/{n}_10.json").read_text())
        assert gt["type"] == marker["scenario_types"][i]
        assert set(gt["calib"]) == {"focal_px", "cx", "cy", "baseline_m", "height_m", "pitch_deg"}
        for o in gt["obstacles"]:
            assert {"id", "shape", "box", "position_world_m", "position_cam_m", "distance_m", "visible_pixels",
                    "truncated", "velocity_mps"} <= set(o)
        disp = cv2.imread(str(tr / f"disp_occ_0/{n}_10.png"), cv2.IMREAD_UNCHANGED)
        assert disp.shape == (180, 320) and disp.dtype == np.uint16
        max_gt = max(max_gt, disp.max() / 256.0)
    md = marker["max_disparity"]
    assert md % 16 == 0 and md - 16 <= max_gt < md
    # The host finds the set like the firmware: set "synthetic", the marker's search range, GT present.
    from fuzzyctl.dataset import discover

    for root in (out, tr, tmp_path):
        frames = discover(root)
        assert [f.name for f in frames] == ["000000", "000001", "000002"]
        assert all(f.set == "synthetic" and f.max_disparity == md and f.has_gt for f in frames)
    # The written scene reproduces its frame bit-identically.
    r = run(firmware_bin, "sim", "render", str(tr / "scenes" / "000001.toml"), "--out", str(tmp_path / "re"))
    assert r.returncode == 0, r.stderr
    for a, b in [("image_2/000001_10.png", "left.png"), ("image_3/000001_10.png", "right.png"),
                 ("disp_occ_0/000001_10.png", "disp_gt.png")]:
        assert np.array_equal(cv2.imread(str(tr / a), cv2.IMREAD_UNCHANGED),
                              cv2.imread(str(tmp_path / "re" / b), cv2.IMREAD_UNCHANGED)), a
    # Same seed -> same set; another seed -> another set.
    again = tmp_path / "again"
    assert run(firmware_bin, "sim", "generate", "--count", "1", "--seed", "11", "--out", str(again),
               "--width", "320", "--height", "180").returncode == 0
    assert (again / "training/image_2/000000_10.png").read_bytes() == (tr / "image_2/000000_10.png").read_bytes()
    other = tmp_path / "other"
    assert run(firmware_bin, "sim", "generate", "--count", "1", "--seed", "12", "--out", str(other),
               "--width", "320", "--height", "180").returncode == 0
    assert (other / "training/image_2/000000_10.png").read_bytes() != (tr / "image_2/000000_10.png").read_bytes()
    # eval discovers the set as "synthetic" with the marker's range and scores it.
    js = tmp_path / "eval.json"
    e = run(firmware_bin, "eval", "--dataset", str(out), "--threads", "2", "--json", str(js))
    assert e.returncode == 0, e.stderr
    assert f"D={md}" in e.stderr
    sets = json.loads(js.read_text())["sets"]
    assert "synthetic" in json.dumps(sets)


def test_generate_bad_options(firmware_bin, tmp_path):
    p = run(firmware_bin, "sim", "generate", "--count", "0", "--out", str(tmp_path / "x"))
    assert p.returncode == 2 and "--count" in p.stderr
