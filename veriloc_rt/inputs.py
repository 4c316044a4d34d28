"""Reading user files safely: the checks every input file and folder goes through.

Each function raises :class:`~veriloc_rt.errors.InputError` naming the field or file for input
that cannot be used, so the CLI prints one line ``error: <field or file>: <problem>`` and exits
with code 2. The checks happen before anything is read or computed:

* a path is a string without NUL bytes, at most :data:`MAX_PATH_CHARS` characters and
  :data:`MAX_NAME_BYTES` bytes per component (Linux ``PATH_MAX`` and ``NAME_MAX``);
* a file is opened non-blocking and must be a regular file (a FIFO or a device would block the
  read forever, a folder has no content) of at most the caller's size limit;
* text is UTF-8, with or without the byte-order mark spreadsheets write;
* JSON objects must not repeat a key (Python's parser keeps the last one silently, which would
  hide an invalid value), nesting and numbers must stay within what the parser handles;
* an output folder must be (or be creatable as) a writable folder, probed with a temporary file
  that is removed again, so nothing is left behind when the check fails.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import math
import os
import stat
import tempfile
from pathlib import Path
from typing import Any

from .errors import InputError, short_repr

__all__ = ["MAX_PATH_CHARS", "MAX_NAME_BYTES", "MAX_JSON_BYTES", "check_path", "read_bytes",
           "read_text", "decode_text", "parse_json", "check_out_dir"]

#: longest accepted path, characters (Linux PATH_MAX is 4096 bytes including the NUL)
MAX_PATH_CHARS = 4095
#: longest accepted path component, bytes (Linux NAME_MAX)
MAX_NAME_BYTES = 255
#: largest config file read, bytes (the full resolved config is about 10 kB)
MAX_JSON_BYTES = 1 << 20
#: deepest JSON nesting accepted (the config nests four levels)
MAX_JSON_DEPTH = 32


def check_path(value: Any, field: str) -> Path:
    """``value`` as a :class:`~pathlib.Path`, refusing what no file system call accepts.

    :raises InputError: for a non-string, an empty string, a NUL byte or an over-long path
    """
    if isinstance(value, Path):
        value = str(value)
    if not isinstance(value, str) or not value:
        raise InputError(field, f"got {value!r:.80}, expected a non-empty path")
    if "\x00" in value:
        raise InputError(field, "path contains a NUL byte")
    if len(value) > MAX_PATH_CHARS:
        raise InputError(field, f"path of {len(value)} characters, expected at most "
                         f"{MAX_PATH_CHARS}")
    try:
        parts = [len(os.fsencode(part)) for part in Path(value).parts]
    except UnicodeError:
        raise InputError(field, "path is not valid text") from None
    if parts and max(parts) > MAX_NAME_BYTES:
        raise InputError(field, f"path has a component of {max(parts)} bytes, expected at most "
                         f"{MAX_NAME_BYTES}")
    return Path(value)


def read_bytes(path: Any, field: str, what: str, max_bytes: int) -> bytes:
    """The content of the regular file ``path``, at most ``max_bytes`` long.

    Opened with ``O_NONBLOCK``, so a FIFO is refused instead of waiting for a writer.

    :param field: the name in the error (the config field, or the file itself)
    :param what: the kind of file, for the message ("config file", "key file")
    """
    p = check_path(path, field)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise InputError(field, f"{what} {str(p)!r} does not exist") from None
    except OSError as exc:
        raise InputError(field, f"cannot open {what} {str(p)!r} ({exc.strerror})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
            raise InputError(field, f"{what} {str(p)!r} is {kind}")
        if st.st_size > max_bytes:
            raise InputError(field, f"{what} {str(p)!r} has {st.st_size} bytes, expected at "
                             f"most {max_bytes}")
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if total > max_bytes:  # grew while being read
                raise InputError(field, f"{what} {str(p)!r} is longer than {max_bytes} bytes")
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise InputError(field, f"cannot read {what} {str(p)!r} ({exc.strerror})") from None
    finally:
        os.close(fd)


def decode_text(data: bytes, field: str, what: str) -> str:
    """UTF-8 text, a leading byte-order mark dropped."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(field, f"{what} is not UTF-8 text (byte 0x{data[exc.start]:02x} at "
                         f"offset {exc.start})") from None


def read_text(path: Any, field: str, what: str, max_bytes: int) -> str:
    """:func:`read_bytes` then :func:`decode_text`."""
    return decode_text(read_bytes(path, field, what, max_bytes), field, what)


class _DuplicateKey(ValueError):
    pass


def _unique_object(pairs: list[tuple[str, Any]]) -> dict:
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def _depth(text: str) -> int:
    """Deepest bracket nesting of JSON text (brackets inside strings skipped)."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def parse_json(text: str, field: str) -> Any:
    """JSON data from ``text``; a repeated key in one object, nesting deeper than
    :data:`MAX_JSON_DEPTH`, an integer over Python's 4300-digit conversion limit or a non-finite
    constant (``NaN``, ``Infinity``, not JSON) are errors."""
    depth = _depth(text)
    if depth > MAX_JSON_DEPTH:
        raise InputError(field, f"JSON nested {depth} levels deep, expected at most "
                         f"{MAX_JSON_DEPTH}")

    def constant(name: str):
        raise InputError(field, f"{name} is not a JSON number; expected a finite number")

    try:
        return json.loads(text, object_pairs_hook=_unique_object, parse_constant=constant)
    except InputError:
        raise
    except _DuplicateKey as exc:
        raise InputError(field, f"duplicate key {exc.args[0]!r:.80} in one JSON object (the "
                         "value it hides would be ignored)") from None
    except json.JSONDecodeError as exc:
        raise InputError(field, f"not valid JSON (line {exc.lineno}: {exc.msg})") from None
    except (ValueError, RecursionError) as exc:  # an integer too long to convert
        raise InputError(field, f"not usable JSON ({str(exc).split(';')[0]})") from None


def check_out_dir(path: Any, field: str) -> Path:
    """An output folder that exists or can be created, and is writable.

    Nothing is created: the nearest existing ancestor must be a folder, and a temporary file is
    created there and removed again (``os.access`` would not do: it answers yes to root for a
    read-only mount or ``/proc``).
    """
    p = check_path(path, field)
    probe = p
    while not probe.exists() and probe.parent != probe:
        if probe.is_symlink():
            try:
                os.stat(probe)
                what = "a dangling symbolic link"
            except OSError as exc:
                what = ("a symbolic link loop" if exc.errno == errno.ELOOP
                        else "a dangling symbolic link")
            raise InputError(field, f"{str(probe)!r} is {what}")
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        what = "exists and is not a folder" if probe == p else f"has {str(probe)!r}, not a folder"
        raise InputError(field, f"{str(p)!r} {what}")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".veriloc-write-check-", dir=probe)
    except OSError as exc:
        raise InputError(field, f"cannot write into {str(probe)!r} ({exc.strerror})") from None
    os.close(fd)
    os.unlink(tmp)
    return p


def numeric_csv(text: str, name: str, columns: tuple[list[str], ...],
                expected: str) -> tuple[list[str], list[tuple[int, list[float]]]]:
    """The rows of a CSV file with a header and finite numbers below it.

    :param text: the file's text;  name: the file's name in messages
    :param columns: the accepted headers (lower case, stripped)
    :param expected: the headers as the message names them, e.g. ``"'t,x,y' or 't,x,y,z'"``
    :returns: the header, and (line number, values) of every non-blank row
    :raises InputError: ``name`` (no rows, another header) or ``name:line`` (another number of
        columns, a value that is not a finite number)
    """
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:   # a field over csv.field_size_limit(), a NUL byte
        raise InputError(name, f"not a readable CSV file ({exc})") from None
    if not rows:
        raise InputError(name, f"empty file, expected a header {expected} and rows")
    header = [h.strip().lower() for h in rows[0]]
    if header not in columns:
        raise InputError(name, f"header {short_repr(','.join(rows[0]))}, expected {expected}")
    out = []
    for i, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise InputError(f"{name}:{i}", f"{len(row)} columns, expected {len(header)}")
        try:
            vals = [float(c) for c in row]
        except ValueError:
            raise InputError(f"{name}:{i}", f"non-numeric value in {short_repr(row)}") from None
        if not all(math.isfinite(v) for v in vals):
            raise InputError(f"{name}:{i}", f"non-finite value in {short_repr(row)}")
        out.append((i, vals))
    return header, out
