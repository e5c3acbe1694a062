"""The fuzzystereo program cross-built for aarch64 (preset aarch64, `make build-aarch64`) against the native
build, output for output, run under qemu-aarch64 (`make test-aarch64`, part of `make test`; docs/algorithm.md 7).

The unit tests' golden hashes (tests/golden/) hold the libraries to the same bits on both platforms; this
holds the whole program to it — its OpenCV image I/O, rectification-free capture from the simulator, the
robot loop in fs_app — on three commands:

1. ``sim render`` of a scene: every image decoded, the ground-truth JSON;
2. ``match --dump`` and ``detect --dump`` on the rendered pair: every output file (PNG decoded, ``.npy``
   loaded, JSON parsed);
3. ``run --source sim:...`` for ``--frames`` frames with ``--record``: every frame's decisions
   (``frames.jsonl``: detections, tracks, plan, motor commands, true pose) and ``run.json``.

Timings (``stage_ms``, ``timing_ms``, ``fps_wall``, ``*_ms`` figures) are left out; everything else must be
equal, floats to the last bit (both builds write the shortest round-trip decimal). Exit 0 when equal, 1 with
one line per difference, 2 on a usage error.
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

TIMING_KEYS = {"stage_ms", "timing_ms", "fps_wall", "ms", "omp_wait_policy"}


def strip_timings(x):
    if isinstance(x, dict):
        return {k: strip_timings(v) for k, v in x.items()
                if k not in TIMING_KEYS and not k.endswith("_ms") and not k.startswith("ms_")}
    if isinstance(x, list):
        return [strip_timings(v) for v in x]
    return x


def load(path: Path):
    suffix = path.suffix.lower()
    if suffix in (".png", ".pgm", ".ppm", ".jpg"):
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise ValueError(f"{path}: unreadable image")
        return img
    if suffix == ".npy":
        return np.load(path, allow_pickle=False)
    if suffix == ".json":
        return strip_timings(json.loads(path.read_text()))
    if suffix == ".jsonl":
        return [strip_timings(json.loads(line)) for line in path.read_text().splitlines() if line.strip()]
    return path.read_bytes()


def equal(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape == b.shape and \
            a.dtype == b.dtype and bool(np.array_equal(a, b))
    return a == b


def describe(a, b) -> str:
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape == b.shape:
        diff = a != b
        return f"{int(diff.sum())} of {diff.size} values differ"
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{len(a)} against {len(b)} entries"
        first = next(i for i, (x, y) in enumerate(zip(a, b)) if x != y)
        return f"first difference at entry {first}"
    return "contents differ"


def compare_dirs(native: Path, arm: Path, what: str, skip=("config.toml",)) -> list[str]:
    problems = []
    files = sorted(p.relative_to(native) for p in native.rglob("*") if p.is_file())
    arm_files = sorted(p.relative_to(arm) for p in arm.rglob("*") if p.is_file())
    if files != arm_files:
        only_n = sorted(set(files) - set(arm_files))
        only_a = sorted(set(arm_files) - set(files))
        problems.append(f"{what}: files differ (native only {only_n[:5]}, aarch64 only {only_a[:5]})")
    for rel in files:
        if rel.name in skip or not (arm / rel).is_file():
            continue
        a, b = load(native / rel), load(arm / rel)
        if not equal(a, b):
            problems.append(f"{what}: {rel}: {describe(a, b)}")
    return problems


def run(cmd: list[str], log: Path) -> None:
    with log.open("w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        raise RuntimeError(f"exit {r.returncode}: {shlex.join(cmd)} (log: {log})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--native", required=True, help="native fuzzystereo binary")
    ap.add_argument("--arm64", required=True, help="aarch64 command: emulator and binary, as one shell-quoted string")
    ap.add_argument("--work", required=True, type=Path, help="scratch directory (emptied)")
    ap.add_argument("--scene", default="common/sim/scenes/example.toml")
    ap.add_argument("--run-scene", default="common/sim/scenes/demo.toml")
    ap.add_argument("--frames", type=int, default=40)
    a = ap.parse_args()
    builds = {"native": [a.native], "aarch64": shlex.split(a.arm64)}
    work = a.work
    shutil.rmtree(work, ignore_errors=True)
    problems: list[str] = []
    for name, exe in builds.items():
        d = work / name
        d.mkdir(parents=True)
        print(f"compare_program: {name}: sim render, match, detect, run ({a.frames} frames)", flush=True)
        run(exe + ["sim", "render", a.scene, "--out", str(d / "scene")], d / "render.log")
        # Both builds match the same (native) pair, so a rendering difference cannot hide a matcher one.
        scene = work / "native" / "scene"
        run(exe + ["match", "--left", str(scene / "left.png"), "--right", str(scene / "right.png"),
                   "--out", str(d / "match"), "--dump"], d / "match.log")
        run(exe + ["detect", "--left", str(scene / "left.png"), "--right", str(scene / "right.png"),
                   "--calib", str(scene / "obstacles.json"), "--out", str(d / "detect"), "--dump"], d / "detect.log")
        run(exe + ["run", "--source", f"sim:{a.run_scene}", "--motors", "sim", "--quiet",
                   "--max-frames", str(a.frames), "--record", str(d / "run"), "--snapshot-every", "0"], d / "run.log")
    for what in ("scene", "match", "detect", "run"):
        problems += compare_dirs(work / "native" / what, work / "aarch64" / what, what)
    for p in problems:
        print(f"compare_program: DIFFERENT {p}")
    if problems:
        return 1
    n = sum(1 for what in ("scene", "match", "detect", "run") for f in (work / "native" / what).rglob("*") if f.is_file())
    print(f"compare_program: the aarch64 program's outputs equal the native ones ({n} files; timings left out)")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except RuntimeError as e:
        print(f"compare_program: {e}", file=sys.stderr)
        sys.exit(1)
