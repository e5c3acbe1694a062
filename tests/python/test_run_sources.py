"""`fuzzystereo run` with its camera and motor backends: bad input is one line and exit 2, the
real-hardware backends fail with a message naming what they looked for, a recorded run turns into
an HTML report, and a dataset replays through the whole loop."""

from __future__ import annotations

import json
import subprocess

import pytest

pytestmark = pytest.mark.firmware


def run(binary, *args, timeout=120):
    return subprocess.run([str(binary), *args], capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--source", "sim:/nonexistent/scene.toml"], "/nonexistent/scene.toml"),
        (["--source", "sim:SCENE", "--goal", "3;4"], "--goal '3;4' is not valid"),
        (["--source", "sim:SCENE", "--motors", "pwm"], "--motors 'pwm' is not valid"),
        (["--source", "replay:/nonexistent/dir", "--goal", "1,0"], "/nonexistent/dir"),
        (["--source", "uvc:/dev/video99", "--goal", "1,0"], "/dev/video99"),
        (["--source", "oakd", "--goal", "1,0", "--config", "OAKD_NO_PYTHON"], "camera.oakd_python"),
        (["--source", "sim:SCENE", "--link", "pty"], "--state-dir"),
    ],
)
def test_bad_run_input_is_one_line_exit_2(firmware_bin, common_dir, tmp_path, args, needle):
    scene = str(common_dir / "sim" / "scenes" / "demo.toml")
    args = [a.replace("SCENE", scene) for a in args]
    if "OAKD_NO_PYTHON" in args:
        cfg = tmp_path / "oakd.toml"
        cfg.write_text('[camera]\noakd_python = "/nonexistent/python3"\n')
        args = [str(cfg) if a == "OAKD_NO_PYTHON" else a for a in args]
    p = run(firmware_bin, "run", *args, "--max-frames", "1", "--quiet")
    assert p.returncode == 2, p.stdout + p.stderr
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and needle in lines[0], p.stderr


def test_gpiod_motors_without_hardware_name_the_chip(firmware_bin, common_dir, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[motors]\ngpio_chip = "gpiochip77"\n')
    p = run(firmware_bin, "run", "--source", f"sim:{common_dir / 'sim' / 'scenes' / 'demo.toml'}", "--motors", "gpiod",
            "--config", str(cfg), "--max-frames", "1", "--quiet")
    assert p.returncode == 2, p.stdout + p.stderr
    assert "gpiochip77" in p.stderr


def test_recorded_run_makes_a_report(firmware_bin, common_dir, tmp_path):
    rec = tmp_path / "rec"
    cfg = tmp_path / "c.toml"  # snapshots whatever the test machine's free space ([record] min_free_mb)
    cfg.write_text("[record]\nmin_free_mb = 0.0\nmin_free_log_mb = 0.0\n")
    p = run(firmware_bin, "run", "--source", f"sim:{common_dir / 'sim' / 'scenes' / 'demo.toml'}", "--max-frames", "6",
            "--snapshot-every", "5", "--record", str(rec), "--quiet", "--json", str(tmp_path / "r.json"), "--config", str(cfg))
    assert p.returncode == 0, p.stderr
    frames = [json.loads(ln) for ln in (rec / "frames.jsonl").read_text().splitlines()]
    assert [f["frame"] for f in frames] == list(range(6))
    assert all({"pose", "true_pose", "cmd", "wheels", "detections", "tracks", "stage_ms"} <= set(f) for f in frames)
    assert frames[-1]["true_pose"][0] > frames[0]["true_pose"][0]  # it drives towards the goal (+x)
    # true_pose is the simulated robot's pose when the frame was taken, as `pose` (odometry from the
    # simulated wheels, exact to < 1 mm here); before session 26 it was logged after the actuation,
    # one control period later (0.24 rad of the look-around turn off the frame's yaw).
    for f in frames:
        assert all(abs(a - b) < 0.005 for a, b in zip(f["pose"], f["true_pose"])), (f["frame"], f["pose"], f["true_pose"])
    assert any(f["detections"] for f in frames)  # the crate 2.5 m ahead is seen
    assert (rec / "frames" / "000000_overlay.png").is_file() and (rec / "frames" / "000005_disp.png").is_file()
    result = json.loads((tmp_path / "r.json").read_text())
    assert result["status"] == "frames" and result["frames"] == 6 and not result["collided"]
    from fuzzyctl.runreport import write_report

    html = write_report(rec, tmp_path / "report.html").read_text()
    assert "Trajectory" in html and html.count("data:image/png;base64,") >= 4


def test_dataset_replay_through_the_loop(firmware_bin, datasets_root):
    kitti = datasets_root / "kitti2015"
    if not kitti.is_dir():
        pytest.skip(f"{kitti} not found (FUZZYSTEREO_DATASETS)")
    p = run(firmware_bin, "run", "--source", f"replay:{kitti}", "--goal", "5,0", "--max-frames", "3", timeout=300)
    assert p.returncode == 0, p.stderr
    assert "status end_of_stream" in p.stdout and "frames 1" in p.stdout
    assert "frame    0" in p.stderr and "obst=" in p.stderr


def test_ground_seen_ahead_without_a_camera_height_says_it_is_off(firmware_bin, datasets_root, tmp_path):
    # A KITTI replay carries focal length and baseline but no mounting height: the ground band cannot
    # be placed, so the stop cannot act; the user is told once, at start-up.
    kitti = datasets_root / "kitti2015"
    if not kitti.is_dir():
        pytest.skip(f"{kitti} not found (FUZZYSTEREO_DATASETS)")
    cfg = tmp_path / "g.toml"
    cfg.write_text("[robot]\nground_ahead_min_pct = 40\n")
    p = run(firmware_bin, "run", "--source", f"replay:{kitti}", "--goal", "5,0", "--max-frames", "1", "--quiet",
            "--config", str(cfg), timeout=300)
    assert p.returncode == 0, p.stderr
    warn = [ln for ln in p.stderr.splitlines() if "ground_ahead_min_pct" in ln]
    assert len(warn) == 1 and "no camera height" in warn[0] and "stays off" in warn[0], p.stderr
    p = run(firmware_bin, "run", "--source", f"replay:{kitti}", "--goal", "5,0", "--max-frames", "1", "--quiet",
            timeout=300)
    assert "ground_ahead_min_pct" not in p.stderr  # off by default: nothing to say
