"""ChannelConfig / ReceiverConfig: JSON round trip, unknown keys and bad values rejected."""

from __future__ import annotations

import pytest

from veriloc_rt.config.channel import ChannelConfig, ReceiverConfig
from veriloc_rt.config.fields import from_dict, to_dict
from veriloc_rt.errors import InputError


@pytest.mark.parametrize("cls", [ChannelConfig, ReceiverConfig])
def test_round_trip_of_the_defaults(cls):
    assert from_dict(cls, to_dict(cls()), "x") == cls()


@pytest.mark.parametrize("cls,data,field", [
    (ChannelConfig, {"domain": "wavelet"}, "channel.domain"),
    (ChannelConfig, {"bs_max_power_dbm": 100.0}, "channel.bs_max_power_dbm"),
    (ChannelConfig, {"noise_figure": 3.0}, "channel.noise_figure"),
    (ReceiverConfig, {"toa_method": "median"}, "receiver.toa_method"),
    (ReceiverConfig, {"srs_symbols": [14]}, "receiver.srs_symbols"),
    (ReceiverConfig, {"doppler_max_hz": 10.0, "doppler_step_hz": 50.0}, "receiver.doppler_step_hz"),
])
def test_bad_input_names_the_field(cls, data, field):
    with pytest.raises(InputError) as err:
        from_dict(cls, data, field.split(".")[0])
    assert err.value.field == field


@pytest.mark.parametrize("step_hz,fastest_hz,expected_hz", [
    (25.0, 162.0, 200.0),    # 6.48 steps -> 7, plus the one beyond: 8 x 25 Hz
    (25.0, 150.0, 175.0),    # exactly 6 steps, plus one
    (25.0, 0.0, 25.0),       # a static channel still gets the neighbours of 0 Hz
    (25.0, 390.0, 400.0),    # 17 steps would be 425 Hz: capped at the UE's doppler_max_hz
    (12.5, 162.0, 175.0),    # 12.96 steps -> 13, plus one: 14 x 12.5 Hz
    (12.5, 279.0, 300.0),    # the paper's UMa drive: 22.3 -> 23, plus one: 24 x 12.5 Hz
])
def test_the_doppler_scan_fitted_to_the_channel(step_hz, fastest_hz, expected_hz):
    """receiver.doppler_scan 'channel': +-(fastest Doppler rounded up to whole steps + one
    step), at most doppler_max_hz (worked values at 25 and 12.5 Hz steps, the 400 Hz cap)."""
    cfg = ReceiverConfig(doppler_step_hz=step_hz)
    got = cfg.scanned_for(fastest_hz)
    assert got.doppler_max_hz == expected_hz and got.doppler_scan == "fixed"
    assert got.doppler_step_hz == step_hz


@pytest.mark.parametrize("cfg", [ReceiverConfig(doppler_scan="fixed"), ReceiverConfig(doppler_max_hz=0.0)])
def test_a_fixed_or_disabled_scan_is_not_fitted(cfg):
    assert cfg.scanned_for(12.0) == cfg


def test_a_negative_fastest_doppler_is_refused():
    with pytest.raises(ValueError, match="max_doppler_hz"):
        ReceiverConfig().scanned_for(-1.0)
