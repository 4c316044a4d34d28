"""Strict-JSON check of a written file (issue #40): Python's reader with every non-finite token
(``NaN``, ``Infinity``, ``-Infinity``) an error, and, where Node.js is installed, ``JSON.parse``
(which has no such tokens)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

NODE = shutil.which("node")


def _reject(token: str):
    raise AssertionError(f"non-finite JSON token {token}")


def assert_strict_json(path: str | Path) -> object:
    """Parse ``path`` strictly (Python, and Node.js when present); return the Python value."""
    path = Path(path)
    with open(path, encoding="utf-8") as fh:
        value = json.load(fh, parse_constant=_reject)
    if NODE is not None:
        r = subprocess.run([NODE, "-e", "JSON.parse(require('fs').readFileSync(process.argv[1], "
                            "'utf8'))", str(path)], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, (path, r.stderr)
    return value


def assert_strict_json_text(text: str, tmp: Path) -> object:
    """:func:`assert_strict_json` of ``text`` (a command's standard output)."""
    f = tmp / "stdout.json"
    f.write_text(text, encoding="utf-8")
    return assert_strict_json(f)


def assert_folder_strict(folder: str | Path) -> list[Path]:
    """Every ``*.json`` under ``folder`` parses strictly; the files checked."""
    files = sorted(Path(folder).rglob("*.json"))
    for f in files:
        assert_strict_json(f)
    return files
