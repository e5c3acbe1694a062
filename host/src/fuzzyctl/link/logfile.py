"""Device log files (docs/protocol.md "Log files"): header with the layout hash, then records
``length:u32 | crc32c:u32 | t_ms:u32 | msg_id:u8 | payload``. The parser verifies every record,
stops at the first incomplete one (a file cut off mid-record stays readable up to there) and
reports corruption instead of raising.
"""

from __future__ import annotations

import csv
import io
import json
import struct
from dataclasses import dataclass, field

from .framing import crc32c
from .schema import CodecError, Schema

MAGIC = b"FSLOG\x00\x00\x01"
HEADER = 16


@dataclass
class ParsedLog:
    layout: bytes = b""
    records: list[tuple[int, str, dict]] = field(default_factory=list)
    ok: bool = True
    note: str = ""
    good_bytes: int = 0


def parse_log(data: bytes, schema: Schema) -> ParsedLog:
    p = ParsedLog()
    if len(data) < HEADER or data[:8] != MAGIC:
        p.ok, p.note = False, "not a fuzzystereo log (bad header)"
        return p
    p.layout = data[8:16]
    if p.layout != schema.hash:
        p.ok, p.note = False, f"log layout {p.layout.hex()} differs from this fuzzyctl's {schema.hash.hex()}"
        return p
    pos = HEADER
    while len(data) - pos >= 8:
        ln, crc = struct.unpack_from("<II", data, pos)
        if ln < 5 or len(data) - pos - 8 < ln:
            p.note = f"incomplete record at byte {pos} (file cut off): {len(p.records)} whole records read"
            break
        body = data[pos + 8:pos + 8 + ln]
        if crc32c(body) != crc:
            p.ok, p.note = False, f"corrupt record at byte {pos} (CRC mismatch); {len(p.records)} records before it"
            break
        t_ms, msg_id = struct.unpack_from("<IB", body)
        try:
            name, values = schema.decode(msg_id, body[5:])
        except CodecError as exc:
            p.ok, p.note = False, f"undecodable record at byte {pos}: {exc}"
            break
        p.records.append((t_ms, name, values))
        pos += 8 + ln
    else:
        if len(data) != pos:
            p.note = f"incomplete record at byte {pos} (file cut off): {len(p.records)} whole records read"
    p.good_bytes = pos
    return p


def _flat(values: dict) -> dict:
    row = {}
    for k, v in values.items():
        if isinstance(v, list):
            row[k] = json.dumps(v)
        elif isinstance(v, bytes):
            row[k] = v.hex()
        else:
            row[k] = v
    return row


def to_json(p: ParsedLog) -> str:
    return json.dumps([{"t_ms": t, "message": n, **_flat(v)} for t, n, v in p.records], indent=1)


def to_csv(p: ParsedLog) -> str:
    rows = [{"t_ms": t, "message": n, **_flat(v)} for t, n, v in p.records]
    buf = io.StringIO()
    if rows:
        cols = list(dict.fromkeys(k for r in rows for k in r))
        w = csv.DictWriter(buf, fieldnames=cols)
        w.writeheader()
        w.writerows(rows)
    return buf.getvalue()
