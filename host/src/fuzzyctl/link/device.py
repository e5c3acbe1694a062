"""One plain function per device operation, taking a :class:`~fuzzyctl.link.transport.Link`
(shared by the CLI, the stress scripts and the tests). Flows: docs/protocol.md.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .framing import crc32c
from .logfile import parse_log
from .transport import Link, LinkError

Progress = Callable[[int, int], None] | None


def info(link: Link) -> dict:
    return link.hello()


# ---- config ---------------------------------------------------------------------------------


def config_pull(link: Link) -> bytes:
    """The device's active config text, checked against the CRC the device reports."""
    first = link.request("config_get", {"offset": 0, "length": min(link.chunk, 1000)})
    total, crc = first["total"], first["crc"]
    data = bytearray(first["data"])
    while len(data) < total:
        part = link.request("config_get", {"offset": len(data), "length": min(link.chunk, 1000)})
        if part["crc"] != crc or part["total"] != total:
            raise LinkError("the device's config changed during the pull; pull again")
        if not part["data"]:
            raise LinkError(f"device sent no data at offset {len(data)} of {total}")
        data += part["data"]
    if crc32c(bytes(data)) != crc:
        raise LinkError(f"config pull: CRC mismatch (device {crc:08x}, received {crc32c(bytes(data)):08x})")
    return bytes(data)


@dataclass
class PushResult:
    crc: int
    config_id: int
    bytes: int


def config_push(link: Link, text: bytes, progress: Progress = None) -> PushResult:
    """begin, chunks by offset (stop-and-wait: each chunk must follow the bytes already received),
    commit with the host's CRC; the device verifies the CRC, validates and writes atomically."""
    link.request("config_begin", {"total": len(text)})
    off = 0
    while off < len(text):
        n = min(link.chunk, len(text) - off)
        link.request("config_chunk", {"offset": off, "data": text[off:off + n]})
        off += n
        if progress:
            progress(off, len(text))
    crc = crc32c(text)
    r = link.request("config_commit", {"crc": crc})
    if r["crc"] != crc:
        raise LinkError(f"config push: device CRC {r['crc']:08x} differs from the host's {crc:08x}")
    return PushResult(r["crc"], r["config_id"], len(text))


# ---- bulk reads -------------------------------------------------------------------------------


def read_blob(link: Link, request: str, base: dict, start: int, end: int, window: int = 4,
              progress: Progress = None, sink: Callable[[int, bytes], None] | None = None) -> bytes:
    """Bytes [start, end) of a device file via ``request`` (log_read, snapshot_read), with several
    requests in flight; chunks grow/shrink with the error rate; every answer is checked."""
    out = bytearray()
    done: dict[int, bytes] = {}
    pos = start
    while pos < end:
        reqs, offsets = [], []
        off = pos
        # plan a batch at the current chunk size (it adapts between batches)
        while off < end and len(reqs) < 64:
            n = min(link.chunk, end - off)
            reqs.append((request, {**base, "offset": off, "length": n}))
            offsets.append((off, n))
            off += n

        def on_answer(i: int, name: str, v: dict) -> None:
            o, n = offsets[i]
            if v["offset"] != o or len(v["data"]) != n:
                raise LinkError(f"{request}: asked for {n} bytes at {o}, got {len(v['data'])} at {v['offset']} "
                                "(did the file shrink?)")
            done[o] = v["data"]

        link.exchange(reqs, window=window, on_answer=on_answer)
        while pos in done:
            chunk = done.pop(pos)
            if sink:
                sink(pos, chunk)
            else:
                out += chunk
            pos += len(chunk)
            if progress:
                progress(pos - start, end - start)
    return bytes(out)


# ---- logs -------------------------------------------------------------------------------------


def log_list(link: Link) -> list[dict]:
    return link.request("log_list")["files"]


@dataclass
class PulledLog:
    id: int
    path: Path
    size: int
    new_bytes: int
    records: int
    good: bool
    note: str


def log_pull(link: Link, out_dir: Path, ids: list[int] | None = None, window: int = 8,
             progress: Callable[[int, int, int], None] | None = None) -> list[PulledLog]:
    """Copies device logs to OUT_DIR/log_<id>.fsl, resuming after the bytes already there
    (a previous, interrupted pull), then verifies every record of each file."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = log_list(link)
    if ids is not None:
        files = [f for f in files if f["id"] in ids]
    result = []
    for f in files:
        path = out_dir / f"log_{f['id']:06d}.fsl"
        have = path.stat().st_size if path.exists() else 0
        if have > f["size"]:
            have = 0  # not the same file (device state was reset): pull again
            path.unlink()
        with open(path, "ab") as fh:
            def sink(_off: int, data: bytes, fh=fh) -> None:
                fh.write(data)
                fh.flush()

            read_blob(link, "log_read", {"id": f["id"]}, have, f["size"], window=window, sink=sink,
                      progress=(lambda d, t, i=f["id"]: progress(i, d, t)) if progress else None)
            fh.flush()
            os.fsync(fh.fileno())
        parsed = parse_log(path.read_bytes(), link.schema)
        result.append(PulledLog(f["id"], path, f["size"], f["size"] - have, len(parsed.records),
                                parsed.ok, parsed.note))
    return result


# ---- telemetry, snapshot, control ---------------------------------------------------------------


def telemetry(link: Link) -> dict:
    return link.request("telemetry_get")


def snapshot(link: Link, out_dir: Path, progress: Progress = None) -> list[Path]:
    """Captures a snapshot on the device and writes its files (dump format) to OUT_DIR."""
    snap = link.request("snapshot_begin")
    out_dir.mkdir(parents=True, exist_ok=True)
    total = sum(f["size"] for f in snap["files"])
    done = 0
    paths = []
    for i, f in enumerate(snap["files"]):
        name = Path(f["name"]).name
        if name != f["name"] or name in ("", ".", ".."):
            raise LinkError(f"device sent an unsafe snapshot file name {f['name']!r}")
        data = read_blob(link, "snapshot_read", {"snap_id": snap["snap_id"], "file": i}, 0, f["size"],
                         progress=(lambda d, t, base=done: progress(base + d, total)) if progress else None)
        if crc32c(data) != f["crc"]:
            raise LinkError(f"snapshot file {name}: CRC mismatch (device {f['crc']:08x}, received {crc32c(data):08x})")
        done += len(data)
        (out_dir / name).write_bytes(data)
        paths.append(out_dir / name)
    return paths


CONTROL = {"estop": "ESTOP", "pause": "PAUSE", "resume": "RESUME", "clear-estop": "CLEAR_ESTOP"}


def control(link: Link, action: str) -> None:
    link.request("control", {"action": link.schema.enums["control_action"][CONTROL[action]]})


def info_json(i: dict) -> str:
    return json.dumps({k: (v.hex() if isinstance(v, bytes) else v) for k, v in i.items()}, indent=2)
