"""The preset registry: every preset validates, the packaged copy is configs/<name>.json, a
bare name works as CONFIG, an unknown one is a one-line error, and the values the presets cite
(docs/scenarios.md) are the ones they carry."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.config import Config, config_to_dict, load_config
from veriloc_rt.config.presets import (DEFAULT_PRESET, PRESETS, load_config_or_preset,
                                       load_preset, preset_names, preset_path)
from veriloc_rt.errors import InputError

ROOT = Path(__file__).resolve().parents[3]
PACKAGED = ROOT / "veriloc_rt" / "data" / "presets"


def test_every_preset_is_listed_shipped_and_validates():
    shipped = {p.stem for p in PACKAGED.glob("*.json")}
    assert shipped == set(PRESETS) == set(preset_names())
    for name in preset_names():
        cfg = load_preset(name)
        assert isinstance(cfg, Config)
        assert cfg.channel.power_control is False          # broadcast PRS in every preset
        # a CONFIG path and the name give the same config (but the folder a sites CSV is in)
        a, b = config_to_dict(load_config(ROOT / "configs" / f"{name}.json")), config_to_dict(cfg)
        for d in (a, b):
            d["topology"]["sites"] = Path(d["topology"]["sites"]).name if d["topology"]["sites"] else ""
        assert a == b


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_configs_copy_is_the_packaged_preset(name):
    """configs/<name>.json and the packaged file are the same bytes, and so is every file they
    name (the UMi preset's sites CSV)."""
    packaged = preset_path(name)
    assert packaged.read_bytes() == (ROOT / "configs" / f"{name}.json").read_bytes()
    sites = json.loads(packaged.read_text()).get("topology", {}).get("sites")
    if sites:
        assert (PACKAGED / sites).read_bytes() == (ROOT / "configs" / sites).read_bytes()


def test_unknown_preset_is_a_one_line_input_error():
    with pytest.raises(InputError) as exc:
        load_config_or_preset("3gpp-rma")
    msg = str(exc.value)
    assert "\n" not in msg and "3gpp-rma" in msg
    assert all(n in msg for n in PRESETS)
    with pytest.raises(InputError):
        preset_path("nonexistent")
    # a path-like argument is a file, never a preset: the file's own error
    with pytest.raises(InputError, match="3gpp-uma.json"):
        load_config_or_preset("3gpp-uma.json")


def test_config_argument_resolution():
    """None: the default preset when one is given (``run``), else ``Config()``; a bare name:
    that preset."""
    assert config_to_dict(load_config_or_preset(None)) == config_to_dict(Config())
    assert config_to_dict(load_config_or_preset(None, DEFAULT_PRESET)) \
        == config_to_dict(load_preset(DEFAULT_PRESET))
    assert config_to_dict(load_config_or_preset("3gpp-uma")) == config_to_dict(load_preset("3gpp-uma"))


def test_default_preset_is_a_3gpp_preset_with_more_than_three_trps():
    """Issue 39 item 2: the default run is a 3GPP preset with more than 3 TRPs, ray traced,
    broadcast PRS."""
    cfg = load_preset(DEFAULT_PRESET)
    assert DEFAULT_PRESET.startswith("3gpp-")
    assert cfg.topology.num_trps > 3
    assert cfg.propagation.model == "raytrace"


def test_harsh_alley_is_the_built_in_canyon():
    """harsh-alley is Config() itself (the built-in canyon, broadcast PRS): every field."""
    assert config_to_dict(load_preset("harsh-alley")) == config_to_dict(Config())


def test_presets_carry_the_cited_values():
    """The values docs/scenarios.md cites, derived here independently of the files:
    UMa 49 dBm per 20 MHz (TR 38.901 Table 7.8-1) at the same PSD over the 10 MHz carrier is
    49 + 10 log10(10/20) = 45.99 -> 46 dBm; UMi at the TS 38.104 medium-range limit 38 dBm;
    10 MHz at 15 kHz is 52 PRB (TS 38.101-1 Table 5.3.2-1); the adversary's advantage over
    the BSs is 0, 0 and 24 dB."""
    uma, umi, alley = (load_preset(n) for n in ("3gpp-uma", "3gpp-umi-street", "harsh-alley"))
    assert uma.channel.bs_max_power_dbm == pytest.approx(49 + 10 * math.log10(10 / 20), abs=0.05)
    assert umi.channel.bs_max_power_dbm == 38.0 and alley.channel.bs_max_power_dbm == 24.0
    for cfg, adv_gain in ((uma, 0.0), (umi, 0.0), (alley, 24.0)):
        assert cfg.nr.numerology == 0 and cfg.nr.num_prb == 52
        assert cfg.channel.adversary_power_dbm - cfg.channel.bs_max_power_dbm == adv_gain
        for t in (cfg.threats.fbs, cfg.threats.meaconing, cfg.threats.jamming):
            assert t.power_dbm == cfg.channel.adversary_power_dbm
    assert (uma.topology.isd_m, uma.topology.bs_height_m, uma.topology.num_trps) == (500.0, 25.0, 9)
    # UMi: street-level sites below the roofs, on the canyon's streets, about 200 m apart
    xyz = np.loadtxt(PACKAGED / "umi-street-sites.csv", delimiter=",", skiprows=1)
    assert np.all(xyz[:, 2] < umi.scene.building_height_m)
    pitch = umi.scene.block_size_m + umi.scene.street_width_m
    on_street = np.isclose(np.mod(xyz[:, :2], pitch), 0.0)
    assert np.all(on_street.any(axis=1))
    d = np.linalg.norm(xyz[:, None, :2] - xyz[None, :, :2], axis=2)
    np.fill_diagonal(d, np.inf)
    assert np.all((d.min(axis=1) > 190.0) & (d.min(axis=1) < 215.0))
    assert umi.topology.num_trps > 3
