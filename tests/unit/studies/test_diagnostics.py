"""``benign_chain``'s timing passes: the results are the first pass's, a chain that answers a
repeated point differently is refused, the cost is a CPU time per point."""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.phy.chain import PositioningChain
from veriloc_rt.propagation.stochastic import uma_propagation
from veriloc_rt.sim.run_folder import run_keys
from veriloc_rt.studies import diagnostics
from veriloc_rt.studies.diagnostics import benign_chain
from veriloc_rt.world.geometry import build_geometry

#: a UMa drive of three points (no ray tracing)
CONFIG = {"seed": 3, "trajectory": {"num_points": 3}, "propagation": {"model": "uma"}}


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    cfg = config_from_dict(CONFIG)
    geo = build_geometry(cfg, tmp_path_factory.mktemp("scene"))
    bs_ue = uma_propagation(geo, cfg.propagation, cfg.seed).bs_ue
    return cfg, geo, bs_ue, run_keys(cfg, len(geo.bs_pos))


def test_two_passes_give_the_first_pass_results(drive):
    cfg, geo, bs_ue, keys = drive
    one = benign_chain(cfg, geo, bs_ue, keys, np.arange(3), shared_noise=True)
    two = benign_chain(cfg, geo, bs_ue, keys, np.arange(3), shared_noise=True, passes=2)
    for name in ("toa", "az", "pos", "decisions"):
        np.testing.assert_array_equal(getattr(two, name), getattr(one, name))
    # a CPU time per point: a chain call on a 3-BS UMa point takes tens of milliseconds
    assert 0.0 < two.seconds_per_point < 10.0


def test_a_chain_that_changes_between_passes_is_refused(drive, monkeypatch):
    cfg, geo, bs_ue, keys = drive
    calls = {"n": 0}

    class Drifting(PositioningChain):
        def __call__(self, *args, **kwargs):   # the fourth call (point 0, pass 2) is 1 ns late
            calls["n"] += 1
            res = super().__call__(*args, **kwargs)
            if calls["n"] == 4:
                object.__setattr__(res, "toa_s", res.toa_s + 1e-9)
            return res

    monkeypatch.setattr(diagnostics, "PositioningChain", Drifting)
    with pytest.raises(RuntimeError, match="pass 2 at point 0 differs"):
        benign_chain(cfg, geo, bs_ue, keys, np.arange(3), passes=2)


@pytest.mark.parametrize("passes", [0, 1.5])
def test_passes_must_be_a_positive_int(drive, passes):
    cfg, geo, bs_ue, keys = drive
    with pytest.raises(ValueError, match="passes"):
        benign_chain(cfg, geo, bs_ue, keys, np.arange(3), passes=passes)


def test_same_results_compares_every_output_with_nans_equal(drive):
    import dataclasses
    cfg, geo, bs_ue, keys = drive
    one = benign_chain(cfg, geo, bs_ue, keys, np.arange(3), shared_noise=True)
    again = benign_chain(cfg, geo, bs_ue, keys, np.arange(3), shared_noise=True)
    assert one.same_results(again)
    # a NaN where the first run has one is the same result; a ToA 1 ns off or a flipped
    # decision is not
    toa = one.toa.copy()
    toa[0, 0] = np.nan
    assert dataclasses.replace(one, toa=toa).same_results(dataclasses.replace(again, toa=toa.copy()))
    assert not one.same_results(dataclasses.replace(again, toa=again.toa + 1e-9))
    flipped = again.decisions.copy()
    flipped[1, 2] = ~flipped[1, 2]
    assert not one.same_results(dataclasses.replace(again, decisions=flipped))
