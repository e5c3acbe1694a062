"""Per-frame work over a dataset: a process pool (``--jobs``) behind a rich progress bar.

``run_frames(fn, frames, jobs)`` calls ``fn(frame)`` for every frame (in this process when
``jobs == 1``, else in ``jobs`` worker processes) and yields ``(frame, result)`` as frames finish.
``fn`` must be picklable (a module-level function or a ``functools.partial`` of one). A
:class:`FatalError` raised for one frame is returned as that frame's result (the caller reports it
and goes on with the other frames); any other exception propagates.
"""

from __future__ import annotations

import os
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Callable, Iterator, Sequence, TypeVar

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from .dataset import Frame
from .errors import FatalError

T = TypeVar("T")


def _guarded(fn: Callable[[Frame], T], frame: Frame) -> T | FatalError:
    try:
        return fn(frame)
    except FatalError as exc:
        return exc


def _worker_init() -> None:
    # Each worker is one of --jobs processes: keep OpenCV/BLAS from spawning a thread per core each.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    import cv2

    cv2.setNumThreads(1)


def run_frames(
    fn: Callable[[Frame], T], frames: Sequence[Frame], jobs: int, label: str, console: Console
) -> Iterator[tuple[Frame, T | FatalError]]:
    """``(frame, fn(frame) or its FatalError)`` in completion order, with a progress bar on ``console``."""
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
               TextColumn("{task.fields[last]}"))
    with Progress(*columns, console=console, transient=False) as progress:
        task = progress.add_task(label, total=len(frames), last="")
        if jobs <= 1:
            for f in frames:
                progress.update(task, last=f"running {f.key}")
                result = _guarded(fn, f)
                progress.update(task, advance=1, last=f"done {f.key}")
                yield f, result
            return
        with ProcessPoolExecutor(max_workers=jobs, initializer=_worker_init) as pool:
            pending: dict[Future, Frame] = {pool.submit(_guarded, fn, f): f for f in frames}
            try:
                while pending:
                    done, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in done:
                        f = pending.pop(fut)
                        progress.update(task, advance=1, last=f"done {f.key}")
                        yield f, fut.result()
            except BaseException:
                for fut in pending:
                    fut.cancel()
                raise
