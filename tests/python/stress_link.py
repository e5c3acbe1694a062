#!/usr/bin/env python3
"""Link stress runs against the real firmware (`fuzzystereo serve --link pty`); the lead runs
them, pytest runs small versions (tests/python/test_link_faults.py).

  faults     N transfers (config push + pull-back, log pull) through the fault relay at the given
             byte drop/corrupt rates; every transfer either verifies against the device's own files
             or fails with a LinkError; a transfer that reports success with wrong data is a SILENT
             CORRUPTION (must be 0).
  powercut   N config pushes killed (SIGKILL) at random points; after each restart the device must
             run the old or the new config, never another / invalid one.
  throughput log pull through the relay throttled to each baud rate; payload bytes/s vs baud/10.

usage: stress_link.py faults [--transfers 1000] [--drop 0.01] [--corrupt 0.01]
       stress_link.py powercut [--runs 200]
       stress_link.py throughput [--bauds 115200 921600] [--kib 64]
(env FUZZYSTEREO_BIN = firmware binary, default build/default/fuzzystereo)
"""

from __future__ import annotations

import argparse
import os
import random
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(REPO / "host" / "src"))
sys.path.insert(0, str(HERE))

from fuzzyctl.link.device import config_pull, config_push, log_list, log_pull  # noqa: E402
from fuzzyctl.link.framing import crc32c  # noqa: E402
from fuzzyctl.link.relay import FaultRelay  # noqa: E402
from fuzzyctl.link.transport import Link, LinkError  # noqa: E402
from linkdev import Device  # noqa: E402


def binary() -> Path:
    return Path(os.environ.get("FUZZYSTEREO_BIN", REPO / "build" / "default" / "fuzzystereo"))


def random_config(rng: random.Random) -> bytes:
    w = rng.choice([3, 5, 7, 9, 11])
    tau = rng.choice([0.25, 0.5, 0.75, 1.0])
    pad = "# " + "".join(rng.choice("abcdefghij \x7e") for _ in range(rng.randrange(0, 600))) + "\n"
    return f"{pad}[esr]\nwindow = {w}\ntau = {tau}\n".encode()


def run_faults(transfers: int, drop: float, corrupt: float, seed: int = 1, work: Path | None = None,
               log=print) -> dict:
    rng = random.Random(seed)
    work = Path(work or tempfile.mkdtemp(prefix="fs_link_faults_"))
    res = {"ok": 0, "clean_error": 0, "silent_corruption": 0, "errors": {}}
    with Device(binary(), work / "state", ["--rate", "50", "--fill-log-kib", "3"]) as dev:
        time.sleep(1.2)
        relay = FaultRelay(dev.pty, drop=drop, corrupt=corrupt, seed=seed).start()
        try:
            link = Link(relay.host_path, timeout=0.15, retries=30)
            link.chunk_max = 256
            t0 = time.monotonic()
            for i in range(transfers):
                kind = "config" if i % 2 == 0 else "log"
                try:
                    if link.info is None or i % 50 == 0:
                        link.hello()
                    if kind == "config":
                        text = random_config(rng)
                        r = config_push(link, text)
                        on_disk = (dev.state_dir / "config" / "active.toml").read_bytes()
                        back = config_pull(link)
                        good = on_disk == text and back == text and r.config_id == crc32c(text)
                    else:
                        out = work / "pulled" / str(i)
                        files = log_list(link)
                        pulled = log_pull(link, out, [files[0]["id"]])  # the 3 KiB fill file: fixed size
                        p = pulled[0]
                        dev_bytes = (dev.state_dir / "logs" / p.path.name).read_bytes()
                        mine = p.path.read_bytes()
                        good = p.good and dev_bytes[: len(mine)] == mine and len(mine) == p.size
                    if good:
                        res["ok"] += 1
                    else:
                        res["silent_corruption"] += 1
                        log(f"transfer {i} ({kind}): SILENT CORRUPTION")
                except LinkError as exc:
                    res["clean_error"] += 1
                    key = type(exc).__name__
                    res["errors"][key] = res["errors"].get(key, 0) + 1
                    link.info = None
                if (i + 1) % 100 == 0:
                    log(f"  {i + 1}/{transfers} transfers, {res}, {time.monotonic() - t0:.0f} s")
            res["seconds"] = time.monotonic() - t0
            res["link_stats"] = dict(link.stats)
            link.close()
        finally:
            relay.stop()
        res["relay"] = {k: vars(v) for k, v in relay.stats.items()}
    return res


def run_powercut(runs: int, seed: int = 2, work: Path | None = None, log=print) -> dict:
    from fuzzyctl.config import parse_config

    rng = random.Random(seed)
    work = Path(work or tempfile.mkdtemp(prefix="fs_link_powercut_"))
    state = work / "state"
    res = {"runs": runs, "old": 0, "new": 0, "bad": 0, "killed_mid_push": 0, "push_completed": 0}
    known = {crc32c(random_config(random.Random(-1)))}
    prev = None
    for i in range(runs):
        dev = Device(binary(), state).start()
        try:
            link = Link(dev.pty, timeout=0.5, retries=3)
            info = link.hello()
            active = state / "config" / "active.toml"
            text_now = active.read_bytes() if active.exists() else None
            ok = info["config_source"] in ("active", "defaults") and (prev is None or info["config_id"] in prev)
            if text_now is not None:
                parse_config(text_now.decode(), "active.toml")  # raises if invalid
                ok = ok and crc32c(text_now) == info["config_id"]
            if not ok:
                res["bad"] += 1
                log(f"run {i}: device came up with config {info['config_id']:08x} from {info['config_source']}, "
                    f"expected one of {[f'{c:08x}' for c in (prev or [])]}")
            elif prev is not None:
                res["old" if info["config_id"] == prev[0] else "new"] += 1
            new = random_config(rng)
            link.chunk_max = link.chunk = 32  # many exchanges: the kill lands anywhere in the push
            old_id = info["config_id"]
            prev = [old_id, crc32c(new)]
            timer = threading.Timer(rng.uniform(0.0, 0.03), dev.kill)
            timer.start()
            try:
                config_push(link, new)
                res["push_completed"] += 1
            except LinkError:
                res["killed_mid_push"] += 1
            timer.join()
            link.close()
        finally:
            dev.kill()
    del known
    return res


def run_throughput(baud: int, kib: int, work: Path | None = None, window: int = 8) -> dict:
    work = Path(work or tempfile.mkdtemp(prefix="fs_link_tput_"))
    with Device(binary(), work / "state", ["--fill-log-kib", str(kib)]) as dev:
        relay = FaultRelay(dev.pty, baud=baud).start()
        try:
            with Link(relay.host_path, baud=baud, timeout=2.0) as link:
                link.hello()
                files = log_list(link)
                big = max(files, key=lambda f: f["size"])
                t0 = time.monotonic()
                p = log_pull(link, work / "out", [big["id"]], window=window)[0]
                dt = time.monotonic() - t0
        finally:
            relay.stop()
    rate = p.size / dt
    return {"baud": baud, "bytes": p.size, "seconds": dt, "payload_Bps": rate, "link_Bps": baud / 10,
            "efficiency": rate / (baud / 10), "verified": p.good}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("faults")
    f.add_argument("--transfers", type=int, default=1000)
    f.add_argument("--drop", type=float, default=0.01)
    f.add_argument("--corrupt", type=float, default=0.01)
    f.add_argument("--seed", type=int, default=1)
    p = sub.add_parser("powercut")
    p.add_argument("--runs", type=int, default=200)
    p.add_argument("--seed", type=int, default=2)
    t = sub.add_parser("throughput")
    t.add_argument("--bauds", type=int, nargs="+", default=[115200, 921600])
    t.add_argument("--kib", type=int, default=64)
    a = ap.parse_args()
    if a.cmd == "faults":
        r = run_faults(a.transfers, a.drop, a.corrupt, a.seed)
        print(r)
        return 1 if r["silent_corruption"] else 0
    if a.cmd == "powercut":
        r = run_powercut(a.runs, a.seed)
        print(r)
        return 1 if r["bad"] else 0
    worst = 1.0
    for b in a.bauds:
        r = run_throughput(b, a.kib)
        print(f"{b} baud: {r['bytes']} B in {r['seconds']:.2f} s = {r['payload_Bps']:.0f} B/s of {r['link_Bps']:.0f} B/s "
              f"({100 * r['efficiency']:.1f} %), verified={r['verified']}")
        worst = min(worst, r["efficiency"])
    return 0 if worst >= 0.8 else 1


if __name__ == "__main__":
    sys.exit(main())
