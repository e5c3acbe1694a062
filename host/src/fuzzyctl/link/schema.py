"""The link protocol schema (common/protocol/protocol.toml), driving the Python codec at run time.

The C++ codec is generated from the same file (common/protocol/gen_cpp.py); :func:`layout_hash`
is the same function as the generator's ``schema_hash`` (checked against
common/protocol/vectors.toml by both languages' tests). Messages are plain dicts of field values;
:meth:`Schema.encode` / :meth:`Schema.decode` check lengths and the valid ranges of the schema and
raise :class:`CodecError` for anything malformed.
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..paths import common_dir

_FMT = {"u8": "<B", "u16": "<H", "u32": "<I", "i32": "<i", "f32": "<f"}


class CodecError(ValueError):
    """A payload that does not match the schema (short, too long, out of range, unknown id)."""


def _strip_docs(node):
    if isinstance(node, dict):
        return {k: _strip_docs(v) for k, v in node.items() if k != "doc"}
    if isinstance(node, list):
        return [_strip_docs(v) for v in node]
    return node


def layout_hash(raw: dict) -> bytes:
    """First 8 bytes of SHA-256 of the canonical JSON of the schema without ``doc`` keys."""
    canon = json.dumps(_strip_docs(raw), sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(canon.encode("utf-8")).digest()[:8]


@dataclass(frozen=True)
class Message:
    name: str
    id: int
    kind: str
    fields: list[dict]
    response: str | None
    doc: str


class Schema:
    def __init__(self, raw: dict, source: str = "protocol.toml"):
        self.raw = raw
        self.source = source
        self.hash = layout_hash(raw)
        self.max_payload = int(raw["protocol"]["max_payload"])
        self.enums = {k: {n: v for n, v in e.items() if n != "doc"} for k, e in raw.get("enums", {}).items()}
        self.structs = {k: s["fields"] for k, s in raw.get("structs", {}).items()}
        self.by_name: dict[str, Message] = {}
        self.by_id: dict[int, Message] = {}
        for m in raw["message"]:
            msg = Message(m["name"], int(m["id"]), m["kind"], m["fields"], m.get("response"), m.get("doc", ""))
            self.by_name[msg.name] = msg
            self.by_id[msg.id] = msg

    def status_name(self, code: int) -> str:
        for n, v in self.enums["status"].items():
            if v == code:
                return n
        return f"status {code}"

    # ---- encode --------------------------------------------------------------------------

    def encode(self, name: str, values: dict[str, Any] | None = None) -> bytes:
        msg = self.by_name[name]
        out = bytearray()
        self._encode_fields(msg.fields, values or {}, out, name)
        return bytes(out)

    def _encode_fields(self, fields: list[dict], values: dict, out: bytearray, where: str) -> None:
        for f in fields:
            n, t = f["name"], f["type"]
            v = values.get(n, _default(f))
            if t == "array":
                if len(v) > f["max"]:
                    raise CodecError(f"{where}.{n}: {len(v)} elements, at most {f['max']}")
                out.append(len(v))
                for e in v:
                    self._encode_fields(self.structs[f["struct"]], e, out, f"{where}.{n}")
            elif t == "str":
                b = v.encode("utf-8")
                if len(b) > 255:
                    raise CodecError(f"{where}.{n}: string of {len(b)} bytes, at most 255")
                out.append(len(b))
                out += b
            elif t == "bytes":
                if len(v) > 65535:
                    raise CodecError(f"{where}.{n}: {len(v)} bytes, at most 65535")
                out += struct.pack("<H", len(v)) + bytes(v)
            else:
                _check_range(f, v, where)
                try:
                    out += struct.pack(_FMT[t], v)
                except struct.error as exc:
                    raise CodecError(f"{where}.{n}: {v!r} does not fit {t}") from exc

    # ---- decode --------------------------------------------------------------------------

    def decode(self, msg_id: int, payload: bytes) -> tuple[str, dict[str, Any]]:
        msg = self.by_id.get(msg_id)
        if msg is None:
            raise CodecError(f"unknown message id 0x{msg_id:02x}")
        values, pos = self._decode_fields(msg.fields, payload, 0, msg.name)
        if pos != len(payload):
            raise CodecError(f"{msg.name}: {len(payload) - pos} trailing bytes")
        return msg.name, values

    def _decode_fields(self, fields: list[dict], data: bytes, pos: int, where: str) -> tuple[dict, int]:
        values: dict[str, Any] = {}
        for f in fields:
            n, t = f["name"], f["type"]
            if t == "array":
                count, pos = _take(data, pos, "<B", where)
                if count > f["max"]:
                    raise CodecError(f"{where}.{n}: {count} elements, at most {f['max']}")
                items = []
                for _ in range(count):
                    e, pos = self._decode_fields(self.structs[f["struct"]], data, pos, f"{where}.{n}")
                    items.append(e)
                values[n] = items
            elif t in ("str", "bytes"):
                ln, pos = _take(data, pos, "<B" if t == "str" else "<H", where)
                if len(data) - pos < ln:
                    raise CodecError(f"{where}.{n}: truncated")
                raw = bytes(data[pos:pos + ln])
                pos += ln
                if t == "str":
                    try:
                        values[n] = raw.decode("utf-8")
                    except UnicodeDecodeError as exc:
                        raise CodecError(f"{where}.{n}: not UTF-8") from exc
                else:
                    values[n] = raw
            else:
                v, pos = _take(data, pos, _FMT[t], where)
                _check_range(f, v, where)
                values[n] = v
        return values, pos

    # ---- canonical text (shared with the C++ codec's describe) -----------------------------

    def describe(self, name: str, values: dict[str, Any]) -> str:
        return name + self._describe_fields(self.by_name[name].fields, values)

    def _describe_fields(self, fields: list[dict], values: dict) -> str:
        parts = []
        for f in fields:
            n, t = f["name"], f["type"]
            v = values[n]
            if t == "array":
                s = "[" + ",".join(self._describe_fields(self.structs[f["struct"]], e) for e in v) + "]"
            elif t == "str":
                s = f'"{v}"'
            elif t == "bytes":
                s = f"h'{bytes(v).hex()}'"
            elif t == "f32":
                s = format(float(v), ".9g")
                s = {"inf": "inf", "-inf": "-inf", "nan": "nan"}.get(s, s)
            else:
                s = str(int(v))
            parts.append(f"{n}={s}")
        return "{" + ",".join(parts) + "}"


def _default(f: dict):
    t = f["type"]
    if t == "array":
        return []
    if t == "str":
        return ""
    if t == "bytes":
        return b""
    if t == "f32":
        return 0.0
    return max(0, int(f.get("min", 0)))


def _check_range(f: dict, v, where: str) -> None:
    if f["type"] == "f32":
        if not math.isfinite(v):
            raise CodecError(f"{where}.{f['name']}: {v} is not finite")
        v = struct.unpack("<f", struct.pack("<f", v))[0]  # the value as it travels
    if ("min" in f and v < f["min"]) or ("max" in f and v > f["max"]):
        raise CodecError(f"{where}.{f['name']}: {v} outside [{f.get('min', '-')}, {f.get('max', '-')}]")


def _take(data: bytes, pos: int, fmt: str, where: str):
    size = struct.calcsize(fmt)
    if len(data) - pos < size:
        raise CodecError(f"{where}: truncated")
    return struct.unpack_from(fmt, data, pos)[0], pos + size


def schema_path() -> Path:
    return common_dir() / "protocol" / "protocol.toml"


@lru_cache(maxsize=4)
def load_schema(path: str | None = None) -> Schema:
    p = Path(path) if path else schema_path()
    with open(p, "rb") as f:
        return Schema(tomllib.load(f), str(p))
