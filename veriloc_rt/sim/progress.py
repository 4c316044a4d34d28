"""Progress callbacks ``(label, done, total)`` for :func:`veriloc_rt.run` and the commands:
tqdm bars on stderr (``run(..., progress=True)``, the CLI), or none (``-q/--no-progress``)."""

from __future__ import annotations

import sys

from tqdm import tqdm

__all__ = ["ProgressBar", "NoProgress", "progress_callback"]


class ProgressBar:
    """The library's progress callback ``(label, done, total)`` as one tqdm bar per stage on
    stderr (redrawn on a terminal; elsewhere, e.g. CI logs, updated every 10 s)."""

    def __init__(self, stream=None):
        self.stream = sys.stderr if stream is None else stream   # the one of the call
        self.label: str | None = None
        self.bar: tqdm | None = None
        self.interval = 0.2 if getattr(stream, "isatty", lambda: False)() else 10.0

    def __call__(self, label: str, done: int, total: int) -> None:
        if label != self.label or self.bar is None:
            self.close()
            self.label = label
            self.bar = tqdm(total=total, desc=f"{label:<12}", file=self.stream, ascii=True,
                            mininterval=self.interval, dynamic_ncols=True, leave=True)
        self.bar.total = total
        self.bar.update(done - self.bar.n)
        if done >= total:
            self.close()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        self.bar, self.label = None, None


class NoProgress:
    """A progress callback that shows nothing."""

    def __call__(self, label: str, done: int, total: int) -> None:
        pass

    def close(self) -> None:
        pass


def progress_callback(progress):
    """``progress`` as :func:`veriloc_rt.run` takes it: True -> a :class:`ProgressBar`,
    False or None -> None, a callable as it is."""
    if progress is True:
        return ProgressBar()
    if progress is False or progress is None:
        return None
    if not callable(progress):
        raise TypeError(f"Argument `progress` must be True, False, None or a callable "
                        f"(label, done, total), not {type(progress).__name__}")
    return progress
