"""The Gaussian range-error overbound (``receiver.range_error_model`` 'overbound').

Independent references: the overbound of a large Gaussian sample is its std (the tail
quantiles of N(0, s) are s z(1 - q)); on a heavy-tailed sample the overbound's tail
probability is at least the empirical one at every checked sample (the definition, evaluated
with scipy's normal survival function); the table lookup against bins written out by hand; the
fix stage's stds against max(CRLB std, table sigma); the shipped table says what it is.
"""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest
from scipy.stats import norm

from veriloc_rt.config import config_from_dict
from veriloc_rt.phy.chain.receiver import (FixStage, RangeOverbound, gaussian_overbound,
                                           range_std)

#: the largest ratio over the tail quantiles (0.5 % .. 10 %) of a 40000-sample Gaussian: each
#: quantile's relative sampling error sqrt(q (1 - q) / n) / (phi(z) z) is 0.7 % at q = 0.1 and
#: 1.7 % at q = 0.005, the max over the quantiles a few of those
GAUSS_REL = 0.05


def test_overbound_of_a_gaussian_is_its_std():
    y = np.random.default_rng(4).normal(0.0, 7.0, 40_000)
    assert gaussian_overbound(y, 0.005) == pytest.approx(7.0, rel=GAUSS_REL)


def test_overbound_covers_both_heavy_tails():
    rng = np.random.default_rng(5)
    # late first arrivals: a Gaussian core and an exponential late tail, a few early ones
    y = np.concatenate([rng.normal(0, 3, 4000), rng.exponential(60.0, 600),
                        -rng.exponential(10.0, 100)])
    p_min = 0.005
    s = gaussian_overbound(y, p_min)
    n = y.size
    for side in (np.sort(y)[::-1], np.sort(-y)[::-1]):
        q = np.arange(1, n + 1) / n
        keep = (side > 0) & (q >= p_min) & (q <= 0.1)
        # the Gaussian's tail at each sample holds at least its empirical tail probability
        assert np.all(norm.sf(side[keep] / s) >= q[keep] - 1e-12)
    # and it is the smallest such sigma: 1 % less misses some sample
    s2 = 0.99 * s
    miss = False
    for side in (np.sort(y)[::-1], np.sort(-y)[::-1]):
        q = np.arange(1, n + 1) / n
        keep = (side > 0) & (q >= p_min) & (q <= 0.1)
        miss |= bool(np.any(norm.sf(side[keep] / s2) < q[keep]))
    assert miss


def test_table_lookup_clamps_to_its_bins():
    t = RangeOverbound([0.0, 10.0, 20.0], [50.0, 5.0])
    snr = np.array([-30.0, 0.0, 9.99, 10.0, 19.0, 40.0, np.nan])
    np.testing.assert_array_equal(t.sigma(snr), [50.0, 50.0, 50.0, 5.0, 5.0, 5.0, 50.0])
    with pytest.raises(ValueError):
        RangeOverbound([0.0, 10.0], [1.0, 2.0])


def test_fix_stage_takes_the_larger_std(monkeypatch):
    t = RangeOverbound([0.0, 10.0, 20.0], [50.0, 0.5])
    stage = FixStage(10.0, True, 3.6e6, 3.0, overbound=t)
    snr = np.array([5.0, 25.0])
    want = np.maximum(range_std(snr, 3.6e6, 3.0), t.sigma(snr))
    assert want[0] == 50.0 and want[1] == range_std(snr, 3.6e6, 3.0)[1]
    seen = {}

    class Spy:
        def __init__(self, **kw):
            pass

        def __call__(self, bs, rstd, ref, det, range_std_m):
            seen["sig"] = range_std_m
            return None

    monkeypatch.setattr("veriloc_rt.phy.chain.receiver.Multilaterator", Spy)
    stage.solve(np.ones(2, bool), np.zeros(2), snr, np.zeros((2, 3)), 1.5)
    np.testing.assert_array_equal(seen["sig"], want)


def test_shipped_table_says_what_it_is():
    d = json.loads(resources.files("veriloc_rt").joinpath("data", "range_overbound.json")
                   .read_text())
    assert "this simulator" in d["what"] and "fast_fading" in d["channel"]
    assert d["made_by"].startswith("scripts/calibrate_range_overbound.py")
    t = RangeOverbound.shipped()
    assert np.all(t.sigma_m > 0) and sum(d["count"]) == d["links"]


def test_config_selects_the_model():
    assert config_from_dict({}).receiver.range_error_model == "auto"
    cfg = config_from_dict({"receiver": {"range_error_model": "overbound"}})
    assert cfg.receiver.range_error_model == "overbound"


@pytest.mark.parametrize("prop, model", [
    ({"model": "uma", "uma_mode": "pathloss_only"}, "crlb"),   # no multipath: the CRLB holds
    ({"model": "umi", "uma_mode": "pathloss_only"}, "crlb"),
    ({"model": "uma", "uma_mode": "fast_fading"}, "overbound"),   # late, heavy-tailed arrivals
    ({"model": "umi"}, "overbound"),
    ({"model": "raytrace"}, "overbound"),
])
def test_auto_model_follows_the_channel(prop, model):
    from veriloc_rt.config.channel import resolved_range_error_model
    from veriloc_rt.phy.chain import PositioningChain

    cfg = config_from_dict({"propagation": prop, "topology": {"num_trps": 9}})
    assert resolved_range_error_model(cfg.receiver, cfg.propagation.model,
                                      cfg.propagation.uma_mode) == model
    chain = PositioningChain.from_config(cfg, max_doppler_hz=100.0)
    assert (chain.fix.overbound is not None) == (model == "overbound")
    # an explicit choice is kept whatever the channel
    fixed = config_from_dict({"propagation": prop, "receiver": {"range_error_model": "crlb"}})
    assert resolved_range_error_model(fixed.receiver, fixed.propagation.model,
                                      fixed.propagation.uma_mode) == "crlb"
