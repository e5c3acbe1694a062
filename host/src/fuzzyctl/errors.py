"""The one exception class for faults the user can fix (bad input, missing file, failing device).

Library code raises :class:`FatalError` with a one-line message that names the file or field at
fault; :func:`fuzzyctl.cli.main` catches it once, prints the line and exits non-zero (esptool's
habit). Anything else escaping is a bug and keeps its traceback.
"""


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
