"""Atomic file output: a file is either its old content or its complete new content.

Every file a run writes goes through here: the new content goes to a temporary file in the same
folder, which is then renamed over the target (``os.replace``, atomic on POSIX within one file
system). A run killed while writing leaves the old file (or none) and a stray temporary file,
never a truncated target.
"""

from __future__ import annotations

import errno
import json
import math
import os
import secrets
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_files", "atomic_output", "atomic_write_bytes", "atomic_write_text", "naming",
           "exchange_folders", "TMP_MARK", "DISK_FULL", "strict_json", "json_text", "NONFINITE"]

#: part of every temporary file's name (so that a folder scan can skip them)
TMP_MARK = ".tmp-"


#: errno values of a write that found no room: the file system is full, the user's quota used up
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


@contextmanager
def naming(path: str | Path) -> Iterator[None]:
    """Re-raise an :class:`OSError` of the block that names no file (``write(2)`` and
    ``flush`` name none), or names a temporary file of :func:`atomic_output`, as the same
    error naming ``path``: a full disk then says which file it could not write."""
    try:
        yield
    except OSError as exc:
        if exc.errno is not None and (exc.filename is None or TMP_MARK in str(exc.filename)):
            raise OSError(exc.errno, exc.strerror or os.strerror(exc.errno), str(path)) from exc
        raise


@contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on a clean exit rename it over ``path``.

    The temporary name keeps ``path``'s suffix (matplotlib and NumPy choose the format by it).
    On an exception the temporary file is removed and ``path`` is left as it was; an
    :class:`OSError` of the block that names no file names ``path`` (:func:`naming`).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # created like any new file (mode 0o666 less the umask; mkstemp's would be 0o600)
    tmp = path.parent / f".{path.name}{TMP_MARK}{os.getpid()}-{secrets.token_hex(4)}{path.suffix}"
    with naming(path):
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        with naming(path):
            yield tmp
            os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_files(folder: str | Path) -> Iterator[Path]:
    """Yield a temporary folder inside ``folder``; on a clean exit move every file written there
    to the same relative path under ``folder``, each by one rename, then remove the temporary
    folder.

    For writers that produce a set of files (a scene's XML and its meshes): each target is its
    old content or its complete new content. Files in subfolders are placed before the folder's
    own files, so an index at the top (``scene.xml``) appears only after the files it names.
    On an exception the temporary folder is removed and ``folder`` is left as it was.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f".files{TMP_MARK}{os.getpid()}-{secrets.token_hex(4)}"
    tmp.mkdir()
    try:
        yield tmp
        files = [p for p in tmp.rglob("*") if p.is_file()]
        for src in sorted(files, key=lambda p: (-len(p.relative_to(tmp).parts), str(p))):
            dst = folder / src.relative_to(tmp)
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dst)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


#: renameat2(2) flag: swap the two paths atomically (linux/fs.h)
RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def exchange_folders(a: str | Path, b: str | Path) -> None:
    """Swap the folders ``a`` and ``b`` (of one file system) in one step
    (``renameat2(RENAME_EXCHANGE)``, Linux 3.15+): whoever looks at ``b`` sees its old content
    or its new one, never a mix or nothing. Where the file system or C library lacks it, two
    renames with ``b`` missing in between (put back if the second fails)."""
    a, b = Path(a), Path(b)
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        fn = None
    if fn is not None:
        if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), RENAME_EXCHANGE) == 0:
            return
        err = ctypes.get_errno()
        if err not in (errno.ENOSYS, errno.EINVAL):
            raise OSError(err, os.strerror(err), str(b))
    aside = b.with_name(f".{b.name}{TMP_MARK}old-{os.getpid()}-{secrets.token_hex(4)}")
    os.rename(b, aside)
    try:
        os.rename(a, b)
    except OSError:
        os.rename(aside, b)
        raise
    os.rename(aside, a)


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (:func:`atomic_output`)."""
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`atomic_output`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


#: how :func:`json_text` writes a float that is not finite (JSON has no such number)
NONFINITE = {"inf": "inf", "-inf": "-inf", "nan": None}


def strict_json(obj):
    """``obj`` with every non-finite float replaced as :data:`NONFINITE` says: ``+inf`` and
    ``-inf`` become the strings ``"inf"`` and ``"-inf"`` (``float()`` reads them back, so does
    MATLAB's ``str2double``), NaN becomes ``null`` (no value). NumPy scalars and arrays become
    plain numbers and lists; tuples become lists; a :class:`~pathlib.Path` becomes its text."""
    if isinstance(obj, dict):
        return {str(k): strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "tolist") and not isinstance(obj, (int, float)):   # NumPy scalar or array
        return strict_json(obj.tolist())
    if isinstance(obj, float):
        if math.isnan(obj):
            return NONFINITE["nan"]
        if math.isinf(obj):
            return NONFINITE["inf" if obj > 0 else "-inf"]
    return obj


def json_text(obj, indent: int | None = 2, **kwargs) -> str:
    """``obj`` as strict JSON text (RFC 8259: no ``NaN``/``Infinity`` tokens, which
    ``JSON.parse`` and ``jq`` reject): non-finite floats as :func:`strict_json` writes them."""
    return json.dumps(strict_json(obj), indent=indent, allow_nan=False, **kwargs)
