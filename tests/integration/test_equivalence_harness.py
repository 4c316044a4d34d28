"""The equivalence harness on real runs: a version that differs only in its noise draws is
not distinguished; a version with a biased ToA is."""

import dataclasses
import importlib.util
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import veriloc_rt.phy.chain.positioning as positioning
import veriloc_rt.sim.runner as runner_mod
from veriloc_rt.constants import SPEED_OF_LIGHT

PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "equivalence.py"
CFG = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
       "run": {"scenarios": ["none"]}}
#: the injected versions' switches, read at each call (the harness sets a version's variables
#: around its runs)
SALT, BIAS = "VERILOC_RT_TEST_NOISE_SALT", "VERILOC_RT_TEST_TOA_BIAS_M"


@pytest.fixture
def eq():
    spec = importlib.util.spec_from_file_location("equivalence_harness_it", PATH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    yield mod
    del sys.modules[spec.name]


@pytest.fixture
def injected(monkeypatch):
    """Other noise draws (the chains' noise streams salted) and a ToA bias on TRP slot 1, each
    on when its environment variable is set."""
    real_stream = runner_mod.stream

    def stream(seed, name, *index):
        salt = os.environ.get(SALT)
        if name == "noise" and salt:
            return real_stream(seed, name, *index, int(salt))
        return real_stream(seed, name, *index)

    monkeypatch.setattr(runner_mod, "stream", stream)
    real_timing = positioning.TimingStage.__call__

    def timing(self, *a, **k):
        t = real_timing(self, *a, **k)
        bias = float(os.environ.get(BIAS, "0")) / SPEED_OF_LIGHT
        if not bias:
            return t
        toa = t.toa_s.copy()
        toa[1] += bias   # NaN stays NaN (not detected)
        return dataclasses.replace(t, toa_s=toa, rstd_s=toa - toa[0])

    monkeypatch.setattr(positioning.TimingStage, "__call__", timing)


@pytest.mark.heavy
def test_other_noise_is_not_distinguished_and_a_toa_bias_is(eq, injected, tmp_path):
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps(CFG))
    versions = {"A": eq.Version(), "B": eq.Version({SALT: "1"}), "C": eq.Version({BIAS: "1.0"})}
    samples = eq.collect(str(cfg), [1, 2], 40, versions, log=lambda s: None)
    # the versions did run differently: other noise moves the errors, the bias moves them more
    ea, eb, ec = (np.asarray(samples[v].errors["none"]) for v in "ABC")
    assert ea.size >= 60 and not np.array_equal(ea, eb)

    same = eq.compare(samples["A"], samples["B"])
    text, different = eq.report(str(cfg), [1, 2], 40, {"A": versions["A"], "B": versions["B"]},
                                samples, same, 0.05)
    assert not different, text
    assert "not distinguished" in text and "power at 0.05" in text

    biased = eq.compare(samples["A"], samples["C"])
    rejected = {t.family for t in biased if t.rejected}
    # a 1 m bias on one of three TRPs against ToA errors of ~0.1 m (p95, the benign links'):
    # the fixes move by about 1 m, their errors' CDFs no longer overlap
    assert "position error" in rejected, [(t.name, t.p) for t in biased]
    text, different = eq.report(str(cfg), [1, 2], 40, {"A": versions["A"], "B": versions["C"]},
                                {"A": samples["A"], "B": samples["C"]}, biased, 0.05)
    assert different and "DIFFERENT" in text


@pytest.mark.heavy
def test_a_ray_traced_config_is_traced_once_a_seed_for_both_versions(eq):
    """configs/ci-tiny.json (ray traced) at one seed: version A's run traces the drive's links
    (ray-tracing calls made, as the run's propagation statistics count them), version B's finds
    every call in the cache the harness shares between the versions (none made), and the two
    versions' samples are the same size."""
    versions = {"A": eq.Version(), "B": eq.Version({"VERILOC_RT_REFERENCE": "all"})}
    cfg = str(Path(__file__).resolve().parents[2] / "configs" / "ci-tiny.json")
    samples = eq.collect(cfg, [1], 6, versions, log=lambda s: None)
    assert samples["A"].tracer_calls > 0 and samples["B"].tracer_calls == 0, \
        (samples["A"].tracer_calls, samples["B"].tracer_calls)
    assert samples["A"].points == samples["B"].points == 6
