"""firmware/capture/oakd_bridge.py, the OAK-D bridge the `oakd` camera source runs: its stream
format (write/read round trip), its simulated twin (--fake), its device error paths against stub
`depthai` modules (no hardware here), and its calibration file."""
from __future__ import annotations

import importlib.util
import io
import os
import subprocess
import sys
import time
from pathlib import Path

import cv2
import pytest

ROOT = Path(__file__).resolve().parents[2]
BRIDGE = ROOT / "firmware" / "capture" / "oakd_bridge.py"


def load_bridge():
    spec = importlib.util.spec_from_file_location("oakd_bridge", BRIDGE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


bridge = load_bridge()


def run_bridge(*args, env_extra=None, timeout=30):
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    env.update(env_extra or {})
    return subprocess.run([sys.executable, str(BRIDGE), *args], capture_output=True, timeout=timeout, env=env)


def test_stream_round_trip():
    buf = io.BytesIO()
    bridge.write_hello(buf, {"device": "x", "width": 4, "height": 2})
    bridge.write_pair(buf, 4, 2, bytes(range(8)), bytes(range(8, 16)), 10, 12, 7)
    buf.seek(0)
    hello, pairs = bridge.read_stream(buf)
    assert hello == {"device": "x", "width": 4, "height": 2}
    (head, left, right), = list(pairs)
    assert head == {"width": 4, "height": 2, "channels": 1, "t_left_ns": 10, "t_right_ns": 12, "seq": 7}
    assert left == bytes(range(8)) and right == bytes(range(8, 16))
    with pytest.raises(bridge.BridgeError, match="expected 8"):
        bridge.write_pair(io.BytesIO(), 4, 2, b"123", b"123", 0, 0, 0)


def test_truncated_streams_are_errors():
    buf = io.BytesIO()
    bridge.write_hello(buf, {})
    bridge.write_pair(buf, 4, 2, bytes(8), bytes(8), 0, 0, 0)
    data = buf.getvalue()
    _, pairs = bridge.read_stream(io.BytesIO(data[:-3]))
    with pytest.raises(ValueError, match="inside a pair"):
        list(pairs)
    with pytest.raises(ValueError, match="not an OAK-D bridge stream"):
        bridge.read_stream(io.BytesIO(b"[depthai] warning\n"))


def test_fake_pairs_have_the_requested_disparity_and_increasing_times():
    p = run_bridge("--fake", "--fps", "0", "--width", "80", "--height", "30", "--fake-disparity", "9",
                   "--fake-count", "3", "--fake-drop-at", "2")
    assert p.returncode == 0, p.stderr
    hello, pairs = bridge.read_stream(io.BytesIO(p.stdout))
    assert hello["width"] == 80 and hello["f_px"] == 400.0 and hello["device"] == "fake"
    got = list(pairs)
    assert [h["seq"] for h, _, _ in got] == [0, 1, 3]  # one sequence number skipped at pair 2
    ts = [h["t_left_ns"] for h, _, _ in got]
    assert ts == sorted(ts) and len(set(ts)) == 3
    for h, left, right in got:
        for y in range(30):
            row_l, row_r = left[y * 80:(y + 1) * 80], right[y * 80:(y + 1) * 80]
            assert row_r[:71] == row_l[9:]  # right(x) = left(x + 9)
    assert got[0][1] != got[1][1]  # the texture moves between frames


def test_library_output_on_stdout_cannot_corrupt_the_stream(tmp_path):
    # A stub depthai that prints to stdout on import, as the real one logs warnings there: the
    # stream must still start with the hello (fd 1 points to stderr inside the bridge).
    (tmp_path / "depthai.py").write_text("print('[depthai] [warning] USB protocol not available')\n"
                                         "__version__ = '3.12.0'\n"
                                         "class Device:\n    @staticmethod\n    def getAllAvailableDevices():\n"
                                         "        return []\n")
    p = run_bridge(env_extra={"PYTHONPATH": str(tmp_path)})
    assert p.returncode == bridge.EXIT_DEVICE
    assert p.stdout == b""
    assert b"[depthai] [warning]" in p.stderr and b"no OAK device found" in p.stderr


@pytest.mark.parametrize("stub, code, needle", [
    ("raise ImportError('stub')\n", 3, b"depthai is not installed"),
    ("__version__ = '2.28.0'\n", 3, b"depthai 2.28.0 is too old"),
])
def test_depthai_missing_or_too_old(tmp_path, stub, code, needle):
    (tmp_path / "depthai.py").write_text(stub)
    p = run_bridge(env_extra={"PYTHONPATH": str(tmp_path)})
    assert p.returncode == code
    assert needle in p.stderr and p.stderr.startswith(b"oakd_bridge: ")


@pytest.mark.parametrize("args, needle", [
    (["--width", "8"], b"--width/--height 8x400 outside 16..4096"),
    (["--fps", "500"], b"--fps 500.0 outside (0, 240]"),
    (["--fake", "--width", "32", "--fake-disparity", "40"], b"--fake-disparity 40 outside 0..31"),
])
def test_bad_arguments_exit_2_naming_the_field(args, needle):
    p = run_bridge(*args)
    assert p.returncode == 2 and needle in p.stderr


def test_write_calib_is_read_back_by_opencv(tmp_path):
    path = tmp_path / "calib.yml"
    bridge.write_calib(str(path), {"f_px": 455.5, "baseline_m": 0.0751, "cx": 319.5, "cy": 199.5,
                                   "width": 640, "height": 400})
    fsr = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fsr.getNode("rectified").real() == 1
    assert fsr.getNode("f").real() == pytest.approx(455.5)
    assert fsr.getNode("B").real() == pytest.approx(0.0751)
    assert fsr.getNode("image_width").real() == 640
    with pytest.raises(bridge.BridgeError, match="no stereo calibration"):
        bridge.write_calib(str(path), {"f_px": None, "baseline_m": None})


def test_bridge_dies_with_its_parent(tmp_path):
    """A hung bridge (no more pairs, alive, sleeping: its small pairs fit the pipe) ends when the
    process that started it is killed."""
    pidfile = tmp_path / "pid"
    parent = subprocess.Popen([sys.executable, "-c", (
        "import subprocess, sys, time\n"
        f"p = subprocess.Popen([sys.executable, {str(BRIDGE)!r}, '--fake', '--fps', '0', '--width', '16', '--height', '16', '--fake-stall-after', '1'],"
        " stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)\n"
        f"open({str(pidfile)!r}, 'w').write(str(p.pid))\n"
        "time.sleep(60)\n")])
    try:
        for _ in range(100):
            if pidfile.exists() and pidfile.read_text():
                break
            time.sleep(0.05)
        child = int(pidfile.read_text())
        time.sleep(0.3)  # the bridge has started and stalls
        os.kill(child, 0)  # alive
        parent.kill()
        parent.wait()
        for _ in range(100):
            try:
                os.kill(child, 0)
            except ProcessLookupError:
                break
            # a zombie until init reaps it also counts as ended
            try:
                with open(f"/proc/{child}/stat") as f:
                    if f.read().split()[2] == "Z":
                        break
            except FileNotFoundError:
                break
            time.sleep(0.05)
        else:
            os.kill(child, 9)
            pytest.fail("the bridge outlived its parent")
    finally:
        if parent.poll() is None:
            parent.kill()
