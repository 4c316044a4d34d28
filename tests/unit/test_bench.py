"""The fidelity sweep's bookkeeping: Pareto front and the settings swept.

The sweep itself (tracing and chains) runs in tests/integration/test_bench_compare.py.
"""

from __future__ import annotations

import pytest

from veriloc_rt.bench import KNOBS, QUICK_LEVELS, pareto_front, sweep_settings
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
            if k.group == g:   # the reference is the highest level of every knob
                assert ref.patch[k.path] == QUICK_LEVELS.get(k.name, k.levels)[-1]
    # the config's own value is not swept again (50 000 rays, depth 4, diffraction on)
    rays = [x.value for x in s if x.knob == "rays_per_source"]
    assert 50_000 not in rays and rays == [10_000, 200_000]
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
    from veriloc_rt.bench import _patched

    cfg = config_from_dict({})
    for s in sweep_settings(cfg, quick):
        c = _patched(cfg, s.patch)
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

    from veriloc_rt.bench import POSITION_TOL_M, _chain_deviation
    from veriloc_rt.diagnostics import BenignRun

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

    m = _chain_deviation(mk(run_pos), mk(ref_pos))
    assert m["position_off_pct"] == pytest.approx(60.0)
    assert m["fix_mismatch_pct"] == pytest.approx(40.0)
    assert _chain_deviation(mk(ref_pos), mk(ref_pos))["position_off_pct"] == 0.0
