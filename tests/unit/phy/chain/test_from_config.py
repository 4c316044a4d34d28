"""PositioningChain.from_config: the one chain a config builds (runner and diagnostics)."""

from __future__ import annotations

import dataclasses

from veriloc_rt.config import Config
from veriloc_rt.phy.chain import PositioningChain


def test_from_config_takes_the_config_and_fits_the_doppler_scan():
    """Default receiver (scan 'channel', step 25 Hz, at most 400 Hz): a 60 Hz channel is
    scanned over +-(ceil(60 / 25) + 1) * 25 = +-100 Hz, worked out here from the rule of
    ReceiverConfig.scanned_for; a 1000 Hz channel is capped at doppler_max_hz, 400 Hz."""
    cfg = Config()
    chain = PositioningChain.from_config(cfg, max_doppler_hz=60.0)
    assert chain.receiver.doppler_max_hz == 100.0 and chain.receiver.doppler_scan == "fixed"
    assert chain.nr == cfg.nr and chain.channel == cfg.channel and chain.security == cfg.security
    assert PositioningChain.from_config(cfg, max_doppler_hz=1000.0).receiver.doppler_max_hz == 400.0
    # a run's DS-tagged chain: its own security and receiver, the same scan rule
    sec = dataclasses.replace(cfg.security, tag_scheme="ds")
    rx = dataclasses.replace(cfg.receiver, uplink=False)
    ds = PositioningChain.from_config(cfg, max_doppler_hz=60.0, security=sec, receiver=rx)
    assert ds.security.tag_scheme == "ds" and not ds.receiver.uplink
    assert ds.receiver.doppler_max_hz == 100.0
