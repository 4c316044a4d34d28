"""The tags' margin and the link-budget block (veriloc_rt/report/link_budget.py) against hand
derivations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.report.link_budget import (MULTIPATH_PENALTY_DB, TAG_THRESHOLD_DB,
                                           format_link_budget, link_budget_block,
                                           multipath_penalty_db, tag_margin_db)

#: sums of a few doubles
EXACT = 1e-12


def test_margin_by_hand():
    # -10 dB per RE and antenna, 5 antennas combined: -10 + 10 log10 5 = -3.0103 dB at the
    # decoder; HMAC's bench threshold -2.5 dB: -0.5103 dB, less a 4.3 dB penalty: -4.8103 dB
    m = tag_margin_db([-10.0], 5, "hmac", 4.3)
    assert m[0] == pytest.approx(-10.0 + 6.989700043360188 + 2.5 - 4.3, abs=EXACT)
    # DS needs 2 dB more on the bench (-0.5 against -2.5 dB)
    d = tag_margin_db([-10.0], 5, "ds", 4.3)
    assert m[0] - d[0] == pytest.approx(2.0, abs=EXACT)
    assert TAG_THRESHOLD_DB == {"hmac": -2.5, "ds": -0.5}
    # one antenna, no penalty: the margin is the SNR over the threshold
    assert tag_margin_db([1.0], 1, "hmac", 0.0)[0] == pytest.approx(3.5, abs=EXACT)
    assert math.isnan(tag_margin_db([float("nan")], 5, "hmac", 0.0)[0])
    with pytest.raises(ValueError):
        tag_margin_db([0.0], 5, "none", 0.0)


def test_penalty_by_channel_kind():
    def pen(prop):
        return multipath_penalty_db(config_from_dict({"propagation": prop}).propagation)

    assert pen({"model": "uma", "uma_mode": "pathloss_only"}) == 0.0   # one path per link
    assert pen({"model": "uma", "uma_mode": "fast_fading"}) == MULTIPATH_PENALTY_DB["multipath"]
    assert pen({"model": "raytrace"}) == MULTIPATH_PENALTY_DB["multipath"] == 4.3


def test_block_by_hand():
    # two points of three TRPs: point 0 uses TRPs 0 and 1, point 1 has no fix
    links = {"index": np.array([0, 0, 0, 1, 1, 1]),
             "rx_power_dbm": np.array([-90.0, -100.0, -110.0, -95.0, -105.0, -115.0]),
             "snr_re_db": np.array([0.0, -8.0, -20.0, -5.0, -15.0, -25.0]),
             "heard": np.array([1, 1, 0, 1, 1, 0], bool),
             "tag_verified": np.array([1, 0, 0, 1, 0, 0], bool),
             "used": np.array([1, 1, 0, 0, 0, 0], bool)}
    b = link_budget_block(links, 4, 1.0, scenario="none")
    g = 10 * math.log10(4)   # 6.0206 dB
    assert b["links"] == 6 and b["rx_antennas"] == 4 and b["multipath_penalty_db"] == 1.0
    assert b["rx_power_dbm"]["p50"] == pytest.approx(-102.5, abs=EXACT)
    assert b["snr_re_db"]["p50"] == pytest.approx(-11.5, abs=EXACT)
    # HMAC margins snr + 6.02 + 2.5 - 1.0 >= 0 for snr >= -7.52: 0 and -5 dB (2 of 6);
    # DS (threshold -0.5): snr >= -5.52: the same two
    assert b["above_hmac_threshold_share"] == pytest.approx(2 / 6, abs=EXACT)
    assert b["above_ds_threshold_share"] == pytest.approx(2 / 6, abs=EXACT)
    # the weakest used TRP of point 0 is TRP 1 (-8 dB); point 1 has no fix
    w = b["weakest_used_hmac_margin_db"]
    assert w["p50"] == pytest.approx(-8.0 + g + 2.5 - 1.0, abs=EXACT)
    assert w["p5"] == w["p95"] == w["p50"]
    assert b["heard_share"] == pytest.approx(4 / 6, abs=EXACT)
    assert b["tag_verified_share"] == pytest.approx(2 / 6, abs=EXACT)
    lo, hi = b["heard_share_ci95"]
    assert lo < 4 / 6 < hi
    line = format_link_budget(b)
    assert "\n" not in line and "HMAC" in line and "heard 67 %" in line
    assert link_budget_block({**links, "index": np.array([], int)}, 4, 0.0) == {}
