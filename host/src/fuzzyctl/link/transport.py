"""The host end of the link: one transport class (esptool's habit) owning the port, the framing,
sequence numbers, retries and timeouts, and the --trace hex dump.

Every exchange is a request with a fresh sequence number answered by a frame with the same number
(the device answers a duplicate with its cached answer, so a retry never executes twice). A frame
the device could not read makes it send ``rx_error`` and the host resends at once instead of
waiting for its timeout; bulk reads keep several requests in flight (window) and adapt the chunk
size to the error rate (halve on a loss, double after 16 clean answers).
"""

from __future__ import annotations

import errno
import os
import random
import select
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable

from ..errors import FatalError
from .framing import Frame, FrameDecoder, encode_frame
from .schema import CodecError, Schema, load_schema


class LinkError(FatalError):
    """A link fault (no answer, refused, schema mismatch, port problem)."""


class DeviceRefused(LinkError):
    def __init__(self, request: str, status: int, status_name: str, text: str):
        super().__init__(f"device refused {request}: {status_name} ({status}): {text}")
        self.status, self.status_name, self.text = status, status_name, text


class NoAnswer(LinkError):
    pass


class SchemaMismatch(LinkError):
    pass


def open_port(port: str, baud: int):
    """A raw 8N1 serial port (pyserial), with the common faults turned into clear messages."""
    import serial

    if not os.path.exists(port):
        raise LinkError(f"port {port} does not exist (is the device plugged in / the firmware running? for a pty "
                        "use the path `fuzzystereo serve --link pty` printed)")
    try:
        ser = serial.Serial(port, baudrate=baud, timeout=0, write_timeout=5, exclusive=True)
    except serial.SerialException as exc:
        e = getattr(exc, "errno", None)
        text = str(exc)
        if e == errno.EACCES or "Permission denied" in text:
            raise LinkError(f"permission denied on {port}: add your user to the 'dialout' group "
                            "(sudo usermod -aG dialout $USER, then log in again)") from exc
        if e == errno.EBUSY or "exclusively lock" in text or "busy" in text.lower():
            raise LinkError(f"port {port} is busy: another program (another fuzzyctl, a terminal) has it open") from exc
        raise LinkError(f"cannot open {port}: {text}") from exc
    ser.reset_input_buffer()
    return ser


@dataclass
class _Pending:
    index: int
    name: str
    values: dict
    seq: int
    wire: bytes
    sent: float = 0.0
    tries: int = 0


class Link:
    def __init__(self, port: str, baud: int = 115200, timeout: float = 1.0, retries: int = 5,
                 trace: bool = False, schema: Schema | None = None, trace_out=None, client: str = "fuzzyctl"):
        self.port_name, self.baud, self.timeout, self.retries = port, baud, timeout, retries
        self.schema = schema or load_schema()
        self.trace = trace
        self._trace_out = trace_out or sys.stderr
        self._t_last = time.monotonic()
        self.ser = open_port(port, baud)
        self.fd = self.ser.fileno()
        self.decoder = FrameDecoder(self.schema.max_payload)
        self.seq = random.randrange(65536)
        self.chunk_max = 1000
        self.chunk = self.chunk_max
        self._clean = 0
        self.stats = {"sent": 0, "resent": 0, "rx_errors_seen": 0, "bad_frames": 0}
        self.client = client
        self.info: dict | None = None

    def close(self) -> None:
        self.ser.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---- low level ---------------------------------------------------------------------------

    def _trace(self, direction: str, data: bytes, note: str = "") -> None:
        if not self.trace:
            return
        now = time.monotonic()
        dt = (now - self._t_last) * 1000
        self._t_last = now
        print(f"{direction} +{dt:8.2f} ms {len(data):5d} B {note}", file=self._trace_out)
        for i in range(0, len(data), 32):
            print(f"    {i:04x}  {data[i:i + 32].hex(' ')}", file=self._trace_out)

    def _send(self, p: _Pending) -> None:
        self._trace(">>", p.wire, f"{p.name} seq={p.seq}" + (f" (retry {p.tries})" if p.tries else ""))
        try:
            self.ser.write(p.wire)
        except Exception as exc:  # serial.SerialTimeoutException, OSError
            raise LinkError(f"cannot write to {self.port_name}: {exc}") from exc
        p.sent = time.monotonic()
        p.tries += 1
        self.stats["sent"] += 1
        if p.tries > 1:
            self.stats["resent"] += 1

    def _receive(self, wait: float) -> tuple[list[Frame], int]:
        r, _, _ = select.select([self.fd], [], [], max(0.0, wait))
        if not r:
            return [], 0
        try:
            data = os.read(self.fd, 65536)
        except OSError as exc:
            raise LinkError(f"cannot read from {self.port_name}: {exc}") from exc
        frames, dropped = self.decoder.feed(data)
        self.stats["bad_frames"] += dropped
        for f in frames:
            name = self.schema.by_id[f.id].name if f.id in self.schema.by_id else f"0x{f.id:02x}"
            self._trace("<<", data if len(frames) == 1 else b"", f"{name} seq={f.seq}")
        if dropped:
            self._trace("<<", data, f"{dropped} unreadable frame(s)")
        return frames, dropped

    def _new(self, index: int, name: str, values: dict | None) -> _Pending:
        msg = self.schema.by_name[name]
        payload = self.schema.encode(name, values or {})
        self.seq = (self.seq + 1) & 0xFFFF
        return _Pending(index, name, values or {}, self.seq, encode_frame(msg.id, self.seq, payload))

    def _loss(self) -> None:
        self.chunk = max(16, self.chunk // 2)
        self._clean = 0

    def _success(self) -> None:
        self._clean += 1
        if self._clean >= 16 and self.chunk < self.chunk_max:
            self.chunk = min(self.chunk_max, self.chunk * 2)
            self._clean = 0

    # ---- exchanges ---------------------------------------------------------------------------

    def exchange(self, requests: list[tuple[str, dict]], window: int = 1,
                 on_answer: Callable[[int, str, dict], None] | None = None) -> list[tuple[str, dict]]:
        """Send the requests with up to ``window`` in flight; the answers, in request order.
        Only idempotent requests should use window > 1."""
        answers: list[Any] = [None] * len(requests)
        queue = list(range(len(requests)))[::-1]
        pending: dict[int, _Pending] = {}
        while queue or pending:
            while queue and len(pending) < window:
                i = queue.pop()
                p = self._new(i, *requests[i])
                pending[p.seq] = p
                self._send(p)
            oldest = min(pending.values(), key=lambda q: q.sent)
            frames, dropped = self._receive(oldest.sent + self.timeout - time.monotonic())
            resend_oldest = dropped > 0
            for f in frames:
                msg = self.schema.by_id.get(f.id)
                if msg is not None and msg.name == "rx_error":
                    self.stats["rx_errors_seen"] += 1
                    resend_oldest = True
                    continue
                p = pending.pop(f.seq, None)
                if p is None:
                    continue  # a late answer to a request already answered (duplicate)
                try:
                    name, values = self.schema.decode(f.id, f.payload)
                except CodecError as exc:
                    raise LinkError(f"malformed answer to {p.name}: {exc}") from exc
                expected = self.schema.by_name[p.name].response
                if name == "ack" and values["status"] != 0:
                    raise DeviceRefused(p.name, values["status"], self.schema.status_name(values["status"]), values["text"])
                if name != expected:
                    raise LinkError(f"device answered {p.name} with {name}, expected {expected}")
                answers[p.index] = (name, values)
                self._success()
                if on_answer:
                    on_answer(p.index, name, values)
                # answers come in order: anything sent before this one and still open was lost
                for q in list(pending.values()):
                    if q.sent < p.sent:
                        self._loss()
                        self._check_tries(q)
                        self._send(q)
            now = time.monotonic()
            for q in sorted(pending.values(), key=lambda q: q.sent):
                if now - q.sent >= self.timeout or (resend_oldest and q is min(pending.values(), key=lambda x: x.sent)):
                    self._loss()
                    self._check_tries(q)
                    self._send(q)
                    resend_oldest = False
        return answers

    def _check_tries(self, q: _Pending) -> None:
        if q.tries > self.retries:
            expected = self.schema.by_name[q.name].response
            raise NoAnswer(f"no answer from {self.port_name}: sent {q.name} (seq {q.seq}, {len(q.wire)} bytes) "
                           f"{q.tries} times, waited {self.timeout:g} s each for {expected} (is the firmware running "
                           f"`serve`/`run` with --link on this port, at {self.baud} baud?)")

    def request(self, name: str, values: dict | None = None) -> dict:
        return self.exchange([(name, values or {})])[0][1]

    def hello(self) -> dict:
        """Handshake: layout hashes must match (SchemaMismatch names both)."""
        ours = self.schema.hash
        try:
            info = self.request("hello", {"schema_hash": ours, "client": self.client})
        except DeviceRefused as exc:
            if exc.status_name == "SCHEMA_MISMATCH":
                raise SchemaMismatch(f"protocol layout mismatch: host {ours.hex()} (common/protocol/protocol.toml), "
                                     f"device says: {exc.text}; update the firmware or fuzzyctl so both use the "
                                     "same protocol.toml") from exc
            raise
        if info["schema_hash"] != ours:
            raise SchemaMismatch(f"protocol layout mismatch: host {ours.hex()}, device {info['schema_hash'].hex()}")
        self.info = info
        return info
