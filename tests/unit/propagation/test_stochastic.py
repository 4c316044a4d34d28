"""UMa / UMi propagation for a run: same link structure as ray tracing, reproducible for a seed."""

import dataclasses

import numpy as np

from veriloc_rt.config import config_from_dict
from veriloc_rt.propagation.cir import ADVERSARY_TX, NO_TX
from veriloc_rt.propagation.stochastic import stochastic_propagation, uma_propagation
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


def test_umi_model_draws_umi_links(tmp_path):
    """propagation.model 'umi' draws the UMi table (its own random streams), same structure."""
    cfg = config_from_dict({"trajectory": {"num_points": 30}, "propagation": {"model": "umi"}})
    geo = build_geometry(cfg, tmp_path)
    a = stochastic_propagation(geo, cfg.propagation, cfg.seed)
    assert a.stats["model"] == "umi/fast_fading"
    assert a.bs_ue.meta["model"] == "3GPP TR 38.901 UMi-Street Canyon"
    assert np.array_equal(a.bs_ue.tx_index, geo.serving)
    # NLoS links carry 19 clusters x 20 rays, LoS 12 x 20 + 1 (Table 7.5-6 UMi)
    n_valid_max = a.bs_ue.valid.sum(-1)[~a.bs_ue.los].max()
    assert n_valid_max <= 19 * 20 and a.bs_ue.delays.shape[-1] in (19 * 20, 12 * 20 + 1)
    u = stochastic_propagation(geo, dataclasses.replace(cfg.propagation, model="uma"), cfg.seed)
    assert u.bs_ue.meta["model"] == "3GPP TR 38.901 UMa"


def test_pathloss_offsets_scale_the_same_draws(tmp_path):
    """The offsets shift the serving links' path loss by exactly the configured dB per LoS state
    and change nothing else (same rays, delays, angles; adversary links untouched)."""
    cfg = config_from_dict({"trajectory": {"num_points": 30}, "propagation": {"model": "umi"}})
    geo = build_geometry(cfg, tmp_path)
    a = stochastic_propagation(geo, cfg.propagation, cfg.seed)
    prop = dataclasses.replace(cfg.propagation, stochastic_pathloss_offset_los_db=1.5,
                               stochastic_pathloss_offset_nlos_db=-4.0)
    b = stochastic_propagation(geo, prop, cfg.seed)
    assert np.array_equal(a.bs_ue.delays, b.bs_ue.delays)
    assert np.array_equal(a.bs_ue.los, b.bs_ue.los)
    pa, pb = a.bs_ue.path_power().sum(-1), b.bs_ue.path_power().sum(-1)
    used = a.bs_ue.tx_index != NO_TX
    shift = 10 * np.log10(pa[used] / pb[used])
    expect = np.where(a.bs_ue.los[used], 1.5, -4.0)
    np.testing.assert_allclose(shift, expect, atol=1e-9)
    assert np.array_equal(a.adv_ue.gains, b.adv_ue.gains)
    assert np.array_equal(a.bs_adv.gains, b.bs_adv.gains)


def test_compare_twin_rule():
    """auto: UMi when the median BS height is at or below the median roof, UMa above it or
    without buildings; an explicit setting wins."""
    from types import SimpleNamespace

    from veriloc_rt.studies.compare import choose_twin

    def geo(bs_z, roofs):
        return SimpleNamespace(bs_pos=np.array([[0.0, 0.0, z] for z in bs_z]),
                               scene=SimpleNamespace(heights=np.array(roofs, float)))

    auto = config_from_dict({})
    assert choose_twin(auto, geo([25, 25, 25], [15, 15]))["model"] == "uma"
    assert choose_twin(auto, geo([10, 10, 30], [15, 18, 12]))["model"] == "umi"
    assert choose_twin(auto, geo([10], []))["model"] == "uma"
    forced = config_from_dict({"propagation": {"stochastic_twin": "umi"}})
    t = choose_twin(forced, geo([25], [15]))
    assert t["model"] == "umi" and t["rule"] == "propagation.stochastic_twin"
