"""Config validation: field-path errors, unknown keys, schema, file loading."""

import json

import pytest

from veriloc_rt.config import Config, config_from_dict, config_schema, load_config
from veriloc_rt.config.fields import to_dict
from veriloc_rt.errors import InputError


def test_empty_config_is_the_default():
    assert config_from_dict({}) == Config()


@pytest.mark.parametrize("data, field, words", [
    ({"scene": {"street_width_m": -1}}, "scene.street_width_m", ">= 2.0"),
    ({"scene": {"nope": 1}}, "scene.nope", "unknown key"),
    ({"nope": 1}, "nope", "unknown key"),
    ({"seed": "x"}, "seed", "an integer"),
    ({"seed": True}, "seed", "an integer"),
    ({"propagation": {"raytrace": {"max_depth": 11}}}, "propagation.raytrace.max_depth", "<= 10"),
    ({"propagation": {"raytrace": {"los": 1}}}, "propagation.raytrace.los", "true or false"),
    ({"scene": {"source": "city.obj"}}, "scene.source", ".xml"),
    ({"trajectory": {"min_speed_mps": 20, "max_speed_mps": 10}}, "trajectory.min_speed_mps",
     "max_speed_mps"),
    ({"scene": {"building_height_m": float("inf")}}, "scene.building_height_m", "finite"),
    ({"scene": []}, "scene", "an object"),
    ({"threats": {"fbs": {"spoofed_slots": [3]}}}, "threats.fbs.spoofed_slots[0]", "0..2"),
    ({"threats": {"fbs": {"spoofed_slots": [1, 1]}}}, "threats.fbs.spoofed_slots", "repeated"),
    ({"threats": {"fbs": {"mode": "bias"}}}, "threats.fbs.spoofed_slots", "a subset"),
    ({"threats": {"fbs": {"mode": "bias", "spoofed_slots": [0, 2, 1]}}},
     "threats.fbs.spoofed_slots", "cancels"),
    ({"threats": {"fbs": {"mode": "delay"}}}, "threats.fbs.mode", "'bias'"),
    ({"channel": {"prs_power": "boosted"}}, "channel.prs_power", "'occupied'"),
    ({"run": {"attack_start_fraction": 0.8}}, "run.attack_end_fraction", "attack_start_fraction"),
    ({"propagation": {"raytrace": {"polarization": {"ue": "X"}}}},
     "propagation.raytrace.polarization.ue", "'+45'"),
    ({"propagation": {"raytrace": {"diffuse_reflection": True}}},
     "propagation.raytrace.diffuse_reflection", "scattering_coefficient is 0"),
    ({"propagation": {"raytrace": {"materials": {"scattering_coefficient": 1.5}}}},
     "propagation.raytrace.materials.scattering_coefficient", "<= 1.0"),
])
def test_bad_values_name_the_field(data, field, words):
    with pytest.raises(InputError) as exc:
        config_from_dict(data)
    assert exc.value.field == field
    assert words in str(exc.value)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("data, field, words", [
    ({"propagation": {"model": "foo"}}, "propagation.model", "'raytrace', 'uma'"),
    ({"run": {"scenarios": ["none", "spoof"]}}, "run.scenarios[1]", "'fbs'"),
])
def test_unknown_plugin_names_name_the_field(data, field, words):
    # plug-in names are looked up in the registries when a run or `config check` starts
    # (the config layer sits below them; docs/design.md, "Plug-in registries")
    from veriloc_rt.sim.plugins import check_plugin_names

    cfg = config_from_dict(data)
    with pytest.raises(InputError) as exc:
        check_plugin_names(cfg)
    assert exc.value.field == field
    assert words in str(exc.value)
    assert "\n" not in str(exc.value)


def test_round_trip_through_json():
    cfg = config_from_dict({"seed": 7, "scene": {"height_jitter_m": 2.5}})
    again = config_from_dict(json.loads(json.dumps(to_dict(cfg))))
    assert again == cfg


def test_schema_lists_every_field_with_defaults():
    schema = config_schema()
    scene = schema["properties"]["scene"]
    assert scene["additionalProperties"] is False
    assert scene["properties"]["street_width_m"]["default"] == 5.0
    assert scene["properties"]["street_width_m"]["minimum"] == 2.0
    fields = set(to_dict(Config()))
    assert fields == set(schema["properties"])


def test_load_config_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match="config file .* does not exist"):
        load_config(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError) as exc:
        load_config(bad)
    assert exc.value.field == str(bad) and "line 1" in exc.value.problem


def test_relative_paths_resolve_against_the_config_folder(tmp_path):
    f = tmp_path / "c.json"
    f.write_text(json.dumps({"scene": {"source": "city/scene.xml"},
                             "trajectory": {"source": "t.csv"}}))
    cfg = load_config(f)
    assert cfg.scene.source == str(tmp_path / "city" / "scene.xml")
    assert cfg.trajectory.source == str(tmp_path / "t.csv")
