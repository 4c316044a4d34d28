"""UMa propagation for a run: same link structure as ray tracing, reproducible for a seed."""

import numpy as np

from veriloc_rt.config import config_from_dict
from veriloc_rt.propagation.cir import ADVERSARY_TX, NO_TX
from veriloc_rt.propagation.stochastic import uma_propagation
from veriloc_rt.world.geometry import build_geometry


def test_uma_links_mirror_the_traced_structure(tmp_path):
    cfg = config_from_dict({"trajectory": {"num_points": 30},
                            "propagation": {"model": "uma", "uma_mode": "pathloss_only"}})
    geo = build_geometry(cfg, tmp_path)
    active = np.arange(30) >= 10
    a = uma_propagation(geo, cfg.propagation, cfg.seed, adversary_points=active)
    b = uma_propagation(geo, cfg.propagation, cfg.seed, adversary_points=active)
    assert np.array_equal(a.bs_ue.tx_index, geo.serving)
    assert np.all(a.adv_ue.tx_index[active] == ADVERSARY_TX)
    assert np.all(a.adv_ue.tx_index[~active] == NO_TX) and not a.adv_ue.valid[~active].any()
    assert np.all(a.bs_adv.tx_index[~active] == NO_TX)
    # path-loss-only: one direct path per link at exactly the straight-line delay
    cir = a.bs_ue
    assert np.all(cir.valid.sum(-1) == 1)
    assert np.allclose(cir.first_path_delay(), cir.geometric_delay(), rtol=0, atol=1e-15)
    for name in ("bs_ue", "bs_adv", "adv_ue"):
        assert np.array_equal(getattr(a, name).gains, getattr(b, name).gains)
    c = uma_propagation(geo, cfg.propagation, cfg.seed + 1, adversary_points=active)
    assert not np.array_equal(a.bs_ue.gains, c.bs_ue.gains)
