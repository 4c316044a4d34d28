"""uma_cir: CIR structure, geometry, sub-clusters, Doppler and determinism (TR 38.901 V18 UMa)."""

import numpy as np
import pytest

from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.propagation.cir import CIR, ula_element_positions
from veriloc_rt.propagation.uma import uma_cir, uma_pathloss_db
from veriloc_rt.propagation.uma_params import cluster_parameters

FC = 3.5e9
LAM = SPEED_OF_LIGHT / FC
ELEM = ula_element_positions(5, LAM / 2, np.radians(30.0))
BS = np.array([[0.0, 289.0, 25.0], [250.0, -144.0, 25.0], [-250.0, -144.0, 25.0]])


def _scene(p=40, vel=(10.0, 0.0, 0.0)):
    rx = np.stack([np.linspace(-100, 100, p), np.linspace(-20, 20, p), np.full(p, 1.5)], -1)
    return dict(tx_pos=np.repeat(BS[None], p, 0), rx_pos=rx, rx_vel=np.tile(vel, (p, 1)),
                tx_vel=np.zeros((p, 3, 3)), tx_index=np.tile(np.arange(3), (p, 1)), fc_hz=FC,
                element_pos=ELEM)


def test_same_seed_same_cir_other_seed_differs():
    a = uma_cir(**_scene(), rng=np.random.default_rng(3))
    b = uma_cir(**_scene(), rng=np.random.default_rng(3))
    c = uma_cir(**_scene(), rng=np.random.default_rng(4))
    for name in ("delays", "gains", "aoa_az", "doppler", "valid", "los"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.allclose(a.gains, c.gains)


def test_pathloss_only_geometry_and_amplitude():
    sc = _scene()
    cir, par = uma_cir(**sc, rng=np.random.default_rng(1), mode="pathloss_only",
                       return_parameters=True)
    assert isinstance(cir, CIR) and cir.num_paths == 1 and cir.valid.all()
    d = sc["tx_pos"] - sc["rx_pos"][:, None, :]
    dist = np.linalg.norm(d, axis=-1)
    np.testing.assert_allclose(cir.delays[..., 0], dist / SPEED_OF_LIGHT, rtol=1e-14)
    # amplitude: PL of the drawn state plus shadowing, recomputed from the stable function
    d2 = np.linalg.norm(d[..., :2], axis=-1)
    pl = np.where(cir.los, uma_pathloss_db(d2, 25.0, 1.5, FC, True),
                  uma_pathloss_db(d2, 25.0, 1.5, FC, False))
    np.testing.assert_allclose(20 * np.log10(np.abs(cir.gains[:, :, 0, 0])), -(pl + par.sf_db),
                               atol=1e-9)
    # per-element phase: exp(+j 2 pi r.u / lambda) with u the unit vector UE -> BS
    u = d / dist[..., None]
    expect = np.exp(2j * np.pi * np.einsum("ptc,ac->pta", u, ELEM) / LAM)
    got = cir.gains[..., 0] / cir.gains[:, :, 2:3, 0]              # centre element is at 0
    np.testing.assert_allclose(got, expect, atol=1e-12)
    # Doppler of the direct path: v . u / lambda
    np.testing.assert_allclose(cir.doppler[..., 0], 10.0 * u[..., 0] / LAM, atol=1e-9)


def test_fast_fading_los_link_has_direct_ray_first():
    sc = _scene()
    los = np.ones((40, 3), bool)
    cir, par = uma_cir(**sc, rng=np.random.default_rng(2), los_state=los, return_parameters=True)
    np.testing.assert_allclose(cir.first_path_delay(), cir.geometric_delay(), rtol=1e-14)
    n_valid = cir.valid.sum(-1)
    assert n_valid.max() == 12 * 20 + 1 and cir.num_paths == 241
    # total power: PL + SF, minus at most the clusters cut at -25 dB (<= 11 x 10^-2.5 = 3.5 %)
    total = cir.path_power().sum(-1)
    ref = 10 ** (-(par.pathloss_db + par.sf_db) / 10)
    assert np.all(total <= ref * (1 + 1e-12)) and np.all(total >= ref * (1 - 11 * 10**-2.5))
    np.testing.assert_allclose(total[n_valid == 241], ref[n_valid == 241], rtol=1e-12)


def test_fast_fading_nlos_subclusters_table_7_5_5():
    sc = _scene(p=10)
    cir = uma_cir(**sc, rng=np.random.default_rng(5), los_state=np.zeros((10, 3), bool))
    c_ds = cluster_parameters(False, FC)["c_ds_s"]
    for k in range(10):
        for j in range(3):
            v = cir.valid[k, j]
            tau = cir.delays[k, j, v]
            pw = cir.path_power()[k, j, v]
            uniq, counts = np.unique(np.round(tau * 1e15), return_counts=True)
            n_clusters = v.sum() // 20
            # two strongest clusters -> 3 sub-clusters each: N + 4 distinct delays
            assert uniq.size == n_clusters + 4
            # 10/6/4 rays at +0, +1.28 c_DS, +2.56 c_DS of the strongest cluster
            top = np.isclose(pw, pw.max(), rtol=1e-12, atol=0)       # the 20 equal-power rays
            assert top.sum() == 20
            strongest = tau[top].min()
            for off, nray in ((0.0, 10), (1.28, 6), (2.56, 4)):
                assert np.sum(np.isclose(tau, strongest + off * c_ds, rtol=0, atol=1e-15)) == nray
            # NLoS: first arrival at the geometric delay (no 7.6.9 excess delay)
            assert tau.min() == pytest.approx(cir.geometric_delay()[k, j], rel=1e-14)


def test_fast_fading_doppler_bounded_by_speed():
    cir = uma_cir(**_scene(vel=(0.0, 20.0, 0.0)), rng=np.random.default_rng(6))
    assert np.all(np.abs(cir.doppler) <= 20.0 / LAM * (1 + 1e-12))
    assert np.abs(cir.doppler[cir.valid]).max() > 0.5 * 20.0 / LAM


def test_empty_slots_are_masked_without_nan():
    sc = _scene(p=5)
    sc["tx_index"][:, 1] = -1
    sc["tx_pos"][:, 1] = np.nan
    for mode in ("fast_fading", "pathloss_only"):
        cir = uma_cir(**sc, rng=np.random.default_rng(0), mode=mode)
        assert not cir.has_path()[:, 1].any() and cir.has_path()[:, [0, 2]].all()
        assert np.all(cir.gains[:, 1] == 0) and not cir.los[:, 1].any()
        for name in ("delays", "gains", "aoa_az", "aoa_zen", "aod_az", "aod_zen", "doppler"):
            assert np.all(np.isfinite(getattr(cir, name))), name


def test_los_fraction_follows_probability_over_points():
    sc = _scene(p=400)
    cir = uma_cir(**sc, rng=np.random.default_rng(8), mode="pathloss_only",
                  spatial_consistency=False)
    assert cir.los.any() and not cir.los.all()


@pytest.mark.parametrize("kwargs, exc, word", [
    ({"mode": "raytrace"}, ValueError, "mode"),
    ({"rng": 3}, TypeError, "rng"),
    ({"fc_hz": -1.0}, ValueError, "fc_hz"),
    ({"tx_index": np.zeros((40, 3))}, ValueError, "tx_index"),
    ({"rx_pos": np.zeros((40, 2))}, ValueError, "rx_pos"),
])
def test_rejects_bad_arguments(kwargs, exc, word):
    sc = _scene()
    sc["rng"] = np.random.default_rng(0)
    sc.update(kwargs)
    with pytest.raises(exc, match=word):
        uma_cir(**sc)
