"""A fault-injecting relay for link tests: sits between the host and the device on a pty pair,
and drops, corrupts, duplicates and delays bytes at set rates, and throttles each direction to a
baud rate (10 bits per byte, 8N1). The host opens :attr:`FaultRelay.host_path`.

    relay = FaultRelay("/dev/pts/5", drop=0.01, corrupt=0.01, seed=1).start()
    ... Link(relay.host_path) ...
    relay.stop(); print(relay.stats)
"""

from __future__ import annotations

import os
import random
import select
import threading
import time
import tty
from dataclasses import dataclass, field


@dataclass
class RelayStats:
    bytes: int = 0
    dropped: int = 0
    corrupted: int = 0
    duplicated: int = 0
    delayed: int = 0


@dataclass
class FaultRelay:
    device_path: str
    drop: float = 0.0
    corrupt: float = 0.0
    duplicate: float = 0.0
    delay: float = 0.0          # probability per chunk of holding it back
    delay_s: float = 0.02
    baud: int | None = None     # throttle each direction to this rate
    seed: int = 0
    stats: dict = field(default_factory=lambda: {"to_device": RelayStats(), "to_host": RelayStats()})

    def start(self) -> "FaultRelay":
        self._rng = random.Random(self.seed)
        self._lock = threading.Lock()
        self.dev_fd = os.open(self.device_path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.dev_fd)
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)  # kept open: no EIO on the master between host sessions
        self.host_path = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._pump, args=(self.master, self.dev_fd, "to_device"), daemon=True),
                         threading.Thread(target=self._pump, args=(self.dev_fd, self.master, "to_host"), daemon=True)]
        for t in self._threads:
            t.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=2)
        for fd in (self.dev_fd, self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def _mangle(self, data: bytes, st: RelayStats) -> bytes:
        out = bytearray()
        with self._lock:
            r = self._rng
            for b in data:
                st.bytes += 1
                if self.drop and r.random() < self.drop:
                    st.dropped += 1
                    continue
                if self.corrupt and r.random() < self.corrupt:
                    b ^= 1 << r.randrange(8)
                    st.corrupted += 1
                out.append(b)
                if self.duplicate and r.random() < self.duplicate:
                    out.append(b)
                    st.duplicated += 1
            hold = self.delay and r.random() < self.delay
        if hold:
            st.delayed += 1
            time.sleep(self.delay_s)
        return bytes(out)

    def _pump(self, src: int, dst: int, name: str) -> None:
        st = self.stats[name]
        t_free = time.monotonic()
        while not self._stop.is_set():
            r, _, _ = select.select([src], [], [], 0.05)
            if not r:
                continue
            try:
                data = os.read(src, 4096 if self.baud is None else max(16, self.baud // 2000))
            except OSError:
                time.sleep(0.01)
                continue
            data = self._mangle(data, st)
            if self.baud:
                t_free = max(t_free, time.monotonic()) + len(data) * 10.0 / self.baud
                wait = t_free - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            try:
                os.write(dst, data)
            except OSError:
                pass
