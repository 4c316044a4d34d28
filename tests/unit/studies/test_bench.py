"""The fidelity sweep's bookkeeping: Pareto front and the settings swept.

The sweep itself (tracing and chains) runs in tests/integration/test_bench_compare.py.
"""

from __future__ import annotations

import pytest

from veriloc_rt.studies.bench import KNOBS, MODEL_KNOBS, QUICK_LEVELS, pareto_front, sweep_settings
from veriloc_rt.config import config_from_dict


def test_pareto_front_by_hand():
    # (cost, error): (3, 4) is dominated by (2, 3); (2, None) has no error; (5, 1) by (4, 1)
    cost = [1.0, 2.0, 3.0, 4.0, 2.0, 5.0]
    err = [5.0, 3.0, 4.0, 1.0, None, 1.0]
    assert pareto_front(cost, err).tolist() == [True, True, False, True, False, False]


def test_pareto_front_keeps_ties_and_zero_error():
    # two identical settings dominate neither each other; the reference (error 0) is on it
    assert pareto_front([1.0, 1.0, 9.0], [2.0, 2.0, 0.0]).tolist() == [True, True, True]


def test_sweep_settings_raytrace_quick():
    cfg = config_from_dict({})
    s = sweep_settings(cfg, quick=True)
    groups = {x.group for x in s}
    assert groups == {"raytrace", "waveform"}
    for g in groups:
        roles = [x.role for x in s if x.group == g]
        assert roles.count("config") == 1 and roles.count("reference") == 1
        ref = next(x for x in s if x.group == g and x.role == "reference")
        for k in KNOBS:
            # the reference is the highest level of every knob that computes the same physics
            if k.group == g and k.name not in MODEL_KNOBS:
                assert ref.patch[k.path] == QUICK_LEVELS.get(k.name, k.levels)[-1]
    # the config's own value is not swept again (1000 rays, depth 4, diffraction on,
    # exhaustive edge candidates)
    rays = [x.value for x in s if x.knob == "rays_per_source"]
    assert 1_000 not in rays and rays == [10_000, 200_000]
    assert [x.value for x in s if x.knob == "edge_candidates"] == ["sampled", "both"]
    assert [x.value for x in s if x.knob == "diffraction"] == [False]
    assert [x.value for x in s if x.knob == "max_depth"] == [3]
    assert sum(x.role == "noise floor" for x in s) == 1
    # time-domain settings apply the paths decimated (exact in band, tests/unit/test_channel.py)
    td = next(x for x in s if x.knob == "domain")
    assert td.patch == {"channel.domain": "time", "channel.time_decimation": 8,
                        "channel.time_front_end": "ofdm"}


def test_sweep_settings_uma_has_no_raytrace_group():
    cfg = config_from_dict({"propagation": {"model": "uma"}})
    s = sweep_settings(cfg)
    assert {x.group for x in s} == {"waveform"}
    assert len(s) == 2 + 1 + sum(len(k.levels) - 1 for k in KNOBS if k.group == "waveform")


@pytest.mark.parametrize("quick", [False, True])
def test_every_swept_setting_is_a_valid_config(quick):
    from veriloc_rt.studies.bench import patched_config

    cfg = config_from_dict({})
    for s in sweep_settings(cfg, quick):
        c = patched_config(cfg, s.patch)
        for path, v in s.patch.items():
            node = c
            for k in path.split("."):
                node = getattr(node, k)
            assert node == v or (isinstance(v, tuple) and tuple(node) == v)


def test_pareto_front_cost_resolution():
    # (cost, error). Without a resolution (1.00, 2) loses to (0.99, 2): 1 % cheaper, as accurate.
    # With 5 % the two costs are equal and neither dominates; (0.90, 2.5) is cheaper beyond the
    # resolution but less accurate, so it dominates nothing; (1.03, 1.0) is the same cost as
    # (1.00, 2) and (0.99, 2) within 5 % and more accurate, so it dominates both; (2.0, 0.0)
    # stays (the reference).
    cost = [1.00, 0.99, 0.90, 2.0]
    err = [2.0, 2.0, 2.5, 0.0]
    assert pareto_front(cost, err).tolist() == [False, True, True, True]
    assert pareto_front(cost, err, cost_rtol=0.05).tolist() == [True, True, True, True]
    cost2, err2 = cost + [1.03], err + [1.0]
    assert pareto_front(cost2, err2, cost_rtol=0.05).tolist() == [False, False, True, True, True]
    with pytest.raises(ValueError, match="cost_rtol"):
        pareto_front(cost, err, cost_rtol=-0.1)


def test_position_off_share_by_hand():
    # 5 points: (a) both fixed 0.5 m apart: same; (b) both fixed 3 m apart: off; (c) only the
    # setting has a fix: off; (d) only the reference: off; (e) neither: same -> 3 of 5 = 60 %
    import numpy as np

    from veriloc_rt.studies.bench import POSITION_TOL_M, chain_deviation
    from veriloc_rt.studies.diagnostics import BenignRun

    nan = np.nan
    ref_pos = np.array([[0.0, 0.0], [10.0, 0.0], [nan, nan], [5.0, 5.0], [nan, nan]])
    run_pos = np.array([[0.5, 0.0], [13.0, 0.0], [1.0, 1.0], [nan, nan], [nan, nan]])
    assert POSITION_TOL_M == 1.0

    def mk(pos):
        n = pos.shape[0]
        z = np.zeros((n, 3))
        return BenignRun(points=np.arange(n), toa=z, los_delay=z, az=z, geo_az=z, pos=pos,
                         truth=np.zeros((n, 2)), decisions=np.zeros((n, 4), bool),
                         seconds_per_point=0.1)

    m = chain_deviation(mk(run_pos), mk(ref_pos))
    assert m["position_off_pct"] == pytest.approx(60.0)
    assert m["fix_mismatch_pct"] == pytest.approx(40.0)
    assert chain_deviation(mk(ref_pos), mk(ref_pos))["position_off_pct"] == 0.0


def _cir(links: list[list[tuple]], depth: int):
    """A one-point CIR from per-slot [(tau s, power, (codes...)), ...], two UE antennas whose
    gains differ in phase only (as the synthetic array's)."""
    import numpy as np

    from veriloc_rt.propagation.cir import CIR

    b, n = len(links), max(1, max(len(p) for p in links))
    tau = np.full((1, b, n), -1.0)
    gains = np.zeros((1, b, 2, n), complex)
    inter = np.zeros((1, b, n, depth), np.uint8)
    valid = np.zeros((1, b, n), bool)
    for i, link in enumerate(links):
        for j, (t, p, seq) in enumerate(link):
            tau[0, i, j], valid[0, i, j] = t, True
            gains[0, i, :, j] = np.sqrt(p) * np.exp(1j * np.array([0.3, 1.9]))
            inter[0, i, j, :len(seq)] = seq
    z = np.zeros((1, b, n))
    return CIR(delays=tau, gains=gains, aoa_az=z, aoa_zen=z + 1.5, aod_az=z, aod_zen=z + 1.5,
               doppler=z, interactions=inter, valid=valid, tx_index=np.arange(b)[None],
               tx_pos=np.zeros((1, b, 3)), rx_pos=np.zeros((1, 3)),
               los=np.zeros((1, b), bool), carrier_frequency=3.5e9)


def test_channel_deviation_power_axes_by_hand():
    # Three serving links, D = diffraction (8), R = reflection (1), delays in us:
    #   link 0: ref D 1.00 (1), DR 1.01 (4), DRR 1.02 (1) pW; the setting misses the DR:
    #           P 2 vs 6 -> -4.7712 dB (off), strongest lost; first/strongest: setting D vs its
    #           tie D/DRR -> 0 dB, reference 1/4 -> -6.0206 dB
    #   link 1: ref D 2.00 (2); the setting adds DR 2.05 (1): P 3 vs 2 -> +1.7609 dB (not off),
    #           strongest found, first/strongest 0 dB in both
    #   link 2: ref D 3.00 (1); the setting has no path: -inf dB (off), strongest lost, no first
    # -> signed p50 of [-inf, -4.7712, 1.7609] is -4.7712; |dev| p90 of [1.76, 4.77, inf] is inf;
    #    2 of 3 off; strongest found 1 of 3; first/strongest p50 of [0, 0] = 0; its deviation
    #    p90 of [6.0206, 0] = 6.0206; first path off (lost) 1 of 3
    import numpy as np

    from veriloc_rt.studies.bench import POWER_TOL_DB, channel_deviation

    us = 1e-6
    D, R = 8, 1
    ref = _cir([[(1.00 * us, 1e-12, (D,)), (1.01 * us, 4e-12, (D, R)), (1.02 * us, 1e-12, (D, R, R))],
                [(2.00 * us, 2e-12, (D,))], [(3.00 * us, 1e-12, (D,))]], depth=4)
    run = _cir([[(1.00 * us, 1e-12, (D,)), (1.02 * us, 1e-12, (D, R, R))],
                [(2.00 * us, 2e-12, (D,)), (2.05 * us, 1e-12, (D, R))], []], depth=3)
    assert POWER_TOL_DB == 3.0
    m = channel_deviation(run, ref, np.array([0]))
    tol = 1e-4   # dB, the worked values are rounded to 4 decimals
    assert m["power_dev_db_p50"] == pytest.approx(-4.7712, abs=tol)
    assert m["power_absdev_db_p90"] == np.inf
    assert m["power_off_pct"] == pytest.approx(200 / 3)
    assert m["strongest_found_pct"] == pytest.approx(100 / 3)
    assert m["first_rel_power_db_p50"] == pytest.approx(0.0, abs=tol)
    assert m["first_rel_power_absdev_db_p90"] == pytest.approx(6.0206, abs=tol)
    assert m["first_path_off_pct"] == pytest.approx(100 / 3)
    # against itself: nothing off, everything found
    s = channel_deviation(ref, ref, np.array([0]))
    assert (s["power_dev_db_p50"], s["power_absdev_db_p90"], s["power_off_pct"]) == (0.0, 0.0, 0.0)
    assert s["strongest_found_pct"] == 100.0 and s["first_rel_power_absdev_db_p90"] == 0.0


def test_sweep_settings_full_raytrace_reference_is_the_converged_one():
    from veriloc_rt.studies.bench import RAYTRACE_REFERENCE

    cfg = config_from_dict({})
    ref = next(x for x in sweep_settings(cfg) if x.group == "raytrace" and x.role == "reference")
    # the study's converged level (docs/convergence.md), not the rays knob's highest level
    assert ref.patch["propagation.raytrace.rays_per_source"] == 10_000_000
    assert ref.patch["propagation.raytrace.max_depth"] == 4
    for path, v in RAYTRACE_REFERENCE.items():
        assert ref.patch[path] == v
    # the crop margin and diffraction stay at their highest levels
    assert ref.patch["scene.margin_m"] == 450.0 and ref.patch["propagation.raytrace.diffraction"] is True
    # a UE's three links fit one PathSolver call: 3 targets x depth x rays <= work_per_call
    assert 3 * 4 * 10_000_000 <= ref.patch["propagation.raytrace.work_per_call"]


@pytest.mark.parametrize("quick", [False, True])
def test_every_setting_of_a_sweep_has_its_own_key(quick):
    """The sweep keeps each setting's CIRs and chain run under Setting.key: two settings with
    one key would silently share (and overwrite) them."""
    settings = sweep_settings(config_from_dict({}), quick=quick)
    keys = [s.key for s in settings]
    assert len(keys) > 10 and len(set(keys)) == len(keys)


def test_diffuse_scattering_is_swept_but_not_in_the_reference():
    """Scattering changes the modelled physics: its setting traces diffusely (S > 0 without
    diffuse tracing would only dim the specular paths), and the reference stays smooth."""
    from veriloc_rt.studies.bench import MODEL_KNOBS

    settings = sweep_settings(config_from_dict({}))
    ref = next(x for x in settings if x.group == "raytrace" and x.role == "reference")
    path = "propagation.raytrace.materials.scattering_coefficient"
    assert "scattering_coefficient" in MODEL_KNOBS and path not in ref.patch
    rough = [x for x in settings if x.knob == "scattering_coefficient"]
    assert [x.value for x in rough] == [0.3]
    assert rough[0].patch == {path: 0.3, "propagation.raytrace.diffuse_reflection": True,
                              "propagation.raytrace.rays_per_source": 50_000}
    # the patched config is valid (diffuse tracing with S = 0 is rejected)
    from veriloc_rt.studies.bench import patched_config
    c = patched_config(config_from_dict({}), rough[0].patch)
    assert c.propagation.raytrace.diffuse_reflection and c.propagation.raytrace.materials.scattering_coefficient == 0.3


def test_more_exact_is_the_exact_one_sided_sign_test_by_hand():
    import numpy as np

    from veriloc_rt.studies.bench import more_exact

    def units(only_a, only_b, both, n=120):
        a, b = np.zeros(n, bool), np.zeros(n, bool)
        a[:only_a] = True
        b[only_a:only_a + only_b] = True
        a[100:100 + both] = b[100:100 + both] = True
        return a, b

    # 4 discordant units, all against a: P(X >= 4 | 4, 1/2) = 1/16 = 0.0625 > 0.05: unresolved
    a, b = units(4, 0, 3)
    assert not more_exact([a, b], 0.05).any()
    # 5 of 5: 1/32 = 0.031 < 0.05: b is more exact than a, not the reverse
    a, b = units(5, 0, 3)
    assert more_exact([a, b], 0.05).tolist() == [[False, False], [True, False]]
    # 7 against 1: P(X >= 7 | 8, 1/2) = (8 + 1) / 256 = 0.035: resolved; 6 against 2: 37/256 = 0.14: not
    a, b = units(7, 1, 0)
    assert more_exact([a, b], 0.05)[1, 0]
    a, b = units(6, 2, 0)
    assert not more_exact([a, b], 0.05)[1, 0]
    # units shared by both (concordant) do not count; a setting without units is never resolved
    assert not more_exact([a, None], 0.05).any()
    with pytest.raises(ValueError, match="alpha"):
        more_exact([a, b], 0.0)


def test_pareto_front_accuracy_resolution():
    # (cost, error): (1.00, 5.8) against (1.07, 2.5), within a 10 % cost resolution. Compared by
    # their shares the dearer one is more exact and dominates; when the sign test does not
    # resolve them (better all False between 0 and 1), both stay. (0.90, 9.0), clearly cheaper
    # and resolvably less exact than both, stays too; (2.0, 0.0) is the reference.
    import numpy as np

    cost, err = [1.00, 1.07, 0.90, 2.0], [5.8, 2.5, 9.0, 0.0]
    assert pareto_front(cost, err, cost_rtol=0.10).tolist() == [False, True, True, True]
    better = np.array(err)[:, None] < np.array(err)[None, :]
    better[1, 0] = better[0, 1] = False
    assert pareto_front(cost, err, cost_rtol=0.10, better=better).tolist() == [True, True, True, True]
    with pytest.raises(ValueError, match="better"):
        pareto_front(cost, err, better=np.zeros((3, 3), bool))


@pytest.mark.parametrize("antenna", ["isotropic", "tr38901"])
def test_bench_cirs_go_through_the_bs_antennas_as_a_run_does(antenna, tmp_path):
    """The bench's CIRs of a config with sector panels are the run's (``compute_propagation``
    applies the panels to the propagation's links): the same gains bit for bit, and with
    panels different from the isotropic links (else the check could not fail)."""
    import numpy as np

    from veriloc_rt.propagation.stochastic import uma_propagation
    from veriloc_rt.sim.engine import compute_propagation
    from veriloc_rt.studies.bench import with_bs_antenna
    from veriloc_rt.world.geometry import build_geometry

    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                            "topology": {"bs_antenna": antenna, "num_trps": 4},
                            "trajectory": {"num_points": 6}})
    geo = build_geometry(cfg, tmp_path / "scene")
    raw = uma_propagation(geo, cfg.propagation, cfg.seed).bs_ue
    bench = with_bs_antenna(raw, cfg, geo)
    run = compute_propagation(cfg, geo).bs_ue
    np.testing.assert_array_equal(bench.gains, run.gains)
    if antenna == "isotropic":
        assert bench is raw
    else:
        assert not np.allclose(np.abs(bench.gains), np.abs(raw.gains))
