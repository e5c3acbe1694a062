"""Running the ``fuzzystereo`` program (the firmware built for the desktop).

One plain function per firmware command, taking the binary path; the CLI and the tests share them.
Faults (binary missing, non-zero exit, output that does not parse) are :class:`FatalError`.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Sequence

import numpy as np

from . import paths
from .errors import FatalError


def find_binary(path: str | Path | None = None) -> Path:
    """The firmware binary: ``path``, else ``$FUZZYSTEREO_BIN``, else ``build/default/fuzzystereo``."""
    binary = Path(path) if path is not None else paths.default_firmware_binary()
    if not binary.is_file():
        raise FatalError(
            f"firmware binary {binary} not found: build it (cmake --preset default && "
            f"cmake --build --preset default), pass --bin or set {paths.ENV_BIN}"
        )
    if not os.access(binary, os.X_OK):
        raise FatalError(f"firmware binary {binary} is not executable")
    return binary


def run(binary: str | Path, args: Sequence[str], stdin: str | None = None, timeout: float = 600.0) -> str:
    """Run ``binary args...``; its stdout, or FatalError with the command and its last stderr line."""
    cmd = [str(binary), *map(str, args)]
    try:
        proc = subprocess.run(cmd, input=stdin, capture_output=True, text=True, timeout=timeout)
    except FileNotFoundError as exc:
        raise FatalError(f"cannot run {binary}: {exc.strerror}") from exc
    except subprocess.TimeoutExpired as exc:
        raise FatalError(f"'{' '.join(cmd)}' did not finish within {timeout:g} s") from exc
    if proc.returncode != 0:
        lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
        why = lines[-1] if lines else "no message"
        raise FatalError(f"'{' '.join(cmd[1:])}' failed (exit {proc.returncode}): {why}")
    return proc.stdout


def fis_eval(
    binary: str | Path,
    dc1: np.ndarray,
    dc2: np.ndarray,
    fis: str | Path | None = None,
    config: str | Path | None = None,
    timeout: float = 600.0,
) -> tuple[np.ndarray, np.ndarray]:
    """``fuzzystereo fis eval``: (lut, exact) outputs for the input pairs.

    Contract: stdin has one ``dc1 dc2`` pair per line; stdout one ``lut exact`` line per pair —
    the fixed-point LUT read and the double-precision Mamdani evaluation, both in [0, 1].
    """
    a = np.asarray(dc1, dtype=np.float64).ravel()
    b = np.asarray(dc2, dtype=np.float64).ravel()
    args = ["fis", "eval"]
    if fis is not None:
        args += ["--fis", str(fis)]
    if config is not None:
        args += ["--config", str(config)]
    stdin = "".join(f"{x!r} {y!r}\n" for x, y in zip(a.tolist(), b.tolist()))
    out = run(binary, args, stdin=stdin, timeout=timeout)
    return parse_fis_eval_output(out, a.size)


def parse_fis_eval_output(text: str, expected: int) -> tuple[np.ndarray, np.ndarray]:
    """Parse ``lut exact`` lines; FatalError naming the first bad line."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if len(lines) != expected:
        raise FatalError(f"'fis eval' printed {len(lines)} lines for {expected} input pairs")
    values = np.empty((expected, 2))
    for i, line in enumerate(lines):
        fields = line.split()
        try:
            if len(fields) != 2:
                raise ValueError
            values[i] = [float(fields[0]), float(fields[1])]
        except ValueError:
            raise FatalError(f"'fis eval' output line {i + 1} is not 'lut exact': {line[:80]!r}") from None
    return values[:, 0], values[:, 1]


def match(
    binary: str | Path,
    left: str | Path,
    right: str | Path,
    out: str | Path,
    max_disparity: int | None = None,
    config: str | Path | None = None,
    threads: int | None = None,
    dump: bool = True,
    timeout: float = 1800.0,
) -> Path:
    """``fuzzystereo match``: disparity maps (and with ``dump`` the stage dump) in ``out``; returns ``out``."""
    args = ["match", "--left", str(left), "--right", str(right), "--out", str(out)]
    if max_disparity is not None:
        args += ["--max-disparity", str(max_disparity)]
    if config is not None:
        args += ["--config", str(config)]
    if threads is not None:
        args += ["--threads", str(threads)]
    if dump:
        args.append("--dump")
    run(binary, args, timeout=timeout)
    return Path(out)
