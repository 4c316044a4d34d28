"""The config editor's form from the schema, and its checks against the CLI's own messages."""

from __future__ import annotations

import dataclasses
import json
import typing
from dataclasses import dataclass

import pytest

from veriloc_rt.cli import main
from veriloc_rt.config import Config, TrajectoryConfig, config_from_dict
from veriloc_rt.config.fields import json_schema, param, section
from veriloc_rt.live.editor import (PLUGIN_FIELDS, check_config, editor_config, form_fields,
                                    range_text, save_config, set_field)
from veriloc_rt.propagation.models import PROPAGATION_REGISTRY, PropagationModel


@dataclass(frozen=True)
class Inner:
    """An inner section."""

    gain_db: float | None = param(None, "a gain or none", lo=0.0, hi=30.0)
    mode: str = param("a", "the mode", choices=("a", "b"))


@dataclass(frozen=True)
class Outer:
    """A test config."""

    count: int = param(3, "how many", lo=1, hi=10)
    rate: float = param(0.5, "a rate", lo=0.0, lo_open=True)
    flag: bool = param(True, "a flag")
    name: str = param("x", "a name")
    ids: tuple[int, ...] = param((0, 1), "a list")
    inner: Inner = section(Inner, "inner section")


def test_form_of_a_known_schema():
    f = {e["path"]: e for e in form_fields(json_schema(Outer))}
    assert list(f) == ["count", "rate", "flag", "name", "ids", "inner.gain_db", "inner.mode"]
    assert f["count"] == {
        "path": "count", "section": "", "kind": "integer", "default": 3, "minimum": 1,
        "maximum": 10, "exclusive_minimum": None, "choices": None, "nullable": False,
        "range": "1 .. 10", "doc": "how many"}
    assert (f["rate"]["kind"], f["rate"]["exclusive_minimum"], f["rate"]["range"]) == \
        ("number", 0.0, "> 0")
    assert [f[k]["kind"] for k in ("flag", "name", "ids")] == ["boolean", "string", "json"]
    assert f["ids"]["default"] == [0, 1]
    g = f["inner.gain_db"]
    assert (g["section"], g["kind"], g["nullable"], g["range"], g["default"]) == \
        ("inner", "json", True, "0 .. 30 or null", None)
    assert (f["inner.mode"]["kind"], f["inner.mode"]["choices"], f["inner.mode"]["range"]) == \
        ("enum", ["a", "b"], 'one of "a", "b"')


def _leaves(cls: type, prefix: str = "") -> dict:
    """Every leaf field of a config dataclass with its metadata, walked from the dataclasses
    themselves (not from the schema)."""
    out = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        path = f"{prefix}.{f.name}" if prefix else f.name
        if dataclasses.is_dataclass(hints[f.name]):
            out |= _leaves(hints[f.name], path)
        else:
            out[path] = f
    return out


def test_form_has_every_config_field_with_its_metadata():
    form = {e["path"]: e for e in form_fields()}
    leaves = _leaves(Config)
    assert set(form) == set(leaves)
    for path, f in leaves.items():
        e, meta = form[path], f.metadata
        assert e["doc"] == meta["doc"], path
        if path not in PLUGIN_FIELDS:   # those: the registries' names (test below)
            assert e["choices"] == (list(meta["choices"]) if meta["choices"] is not None
                                    else None)
        lo_key = "exclusive_minimum" if meta["lo_open"] else "minimum"
        assert e[lo_key] == meta["lo"] and e["maximum"] == meta["hi"], path
        default = f.default
        assert e["default"] == (list(default) if isinstance(default, tuple) else default), path
    n = form["trajectory.num_points"]
    meta = {f.name: f for f in dataclasses.fields(TrajectoryConfig)}["num_points"].metadata
    assert n["range"] == f"{meta['lo']} .. {meta['hi']}"


def test_plugin_fields_offer_the_registered_names():
    """propagation.model is a choice of the propagation registry's names and run.scenarios a
    multiple choice of the threats' (with 'none'); a model registered after start-up is offered
    on the next form, and gone once unregistered."""
    form = {e["path"]: e for e in form_fields()}
    m, s = form["propagation.model"], form["run.scenarios"]
    assert (m["kind"], m["choices"]) == ("enum", list(PROPAGATION_REGISTRY.names()))
    assert m["choices"][:3] == ["raytrace", "uma", "umi"] and m["default"] in m["choices"]
    assert (s["kind"], s["choices"]) == ("choices", ["none", "fbs", "meaconing", "jamming"])
    assert set(s["default"]) <= set(s["choices"])
    assert form["detectors.extra"]["kind"] == "choices"
    PROPAGATION_REGISTRY.register("editor_test_model", type("EditorTest", (PropagationModel,), {}))
    try:
        m = {e["path"]: e for e in form_fields()}["propagation.model"]
        assert m["choices"][-1] == "editor_test_model"
        assert m["range"].endswith('"editor_test_model"')
    finally:
        PROPAGATION_REGISTRY.unregister("editor_test_model")
    assert "editor_test_model" not in {e["path"]: e for e in form_fields()}[
        "propagation.model"]["choices"]


@pytest.mark.parametrize("prop, text", [
    ({"minimum": 2, "maximum": 10}, "2 .. 10"),
    ({"exclusiveMinimum": 0.001, "maximum": 3600.0}, "> 0.001 .. 3600"),
    ({"minimum": 0.0}, ">= 0"),
    ({"maximum": 5}, "<= 5"),
    ({}, "any"),
    ({"enum": [1, 2]}, "one of 1, 2"),
    ({"anyOf": [{"type": "number"}, {"type": "null"}], "minimum": 0.0}, ">= 0 or null"),
])
def test_range_text(prop, text):
    assert range_text(prop) == text


def test_check_gives_the_line_the_cli_prints(tmp_path, capsys):
    data = set_field(editor_config(None), "trajectory.num_points", 1)
    exc = check_config(data)
    assert exc is not None and exc.field == "trajectory.num_points"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    assert main(["config", "show", str(bad)]) == 2
    assert capsys.readouterr().err.strip() == f"error: {exc}"
    assert check_config(set_field(data, "trajectory.num_points", 2)) is None


def test_save_writes_the_config_it_checked(tmp_path):
    data = set_field(editor_config(None), "seed", 7)
    path = save_config(data, tmp_path / "sub" / "c.json")
    assert config_from_dict(json.loads(path.read_text())).seed == 7
    with pytest.raises(ValueError, match="^seed: got -1"):
        save_config(set_field(data, "seed", -1), tmp_path / "d.json")
    assert not (tmp_path / "d.json").exists()


def test_check_of_the_inputs_gives_the_line_of_config_check(tmp_path, capsys):
    # valid as a config, but the trajectory CSV does not exist: only the input checks see it
    data = set_field(editor_config(None), "trajectory.source", str(tmp_path / "missing.csv"))
    assert check_config(data) is None
    exc = check_config(data, inputs=True)
    assert exc is not None
    f = tmp_path / "c.json"
    f.write_text(json.dumps(data))
    assert main(["config", "check", str(f)]) == 2
    assert capsys.readouterr().err.strip() == f"error: {exc}"
