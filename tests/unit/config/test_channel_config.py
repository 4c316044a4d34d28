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
