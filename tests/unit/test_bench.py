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
