"""Generic machinery for frozen, nested config dataclasses.

A config section is a ``@dataclass(frozen=True)`` whose fields carry their constraints in
``metadata`` (built with :func:`param`). :func:`from_dict` builds a section from plain JSON data,
rejecting unknown keys and wrong types or values with an :class:`~veriloc_rt.errors.InputError`
that names the dotted field path; :func:`to_dict` and :func:`json_schema` go the other way.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from typing import Any

from ..errors import InputError, bad_value

__all__ = ["param", "section", "from_dict", "to_dict", "json_schema", "check_value",
           "patch_data", "validate_on_construction", "INT_LIMIT"]

#: every integer field fits in a signed 64-bit integer (NumPy and the file formats use int64)
INT_LIMIT = 2**63


def param(default: Any, doc: str, *, lo: float | None = None, hi: float | None = None,
          choices: tuple | None = None, lo_open: bool = False) -> Any:
    """A config field with its default, description and allowed range or choices.

    :param lo: smallest allowed value (inclusive unless ``lo_open``)
    :param hi: largest allowed value (inclusive)
    :param choices: the allowed values, for enumerations
    """
    meta = {"doc": doc, "lo": lo, "hi": hi, "choices": choices, "lo_open": lo_open}
    if isinstance(default, (list, dict)):
        raise TypeError("mutable defaults are not allowed in frozen configs")
    return dataclasses.field(default=default, metadata=meta)


def section(cls_default: type, doc: str) -> Any:
    """A nested config section with default construction."""
    return dataclasses.field(default_factory=cls_default, metadata={"doc": doc})


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if origin is tuple:
        return "list of " + _type_name(typing.get_args(tp)[0])
    if tp is type(None):
        return "null"
    return {int: "integer", float: "number", bool: "boolean", str: "string"}.get(tp, str(tp))


def _coerce(tp: Any, value: Any, path: str) -> Any:
    """Check ``value`` against annotation ``tp`` and convert JSON forms (list -> tuple)."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        for arg in typing.get_args(tp):
            try:
                return _coerce(arg, value, path)
            except InputError:
                continue
        raise bad_value(path, value, _type_name(tp))
    if origin is tuple:
        (item_tp, *_rest) = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise bad_value(path, value, _type_name(tp))
        return tuple(_coerce(item_tp, v, f"{path}[{i}]") for i, v in enumerate(value))
    if tp is type(None):
        if value is None:
            return None
        raise bad_value(path, value, "null")
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise bad_value(path, value, "true or false")
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            if not -INT_LIMIT <= value < INT_LIMIT:
                raise bad_value(path, value, "an integer of at most 64 bits")
            return value
        if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
            return int(value)
        raise bad_value(path, value, "an integer")
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                as_float = float(value)
            except OverflowError:  # an integer beyond the float range
                raise bad_value(path, value, "a finite number") from None
            if not math.isfinite(as_float):
                raise bad_value(path, value, "a finite number")
            return as_float
        raise bad_value(path, value, "a number")
    if tp is str:
        if isinstance(value, str):
            return value
        raise bad_value(path, value, "a string")
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, path)
    raise TypeError(f"unsupported config annotation {tp!r} at {path}")


def _check_constraints(f: dataclasses.Field, value: Any, path: str) -> None:
    meta = f.metadata
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        raise bad_value(path, value, "one of " + ", ".join(repr(c) for c in choices))
    lo, hi = meta.get("lo"), meta.get("hi")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if lo is not None and (value < lo or (meta.get("lo_open") and value == lo)):
            rng = f"{'>' if meta.get('lo_open') else '>='} {lo}" + (f" and <= {hi}" if hi is not None else "")
            raise bad_value(path, value, f"a value {rng}")
        if hi is not None and value > hi:
            raise bad_value(path, value, f"a value <= {hi}" + (f" and >= {lo}" if lo is not None else ""))


def from_dict(cls: type, data: Any, path: str = "") -> Any:
    """Build config section ``cls`` from JSON ``data``; unknown keys are errors.

    :raises InputError: naming the dotted field path, the value and what is allowed
    """
    where = path or "config"
    if not isinstance(data, dict):
        raise bad_value(where, data, "an object")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        name = f"{path}.{unknown[0]}" if path else unknown[0]
        raise InputError(name, f"unknown key; allowed keys here: {', '.join(sorted(fields))}")
    kwargs = {}
    for name, value in data.items():
        fpath = f"{path}.{name}" if path else name
        coerced = _coerce(hints[name], value, fpath)
        _check_constraints(fields[name], coerced, fpath)
        kwargs[name] = coerced
    try:
        obj = cls(**kwargs)
    except InputError as exc:  # a section that validates itself on construction
        raise InputError(_under(path, exc.field), exc.problem) from None
    check = getattr(obj, "validate", None)
    if check is not None:
        check(path)
    return obj


def _under(path: str, field: str) -> str:
    """``field`` (relative to the section at ``path``, or already a full path) in full."""
    if not path or field == path or field.startswith(path + ".") or field.startswith(path + "["):
        return field
    return f"{path}.{field}"


#: section class -> its dotted path in the root config, for the classes used at one place only
#: (:func:`validate_on_construction`); others name their fields relative to the section
_PATHS: dict[type, str] = {}
_HINTS: dict[type, dict] = {}


def _checked_args(cls: type, given: dict) -> dict:
    """The constructor arguments ``given`` of config section ``cls`` checked and coerced as
    :func:`from_dict` checks a file's values (a nested section may be a dict). Errors name the
    field's dotted path (:data:`_PATHS`)."""
    path = _PATHS.get(cls, "")
    hints = _HINTS.get(cls)
    if hints is None:
        hints = _HINTS[cls] = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    out = {}
    for name, value in given.items():
        if name not in fields:   # the constructor's own TypeError says so
            out[name] = value
            continue
        tp, fpath = hints[name], f"{path}.{name}" if path else name
        if dataclasses.is_dataclass(tp):
            out[name] = value if isinstance(value, tp) else from_dict(tp, value, fpath)
        else:
            out[name] = _coerce(tp, value, fpath)
            _check_constraints(fields[name], out[name], fpath)
    return out


def validate_on_construction(root: type) -> None:
    """Make every config section class reachable from ``root`` check its arguments whenever an
    instance is made (constructor, ``dataclasses.replace``, ``Config.replace``): the same
    one-line :class:`~veriloc_rt.errors.InputError` naming the dotted field path as a config
    file gets. Idempotent."""
    seen: dict[type, list[str]] = {}

    def walk(cls: type, path: str) -> None:
        seen.setdefault(cls, []).append(path)
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if dataclasses.is_dataclass(hints[f.name]):
                walk(hints[f.name], f"{path}.{f.name}" if path else f.name)

    walk(root, "")
    for cls, paths in seen.items():
        if len(paths) == 1:
            _PATHS[cls] = paths[0]
        if getattr(cls.__init__, "_validates", False):
            continue
        init = cls.__init__

        def __init__(self, *args, __init=init, **kwargs):
            cls = type(self)
            names = [f.name for f in dataclasses.fields(cls) if f.init]
            given = dict(zip(names, args)) | kwargs
            path = _PATHS.get(cls, "")
            try:   # a section's own __post_init__ checks name fields relative to it
                __init(self, **_checked_args(cls, given))
            except InputError as exc:
                raise InputError(_under(path, exc.field), exc.problem) from None
            check = getattr(self, "validate", None)
            if check is not None:
                check(path)

        __init__._validates = True
        __init__.__doc__ = init.__doc__
        __init__.__wrapped__ = init
        cls.__init__ = __init__


def patch_data(data: dict, changes: dict, *, must_exist: bool = False) -> dict:
    """A deep copy of the config data ``data`` with each dotted path of ``changes`` set
    (``{"scene.street_width_m": 8}``); missing sections are created (the config's reader then
    rejects an unknown key, naming it). The one patch helper of the package and its scripts.

    :param must_exist: also reject a path whose field is not in ``data``
    :raises InputError: ``<path>: ...`` for a path through a value that is not a section
    """
    import copy

    out = copy.deepcopy(data)
    for path, value in changes.items():
        if not isinstance(path, str) or not path or any(not k for k in path.split(".")):
            raise InputError(str(path), "not a dotted field path (e.g. scene.street_width_m)")
        *sections, leaf = path.split(".")
        node = out
        for i, k in enumerate(sections):
            if must_exist and k not in node:
                raise InputError(path, "no such config field")
            node = node.setdefault(k, {})
            if not isinstance(node, dict):
                raise InputError(path, f"{'.'.join(sections[:i + 1])} is a value, not a section")
        if must_exist and leaf not in node:
            raise InputError(path, "no such config field")
        node[leaf] = copy.deepcopy(value)
    return out


def check_value(cls: type, name: str, value: Any, where: str) -> Any:
    """``value`` checked as field ``name`` of section ``cls`` (type, range, choices) and coerced,
    with ``where`` (a command-line flag) named in the error."""
    f = {f.name: f for f in dataclasses.fields(cls)}[name]
    coerced = _coerce(typing.get_type_hints(cls)[name], value, where)
    _check_constraints(f, coerced, where)
    return coerced


def to_dict(obj: Any) -> Any:
    """Plain JSON-ready form of a config section (tuples become lists)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple):
        return [to_dict(v) for v in obj]
    return obj


def _schema_of(tp: Any) -> dict:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        return {"anyOf": [_schema_of(a) for a in typing.get_args(tp)]}
    if origin is tuple:
        return {"type": "array", "items": _schema_of(typing.get_args(tp)[0])}
    if dataclasses.is_dataclass(tp):
        return json_schema(tp)
    return {"type": {int: "integer", float: "number", bool: "boolean", str: "string",
                     type(None): "null"}[tp]}


def json_schema(cls: type) -> dict:
    """JSON schema (draft 2020-12 subset) of a config section."""
    hints = typing.get_type_hints(cls)
    props = {}
    for f in dataclasses.fields(cls):
        s = _schema_of(hints[f.name])
        meta = f.metadata
        if meta.get("doc"):
            s["description"] = meta["doc"]
        if meta.get("choices") is not None:
            s["enum"] = list(meta["choices"])
        if meta.get("lo") is not None:
            s["exclusiveMinimum" if meta.get("lo_open") else "minimum"] = meta["lo"]
        if meta.get("hi") is not None:
            s["maximum"] = meta["hi"]
        if f.default is not dataclasses.MISSING:
            s["default"] = to_dict(f.default)
        props[f.name] = s
    doc = (cls.__doc__ or "").strip().splitlines()
    out = {"type": "object", "properties": props, "additionalProperties": False}
    if doc:
        out["description"] = doc[0]
    return out
