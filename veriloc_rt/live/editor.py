"""The config editor's form, generated from the config's JSON schema, and its checks.

:func:`form_fields` flattens :func:`~veriloc_rt.config.config_schema` (what ``veriloc-rt config
schema`` prints) into one entry per leaf field: dotted path, input kind, default, range and
doc; the page draws one input per entry, so a field added to the config appears in the editor
with nothing to change here. :func:`check_config` validates an edited config with the
package's own validation (:func:`~veriloc_rt.config.config_from_dict`, and on request the
input checks of ``veriloc-rt config check``) and returns the same one-line
``error: <field>: <problem>`` a run prints; for the page (``file_details=False``) an error found
while reading the files the config names (:data:`FILE_FIELDS`) only names the field, since such
a message may quote the file (a CSV row, a key's length) or tell whether a path exists.
"""

from __future__ import annotations

import json
import os
import stat
import tempfile
from pathlib import Path

from ..config import config_from_dict, config_schema, config_to_dict, load_config, patch_data
from ..errors import InputError
from ..fileio import atomic_output
from ..sim.checks import check_inputs
from ..sim.plugins import registered_choices

__all__ = ["form_fields", "range_text", "check_config", "editor_config", "save_config",
           "set_field", "named_files", "file_error", "FILE_FIELDS", "PLUGIN_FIELDS"]

#: input kinds of the editor: ``kind`` of a :func:`form_fields` entry ('choices': a list of
#: registered names, a multiple choice)
KINDS = ("integer", "number", "boolean", "string", "enum", "choices", "json")
#: the config's fields that name files or folders the input checks read, with their kind, and
#: the value that reads nothing
FILE_FIELDS = {"scene.source": ("scene file", "canyon"),
               "scene.osm": ("OpenStreetMap extract", ""),
               "topology.sites": ("sites file", ""),
               "trajectory.source": ("trajectory file", "generator"),
               "security.keys_dir": ("key folder", None)}
#: the fields whose choices the editor takes from the plug-in registries (scene.source is a
#: file field: a path or a registered name, typed)
PLUGIN_FIELDS = ("propagation.model", "run.scenarios", "detectors.extra")


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
    The config's fields that name plug-ins (``propagation.model``, ``run.scenarios``,
    ``detectors.extra``: :func:`~veriloc_rt.sim.plugins.registered_choices`) offer the names
    registered in this process: ``enum`` for one name, ``choices`` for a list of them.
    """
    if schema is None:
        return [_registered(f) for f in _schema_fields(config_schema(), "")]
    return _schema_fields(schema, prefix)


def _registered(field: dict) -> dict:
    names = registered_choices().get(field["path"])
    if names is None or field["path"] not in PLUGIN_FIELDS:
        return field
    names = list(names)
    if field["kind"] == "string":
        return {**field, "kind": "enum", "choices": names, "range": range_text({"enum": names})}
    return {**field, "kind": "choices", "choices": names,
            "range": "a list of registered names: " + (", ".join(json.dumps(c) for c in names)
                                                        or "none registered")}


def _schema_fields(schema: dict, prefix: str) -> list[dict]:
    out: list[dict] = []
    for name, prop in schema["properties"].items():
        path = f"{prefix}.{name}" if prefix else name
        if prop.get("type") == "object" and "properties" in prop:
            out += _schema_fields(prop, path)
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
    """A copy of ``data`` with the dotted ``path`` set to ``value`` (sections created as
    needed; :func:`~veriloc_rt.config.patch_data`, the one patch helper)."""
    return patch_data(data, {path: value})


def check_config(data, inputs: bool = False, file_details: bool = True) -> InputError | None:
    """None when ``data`` is a valid config, else the :class:`InputError` a run would raise
    (``f"error: {exc}"`` is the CLI's line; ``exc.field`` names the field).

    :param inputs: also every check of the run's inputs that ``veriloc-rt config check`` makes
        (:func:`~veriloc_rt.sim.checks.check_inputs`: scene, trajectory, key files; it builds
        the geometry, a second or so, and traces nothing)
    :param file_details: False: an error of those checks, when the config names a file, is
        :func:`file_error` (the field only), never the message, which may quote the file
    """
    try:
        cfg = config_from_dict(data)
    except InputError as exc:
        return exc
    if not inputs:
        return None
    try:
        with tempfile.TemporaryDirectory(prefix="veriloc-edit-") as tmp:
            check_inputs(cfg, tmp)
    except InputError as exc:
        named = named_files(data)
        return exc if file_details or not named else file_error(exc, named)
    return None


def named_files(data: dict) -> dict[str, str]:
    """``{field: path}`` of the :data:`FILE_FIELDS` that ``data`` (a valid config) sets to a
    file or folder."""
    out = {}
    for field, (_kind, none) in FILE_FIELDS.items():
        section, name = field.split(".")
        value = (data.get(section) or {}).get(name)
        if isinstance(value, str) and value != none and value != "":
            out[field] = value
    return out


def file_error(exc: InputError, named: dict[str, str]) -> InputError:
    """The page's form of ``exc``, an error of the input checks of a config that names the
    files ``named`` (:func:`named_files`): the field whose file it concerns (the one the error
    names, or whose path the error's file lies under; ``inputs`` when that is not known) and
    that it cannot be used, nothing else: no content, no reason (missing, unreadable,
    malformed look the same, so the page cannot probe paths either)."""
    field = None
    for f, value in named.items():
        where = str(Path(value).expanduser())
        if exc.field == f or exc.field.startswith(f + "[") or exc.field == value or (
                exc.field.split(":")[0] in (value, where)) or exc.field.startswith(where + "/"):
            field = f
            break
    if field is None and len(named) == 1:
        field = next(iter(named))
    hint = ("the page shows no file details: `veriloc-rt config check CONFIG` in a terminal "
            "prints them")
    if field is None:
        return InputError("inputs", f"one of the files this config names ({', '.join(named)}) "
                          f"cannot be used ({hint})")
    return InputError(field, f"cannot be used as the {FILE_FIELDS[field][0]} ({hint})")


def editor_config(path: str | Path | None) -> dict:
    """The values the editor starts from: the config file at ``path`` resolved (every field,
    defaults filled in; relative paths made absolute), or the built-in default.

    :raises InputError: when the file is not a valid config
    """
    return config_to_dict(load_config(path))


def save_config(data, path: str | Path) -> Path:
    """Validate ``data`` and write it as JSON to ``path`` (atomically; an existing file keeps
    its permission bits).

    :raises InputError: the config's own error, or ``PATH: ...`` when it cannot be written
        (a link, folder, FIFO or device at ``path`` is refused: it would be replaced)
    """
    exc = check_config(data)
    if exc is not None:
        raise exc
    p = Path(path).expanduser()
    mode = None
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        pass
    except OSError as e:
        raise InputError(str(p), f"cannot write it ({e.strerror or e})") from None
    else:
        if not stat.S_ISREG(st.st_mode):
            raise InputError(str(p), "not a regular file (a link, folder, FIFO or device); "
                             "nothing written")
        mode = stat.S_IMODE(st.st_mode)
    try:
        with atomic_output(p) as tmp:
            tmp.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
            if mode is not None:
                os.chmod(tmp, mode)
    except OSError as e:
        raise InputError(str(p), f"cannot write it ({e.strerror or e})") from None
    return p
