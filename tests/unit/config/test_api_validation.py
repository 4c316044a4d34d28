"""Config objects validate on construction by every route (issue #40): the constructor,
``Config.replace`` (a section as a dict), ``Config.updated`` (dotted paths) and
``dataclasses.replace`` give the same one-line ``InputError`` naming the dotted field path as a
config file read by the CLI. Property-based over every numeric field of the schema with a bound
(derandomized: the ``ci`` profile in ``tests/conftest.py``)."""

from __future__ import annotations

import dataclasses
import math
import typing

import pytest
from hypothesis import given
from hypothesis import strategies as st

from veriloc_rt.config import Config, SceneConfig, config_from_dict, config_schema
from veriloc_rt.config.fields import patch_data
from veriloc_rt.errors import InputError


def _bounded(schema: dict, path: str = "") -> list[tuple[str, dict]]:
    """(dotted path, bounds) of every numeric field of ``schema`` with a minimum or maximum."""
    out = []
    for name, s in schema["properties"].items():
        p = f"{path}.{name}" if path else name
        if s.get("type") == "object":
            out += _bounded(s, p)
            continue
        types = {s.get("type")} | {x.get("type") for x in s.get("anyOf", [])}
        bounds = {k: s[k] for k in ("minimum", "exclusiveMinimum", "maximum") if k in s}
        if types & {"number", "integer"} and bounds:
            out.append((p, {**bounds, "integer": "number" not in types}))
    return out


FIELDS = _bounded(config_schema())


def _section_classes() -> dict[str, type]:
    """dotted section path -> its class ('' the root)."""
    out = {"": Config}

    def walk(cls, path):
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if dataclasses.is_dataclass(hints[f.name]):
                p = f"{path}.{f.name}" if path else f.name
                out[p] = hints[f.name]
                walk(hints[f.name], p)
    walk(Config, "")
    return out


SECTIONS = _section_classes()
#: classes used at one place of the tree: their direct constructor names the full path
UNIQUE = {c for c in SECTIONS.values() if list(SECTIONS.values()).count(c) == 1}


def test_the_schema_has_bounded_numeric_fields():
    assert len(FIELDS) > 50 and ("scene.street_width_m", {"minimum": 2.0, "maximum": 100.0,
                                                           "integer": False}) in FIELDS


@st.composite
def out_of_range(draw):
    path, b = draw(st.sampled_from(FIELDS))
    sides = []
    lo = b.get("minimum", b.get("exclusiveMinimum"))
    if lo is not None:
        sides.append("lo")
    if b.get("maximum") is not None:
        sides.append("hi")
    side = draw(st.sampled_from(sides))
    step = draw(st.integers(1, 10**6)) if b["integer"] else draw(
        st.floats(1e-3, 1e6, allow_nan=False, allow_infinity=False))
    if side == "lo":
        value = lo - step if "minimum" in b else lo - step + (0 if b["integer"] else step)
        if "exclusiveMinimum" in b and not b["integer"] and draw(st.booleans()):
            value = lo   # the open end itself
    else:
        value = b["maximum"] + step
    if not b["integer"]:
        value = float(value)
    assume_ok = math.isfinite(value) and not (
        (side == "lo" and (value >= lo if "minimum" in b else value > lo))
        or (side == "hi" and value <= b["maximum"]))
    if not assume_ok:   # float rounding at large bounds: take a clearly outside value
        value = (lo - 1 if side == "lo" else b["maximum"] * 2 + 1)
    return path, value


def _error(fn) -> InputError:
    with pytest.raises(InputError) as info:
        fn()
    return info.value


@given(out_of_range())
def test_out_of_range_is_the_same_field_error_by_every_route(case):
    path, value = case
    cfg = Config()
    # the reference: a config file's data, as the CLI reads it
    ref = _error(lambda: config_from_dict(patch_data({}, {path: value})))
    assert ref.field == path
    line = f"error: {ref}"
    assert "\n" not in line and line.startswith(f"error: {path}: ")
    assert str(_error(lambda: cfg.updated({path: value}))) == str(ref)
    *sec, leaf = path.split(".")
    section = ".".join(sec)
    cls = SECTIONS[section]
    if sec:
        top, *rest = sec
        nested = {".".join(rest + [leaf]): value} if rest else {leaf: value}
        if not rest:
            assert str(_error(lambda: cfg.replace(**{top: nested}))) == str(ref)
    # the section's own constructor and dataclasses.replace on an instance of it
    direct = _error(lambda: cls(**{leaf: value}))
    again = _error(lambda: dataclasses.replace(cls(), **{leaf: value}))
    if cls in UNIQUE:
        assert str(direct) == str(again) == str(ref)
    else:  # used at several places (e.g. detectors.hmac and detectors.digsig): relative name
        assert direct.field == again.field == leaf and direct.problem == ref.problem


def test_a_section_given_as_a_dict_and_a_valid_update():
    cfg = Config().updated({"scene.street_width_m": 8})
    assert cfg.scene.street_width_m == 8.0 and isinstance(cfg.scene.street_width_m, float)
    assert Config().replace(scene={"street_width_m": 9}).scene.street_width_m == 9.0
    assert Config(scene={"street_width_m": 7}).scene == SceneConfig(street_width_m=7.0)
    e = _error(lambda: Config().updated({"scene.nope": 1}))
    assert e.field == "scene.nope" and "unknown key" in e.problem
    e = _error(lambda: Config().updated({"seed.x": 1}))
    assert e.field == "seed.x" and "seed is a value" in e.problem
    e = _error(lambda: Config().replace(seed="x"))
    assert e.field == "seed" and "an integer" in e.problem
