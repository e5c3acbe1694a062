"""The one exception class for faults the user can fix (bad input, missing file, failing device).

Library code raises :class:`FatalError` with a one-line message that names the file or field at
fault; :func:`fuzzyctl.cli.main` catches it once, prints the line and exits non-zero (esptool's
habit). Anything else escaping is a bug and keeps its traceback.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


class FatalError(RuntimeError):
    """A user or device fault: printed as one line by ``main()``, exit code 2."""

    exit_code = 2

    @classmethod
    def from_exception(cls, message: str, exc: BaseException) -> "FatalError":
        """``FatalError("message: <exc>")`` chained to ``exc`` (for ``raise ... from``)."""
        err = cls(f"{message}: {exc}")
        err.__cause__ = exc
        return err


class CheckFailed(FatalError):
    """A check ran and its result is outside tolerance (``fis check``, ``compare``): exit code 1."""

    exit_code = 1


def load_json(path: Path) -> Any:
    """The parsed JSON file; FatalError naming the file when it is missing, unreadable or not JSON."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise FatalError(f"cannot read {path}: {exc.strerror}") from exc
    except json.JSONDecodeError as exc:
        raise FatalError(f"{path} is not valid JSON: {exc}") from exc
