#!/usr/bin/env python3
"""OAK-D bridge for the `oakd` camera source (docs/capture.md, "oakd").

The firmware is C++, and Luxonis ships depthai for C++ only as source (not packaged for Debian or
Raspberry Pi OS), but as binary wheels on PyPI for x86-64 and arm64. So `fuzzystereo run --source
oakd` starts this script with a Python that has depthai >= 3 (`pip install depthai`), and the script
streams the OAK-D's *rectified* left/right mono pairs (its on-device StereoDepth rectification, from
the factory calibration in the device EEPROM) to the firmware over its stdout pipe.

Stream (little-endian), documented in docs/formats.md "OAK-D bridge stream":
  hello   b"FSOAKD1\\n", then one JSON line: {"device", "depthai", "width", "height", "fps",
          "f_px", "baseline_m", "cx", "cy"}  (f_px/cx/cy of the rectified images, baseline in metres;
          null when unknown)
  pair    struct "<4sIIIqqQ": b"FSFR", width, height, channels (1), t_left_ns, t_right_ns (capture
          times on the host's CLOCK_MONOTONIC, ns), sequence number; then width*height*channels bytes left, the same right
Errors go to stderr as one line starting "oakd_bridge:" and the exit code says which:
  2 bad arguments, 3 depthai missing or too old, 4 no / wrong device, 5 device or stream failure.

`--fake` streams a synthetic random-dot pair with a known constant disparity and no depthai at all:
the simulated twin the tests use to exercise the firmware's pipe, framing and error paths.
`--write-calib FILE` writes the rectified pair's calibration (OpenCV YAML, "rectified: 1") that the
firmware reads as camera.calibration, then exits.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import struct
import sys
import time
from typing import BinaryIO, Iterator

HELLO_MAGIC = b"FSOAKD1\n"
PAIR_MAGIC = b"FSFR"
PAIR_HEADER = struct.Struct("<4sIIIqqQ")  # magic, width, height, channels, t_left_ns, t_right_ns, seq

EXIT_USAGE, EXIT_DEPTHAI, EXIT_DEVICE, EXIT_STREAM = 2, 3, 4, 5


class BridgeError(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def write_hello(out: BinaryIO, meta: dict) -> None:
    out.write(HELLO_MAGIC + json.dumps(meta, sort_keys=True).encode() + b"\n")
    out.flush()


def write_pair(out: BinaryIO, width: int, height: int, left: bytes, right: bytes,
               t_left_ns: int, t_right_ns: int, seq: int, channels: int = 1) -> None:
    n = width * height * channels
    if len(left) != n or len(right) != n:
        raise BridgeError(EXIT_STREAM, f"frame size {len(left)}/{len(right)} bytes, expected {n} ({width}x{height}x{channels})")
    out.write(PAIR_HEADER.pack(PAIR_MAGIC, width, height, channels, t_left_ns, t_right_ns, seq))
    out.write(left)
    out.write(right)
    out.flush()


def read_stream(inp: BinaryIO) -> tuple[dict, Iterator[tuple[dict, bytes, bytes]]]:
    """Reader of the stream above (for tests and host tools): (hello, iterator of (header, left, right))."""
    magic = inp.read(len(HELLO_MAGIC))
    if magic != HELLO_MAGIC:
        raise ValueError(f"not an OAK-D bridge stream (starts with {magic!r})")
    hello = json.loads(inp.readline())

    def pairs():
        while True:
            head = inp.read(PAIR_HEADER.size)
            if not head:
                return
            if len(head) != PAIR_HEADER.size:
                raise ValueError("stream ends inside a pair header")
            m, w, h, c, tl, tr, seq = PAIR_HEADER.unpack(head)
            if m != PAIR_MAGIC:
                raise ValueError(f"bad pair magic {m!r}")
            n = w * h * c
            left, right = inp.read(n), inp.read(n)
            if len(left) != n or len(right) != n:
                raise ValueError("stream ends inside a pair")
            yield {"width": w, "height": h, "channels": c, "t_left_ns": tl, "t_right_ns": tr, "seq": seq}, left, right

    return hello, pairs()


# ---- simulated twin ------------------------------------------------------------------------------

def run_fake(args, out: BinaryIO) -> None:
    """Random-dot pairs: right(x) = left(x + d) for every pixel with x + d < width, d = --fake-disparity;
    the texture scrolls by one pixel per frame so consecutive frames differ."""
    w, h, d = args.width, args.height, args.fake_disparity
    rng = random.Random(args.fake_seed)
    span = w + d + 4096
    rows = [rng.randbytes(span) for _ in range(h)]
    write_hello(out, {"device": "fake", "depthai": None, "width": w, "height": h, "fps": args.fps,
                      "f_px": 400.0, "baseline_m": 0.075, "cx": (w - 1) / 2.0, "cy": (h - 1) / 2.0})
    period = 1.0 / args.fps if args.fps > 0 else 0.0
    t_last = 0
    seq = 0
    while args.fake_count == 0 or seq < args.fake_count:
        if args.fake_stall_after and seq >= args.fake_stall_after:
            time.sleep(3600)  # a hung device: alive, silent
        off = seq % 4096
        left = b"".join(r[off:off + w] for r in rows)
        right = b"".join(r[off + d:off + d + w] for r in rows)
        t = t_last = max(time.monotonic_ns(), t_last + 1)  # capture time: now, strictly increasing
        write_pair(out, w, h, left, right, t, t + args.fake_skew_ns, seq + (seq >= args.fake_drop_at > 0))
        seq += 1
        if period:
            time.sleep(period)


# ---- the device ----------------------------------------------------------------------------------

def import_depthai():
    try:
        import depthai as dai  # noqa: PLC0415 (optional dependency, only on the robot)
    except ImportError as e:
        raise BridgeError(EXIT_DEPTHAI, f"depthai is not installed for {sys.executable} ({e}); install it with "
                          f"'{sys.executable} -m pip install \"depthai>=3\"' or set camera.oakd_python to a Python "
                          "that has it (docs/capture.md)") from None
    version = getattr(dai, "__version__", "0")
    try:
        major = int(str(version).split(".")[0])
    except ValueError:
        major = 0
    if major < 3:
        raise BridgeError(EXIT_DEPTHAI, f"depthai {version} is too old: the bridge uses the depthai v3 API "
                          f"('{sys.executable} -m pip install -U \"depthai>=3\"')")
    return dai


def open_device(dai, device_id: str):
    found = dai.Device.getAllAvailableDevices()
    ids = [getattr(d, "deviceId", "?") for d in found]
    if not found:
        raise BridgeError(EXIT_DEVICE, "no OAK device found (check the USB cable, use a USB3 port and the Luxonis udev "
                          "rule: SUBSYSTEM==\"usb\", ATTRS{idVendor}==\"03e7\", MODE=\"0666\"; docs/capture.md)")
    if device_id and device_id not in ids and device_id not in [getattr(d, "name", "") for d in found]:
        raise BridgeError(EXIT_DEVICE, f"OAK device '{device_id}' not found; available: {', '.join(ids)}")
    try:
        return dai.Device(dai.DeviceInfo(device_id)) if device_id else dai.Device()
    except RuntimeError as e:
        raise BridgeError(EXIT_DEVICE, f"cannot open the OAK device {device_id or ids[0]}: {e}") from None


def rectified_calibration(dai, device, width: int, height: int) -> dict:
    """f, cx, cy of the rectified pair at width x height and the baseline [m], from the device EEPROM.
    The StereoDepth node rectifies both images to the right camera's intrinsics (CAM_C), as depthai's
    own disparity-to-depth conversion assumes."""
    try:
        calib = device.readCalibration()
        k = calib.getCameraIntrinsics(dai.CameraBoardSocket.CAM_C, width, height)
        baseline_cm = calib.getBaselineDistance(dai.CameraBoardSocket.CAM_C, dai.CameraBoardSocket.CAM_B)
        return {"f_px": float(k[0][0]), "cx": float(k[0][2]), "cy": float(k[1][2]), "baseline_m": abs(baseline_cm) / 100.0}
    except RuntimeError as e:
        print(f"oakd_bridge: warning: no calibration read from the device ({e})", file=sys.stderr)
        return {"f_px": None, "cx": None, "cy": None, "baseline_m": None}


def write_calib(path: str, meta: dict) -> None:
    if meta.get("f_px") is None or meta.get("baseline_m") is None:
        raise BridgeError(EXIT_DEVICE, "the device holds no stereo calibration; calibrate it with Luxonis' tools first")
    with open(path, "w", encoding="utf-8") as f:
        f.write("%YAML:1.0\n---\n# OAK-D rectified pair (StereoDepth rectification), written by oakd_bridge.py\n")
        f.write(f"rectified: 1\nf: {meta['f_px']:.6f}\nB: {meta['baseline_m']:.6f}\ncx: {meta['cx']:.6f}\ncy: {meta['cy']:.6f}\n")
        f.write(f"image_width: {meta['width']}\nimage_height: {meta['height']}\n")


def run_device(args, out: BinaryIO) -> None:
    dai = import_depthai()
    device = open_device(dai, args.device)
    meta = {"device": device.getDeviceId(), "depthai": dai.__version__, "width": args.width, "height": args.height,
            "fps": args.fps}
    meta.update(rectified_calibration(dai, device, args.width, args.height))
    if args.write_calib:
        write_calib(args.write_calib, meta)
        print(f"oakd_bridge: wrote {args.write_calib} (f {meta['f_px']:.1f} px, B {meta['baseline_m']:.4f} m)", file=sys.stderr)
        return
    with dai.Pipeline(device) as pipeline:
        size = (args.width, args.height)
        left = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_B)
        right = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_C)
        stereo = pipeline.create(dai.node.StereoDepth)
        left.requestOutput(size, dai.ImgFrame.Type.GRAY8, fps=args.fps).link(stereo.left)
        right.requestOutput(size, dai.ImgFrame.Type.GRAY8, fps=args.fps).link(stereo.right)
        stereo.setRectification(True)
        stereo.setRectifyEdgeFillColor(0)
        q_left = stereo.rectifiedLeft.createOutputQueue(maxSize=4, blocking=False)
        q_right = stereo.rectifiedRight.createOutputQueue(maxSize=4, blocking=False)
        pipeline.start()
        write_hello(out, meta)
        pending_left: dict[int, object] = {}
        while pipeline.isRunning():
            # The rectified outputs of one StereoDepth input pair carry the same sequence number.
            fl = q_left.get()
            pending_left[fl.getSequenceNum()] = fl
            fr = q_right.get()
            seq = fr.getSequenceNum()
            fl = pending_left.pop(seq, None)
            for s in [s for s in pending_left if s < seq]:
                del pending_left[s]  # a left frame whose partner was dropped
            if fl is None:
                continue
            w, h = fl.getWidth(), fl.getHeight()
            if (w, h) != (fr.getWidth(), fr.getHeight()):
                raise BridgeError(EXIT_STREAM, f"rectified left {w}x{h} and right {fr.getWidth()}x{fr.getHeight()} differ")
            # getTimestamp(): the capture time on the host's steady clock (CLOCK_MONOTONIC), which
            # depthai keeps synchronised to the device clock.
            tl = int(fl.getTimestamp().total_seconds() * 1e9)
            tr = int(fr.getTimestamp().total_seconds() * 1e9)
            write_pair(out, w, h, fl.getCvFrame().tobytes(), fr.getCvFrame().tobytes(), tl, tr, seq)


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default="", help="device id (MXID) or name; empty = the first found")
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=400)
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--write-calib", default="", help="write the rectified calibration YAML here and exit")
    p.add_argument("--fake", action="store_true", help="synthetic random-dot pairs, no depthai (tests)")
    p.add_argument("--fake-disparity", type=int, default=8)
    p.add_argument("--fake-count", type=int, default=0, help="pairs to send, then exit (0 = endless)")
    p.add_argument("--fake-stall-after", type=int, default=0, help="stop sending after this many pairs, stay alive")
    p.add_argument("--fake-drop-at", type=int, default=0, help="skip one sequence number at this pair")
    p.add_argument("--fake-skew-ns", type=int, default=0, help="t_right - t_left")
    p.add_argument("--fake-seed", type=int, default=1)
    args = p.parse_args(argv)
    if not (16 <= args.width <= 4096 and 16 <= args.height <= 4096):
        p.error(f"--width/--height {args.width}x{args.height} outside 16..4096")
    if not (0 < args.fps <= 240) and not (args.fake and args.fps == 0):
        p.error(f"--fps {args.fps} outside (0, 240]")
    if args.fake_disparity < 0 or args.fake_disparity >= args.width:
        p.error(f"--fake-disparity {args.fake_disparity} outside 0..{args.width - 1}")
    return args


def private_stdout() -> BinaryIO:
    """The stream goes to a private copy of fd 1; fd 1 itself then points to stderr, so that anything a
    library prints (depthai logs warnings to stdout) cannot corrupt the stream."""
    sys.stdout.flush()
    fd = os.dup(1)
    os.dup2(2, 1)
    return os.fdopen(fd, "wb", buffering=1 << 20)


def die_with_parent() -> None:
    """Linux: SIGTERM this process when the firmware dies (even by SIGKILL), so a bridge blocked in a
    device read does not outlive it. Best effort: other systems keep the EPIPE exit only."""
    try:
        import ctypes  # noqa: PLC0415
        import signal  # noqa: PLC0415
        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):
        pass


def main(argv=None) -> int:
    args = parse_args(argv)
    die_with_parent()
    out = private_stdout()
    try:
        if args.fake:
            run_fake(args, out)
        else:
            run_device(args, out)
    except BridgeError as e:
        print(f"oakd_bridge: {e}", file=sys.stderr)
        return e.code
    except BrokenPipeError:
        # The firmware closed the pipe (stop()): a normal end. Drop what is buffered without writing it.
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), out.fileno())
        except OSError:
            pass
        return 0
    except KeyboardInterrupt:
        return 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
