"""Atomic file output: a file is either its old content or its complete new content.

Every file a run writes goes through here: the new content goes to a temporary file in the same
folder, which is then renamed over the target (``os.replace``, atomic on POSIX within one file
system). A run killed while writing leaves the old file (or none) and a stray temporary file,
never a truncated target.
"""

from __future__ import annotations

import os
import secrets
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_output", "atomic_write_bytes", "atomic_write_text", "TMP_MARK"]

#: part of every temporary file's name (so that a folder scan can skip them)
TMP_MARK = ".tmp-"


@contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on a clean exit rename it over ``path``.

    The temporary name keeps ``path``'s suffix (matplotlib and NumPy choose the format by it).
    On an exception the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # created like any new file (mode 0o666 less the umask; mkstemp's would be 0o600)
    tmp = path.parent / f".{path.name}{TMP_MARK}{os.getpid()}-{secrets.token_hex(4)}{path.suffix}"
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (:func:`atomic_output`)."""
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`atomic_output`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))
