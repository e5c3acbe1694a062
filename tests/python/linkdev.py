"""Helpers for the link tests: run the real firmware (`run` with the simulator source and sim motors,
or the standalone `serve`) on a pseudo-terminal, and the fuzzyctl CLI."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path


#: The scene the `run` device drives (obstacles off a long straight path: it runs for minutes).
STRAIGHT_SCENE = Path(__file__).resolve().parents[2] / "common" / "sim" / "scenes" / "straight.toml"


class Device:
    """The firmware with its serial link on a pty, in the background; .pty is the path the host opens.

    mode "run": ``fuzzystereo run --source sim:SCENE --motors sim --link pty`` (the robot loop on the
    simulator, paced at wall-clock speed); mode "serve": the standalone device services.
    """

    def __init__(self, binary: Path, state_dir: Path, extra: list[str] | None = None, mode: str = "serve"):
        self.binary, self.state_dir, self.extra, self.mode = binary, state_dir, extra or [], mode
        self.proc: subprocess.Popen | None = None
        self.pty = ""

    def start(self, timeout: float = 10.0) -> "Device":
        link_file = self.state_dir.parent / f"{self.state_dir.name}.pty"
        if link_file.exists():
            link_file.unlink()
        self.state_dir.mkdir(parents=True, exist_ok=True)
        self.out = open(self.state_dir.parent / f"{self.state_dir.name}.out", "ab")
        if self.mode == "run":
            head = [str(self.binary), "run", "--source", f"sim:{STRAIGHT_SCENE}", "--motors", "sim", "--quiet"]
        else:
            head = [str(self.binary), "serve"]
        self.proc = subprocess.Popen([*head, "--link", "pty", "--state-dir", str(self.state_dir),
                                      "--pty-link", str(link_file), *self.extra],
                                     stdout=self.out, stderr=subprocess.STDOUT)
        t0 = time.monotonic()
        while not link_file.exists():
            if self.proc.poll() is not None:
                raise RuntimeError(f"{self.mode} exited with {self.proc.returncode}: {self.output()}")
            if time.monotonic() - t0 > timeout:
                raise RuntimeError(f"{self.mode} did not announce its pty")
            time.sleep(0.01)
        self.pty = link_file.read_text().strip()
        return self

    def output(self) -> str:
        return (self.state_dir.parent / f"{self.state_dir.name}.out").read_text(errors="replace")

    def kill(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait()
        self.out.close()

    def stop(self) -> int:
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.out.close()
        return self.proc.returncode if self.proc else 0

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


def fuzzyctl(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    src = str(Path(__file__).resolve().parents[2] / "host" / "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    env["COLUMNS"] = "200"
    import sys

    return subprocess.run([sys.executable, "-m", "fuzzyctl", *args], capture_output=True, text=True, env=env,
                          timeout=timeout)
