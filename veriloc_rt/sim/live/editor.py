"""The config editor's form, generated from the config's JSON schema, and its checks.

:func:`form_fields` flattens :func:`~veriloc_rt.config.config_schema` (what ``veriloc-rt config
schema`` prints) into one entry per leaf field: dotted path, input kind, default, range and
doc; the page draws one input per entry, so a field added to the config appears in the editor
with nothing to change here. :func:`check_config` validates an edited config with the
package's own validation (:func:`~veriloc_rt.config.config_from_dict`, and on request the
input checks of ``veriloc-rt config check``) and returns the same one-line
``error: <field>: <problem>`` a run prints.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

from ...config import config_from_dict, config_schema, config_to_dict, load_config
from ...errors import InputError
from ...fileio import atomic_write_text
from ..checks import check_inputs

__all__ = ["form_fields", "range_text", "check_config", "editor_config", "save_config",
           "set_field"]

#: input kinds of the editor: ``kind`` of a :func:`form_fields` entry
KINDS = ("integer", "number", "boolean", "string", "enum", "json")


def _kind(prop: dict) -> str:
    if "enum" in prop:
        return "enum"
    t = prop.get("type")
    if t in ("integer", "number", "boolean", "string"):
        return t
    # arrays and 'X or null' unions: edited as JSON text (null, a number, a list)
    return "json"


def _nullable(prop: dict) -> bool:
    return any(a.get("type") == "null" for a in prop.get("anyOf", ()))


def range_text(prop: dict) -> str:
    """The allowed values of a schema property as the editor shows them: ``2 .. 10000``,
    ``> 0.001 .. 3600``, ``>= 0``, ``one of 'a', 'b'``, ``'' (any)``; `` or null`` when
    the field may be null."""
    if "enum" in prop:
        text = "one of " + ", ".join(json.dumps(c) for c in prop["enum"])
    else:
        lo = (f"> {prop['exclusiveMinimum']:g}" if "exclusiveMinimum" in prop
              else f"{prop['minimum']:g}" if "minimum" in prop else None)
        hi = f"{prop['maximum']:g}" if "maximum" in prop else None
        if lo is not None and hi is not None:
            text = f"{lo} .. {hi}"
        elif lo is not None:
            text = lo if lo.startswith(">") else f">= {lo}"
        elif hi is not None:
            text = f"<= {hi}"
        else:
            text = "any"
    return text + (" or null" if _nullable(prop) else "")


def form_fields(schema: dict | None = None, prefix: str = "") -> list[dict]:
    """One entry per leaf field of ``schema`` (default: the config's), in schema order.

    Each entry: ``path`` (dotted), ``section`` (the dotted path of its section, '' at the
    top), ``kind`` (one of :data:`KINDS`), ``default``, ``minimum``, ``maximum``,
    ``exclusive_minimum`` (None where the schema has none), ``choices`` (enum values or None),
    ``nullable``, ``range`` (:func:`range_text`) and ``doc`` (the field's description).
    """
    schema = config_schema() if schema is None else schema
    out: list[dict] = []
    for name, prop in schema["properties"].items():
        path = f"{prefix}.{name}" if prefix else name
        if prop.get("type") == "object" and "properties" in prop:
            out += form_fields(prop, path)
            continue
        out.append({
            "path": path, "section": prefix, "kind": _kind(prop),
            "default": prop.get("default"), "minimum": prop.get("minimum"),
            "maximum": prop.get("maximum"), "exclusive_minimum": prop.get("exclusiveMinimum"),
            "choices": prop.get("enum"), "nullable": _nullable(prop),
            "range": range_text(prop), "doc": prop.get("description", ""),
        })
    return out


def set_field(data: dict, path: str, value) -> dict:
    """``data`` with the dotted ``path`` set to ``value`` (sections created as needed)."""
    *sections, leaf = path.split(".")
    node = data
    for s in sections:
        node = node.setdefault(s, {})
    node[leaf] = value
    return data


def check_config(data, inputs: bool = False) -> InputError | None:
    """None when ``data`` is a valid config, else the :class:`InputError` a run would raise
    (``f"error: {exc}"`` is the CLI's line; ``exc.field`` names the field).

    :param inputs: also every check of the run's inputs that ``veriloc-rt config check`` makes
        (:func:`~veriloc_rt.sim.checks.check_inputs`: scene, trajectory, key files; it builds
        the geometry, a second or so, and traces nothing)
    """
    try:
        cfg = config_from_dict(data)
        if inputs:
            with tempfile.TemporaryDirectory(prefix="veriloc-edit-") as tmp:
                check_inputs(cfg, tmp)
    except InputError as exc:
        return exc
    return None


def editor_config(path: str | Path | None) -> dict:
    """The values the editor starts from: the config file at ``path`` resolved (every field,
    defaults filled in; relative paths made absolute), or the built-in default.

    :raises InputError: when the file is not a valid config
    """
    return config_to_dict(load_config(path))


def save_config(data, path: str | Path) -> Path:
    """Validate ``data`` and write it as JSON to ``path`` (atomically).

    :raises InputError: the config's own error, or ``--save PATH: ...`` when it cannot be written
    """
    exc = check_config(data)
    if exc is not None:
        raise exc
    p = Path(path).expanduser()
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        return atomic_write_text(p, json.dumps(data, indent=2) + "\n")
    except OSError as e:
        raise InputError(f"--save {p}", f"cannot write it ({e.strerror or e})") from None
