"""Link framing (docs/protocol.md), the same bytes as firmware/link/src/framing.cpp:

    frame = id:u8 | seq:u16 LE | payload | CRC-32C(id..payload):u32 LE
    wire  = 0x00 | COBS(frame) | 0x00

COBS comes from the PyPI package ``cobs`` and CRC-32C (Castagnoli) from ``google-crc32c``. The
decoder resynchronises on the next 0x00 after garbage and counts each dropped frame by reason.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import google_crc32c
from cobs import cobs

OVERHEAD = 7  # id + seq + crc


def crc32c(data: bytes) -> int:
    return google_crc32c.value(bytes(data))


def encode_frame(msg_id: int, seq: int, payload: bytes) -> bytes:
    raw = struct.pack("<BH", msg_id, seq & 0xFFFF) + payload
    raw += struct.pack("<I", crc32c(raw))
    return b"\x00" + cobs.encode(raw) + b"\x00"


@dataclass
class Frame:
    id: int
    seq: int
    payload: bytes


@dataclass
class FrameErrors:
    cobs: int = 0
    crc: int = 0
    short: int = 0
    oversize: int = 0

    @property
    def total(self) -> int:
        return self.cobs + self.crc + self.short + self.oversize


@dataclass
class FrameDecoder:
    max_payload: int = 1024
    errors: FrameErrors = field(default_factory=FrameErrors)

    def __post_init__(self) -> None:
        n = self.max_payload + OVERHEAD
        self._max_encoded = n + n // 254 + 2
        self._buf = bytearray()
        self._overflow = False

    def feed(self, data: bytes) -> tuple[list[Frame], int]:
        """Frames completed by ``data`` and the number of frames dropped."""
        frames: list[Frame] = []
        dropped = 0
        start = 0
        while True:
            i = data.find(b"\x00", start)
            chunk = data[start:] if i < 0 else data[start:i]
            if len(self._buf) + len(chunk) > self._max_encoded:
                self._overflow = True
                self._buf.clear()
            else:
                self._buf += chunk
            if i < 0:
                break
            f = self._finish()
            if isinstance(f, Frame):
                frames.append(f)
            elif f:
                dropped += 1
            start = i + 1
        return frames, dropped

    def _finish(self):
        buf, overflow = bytes(self._buf), self._overflow
        self._buf.clear()
        self._overflow = False
        if overflow:
            self.errors.oversize += 1
            return True
        if not buf:
            return None
        try:
            raw = cobs.decode(buf)
        except cobs.DecodeError:
            self.errors.cobs += 1
            return True
        if len(raw) < OVERHEAD:
            self.errors.short += 1
            return True
        body, (crc,) = raw[:-4], struct.unpack("<I", raw[-4:])
        if crc32c(body) != crc:
            self.errors.crc += 1
            return True
        msg_id, seq = struct.unpack_from("<BH", body)
        return Frame(msg_id, seq, bytes(body[3:]))
