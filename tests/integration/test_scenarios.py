"""The four scenarios end to end: result files, metrics against the CSVs, attack physics, resume.

Independent references:
* metrics.json is recomputed here from the CSV rows with the paper's definitions (outcomes over
  all points for 'none' and over the attack window for an attack; correct decisions = accepted
  fixes when benign, rejected points under attack);
* jamming: a 48 dBm jammer tens of metres away against <= 24 dBm BSs hundreds of metres away
  leaves the PRS ~60 dB below the interference, beyond the ~41 dB correlation gain of a 10-slot
  comb-6 frame, so every jammed point whose jammer link has a path is a service failure;
* FBS: the spoofer's replica delays put the standard-PRS fix at the target, ``target_offset_m``
  from the UE (the adversary's ideal estimate), so the error of a spoofed fix is that offset.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.sim.engine import run
from veriloc_rt.report.results import CSV_COLUMNS
from veriloc_rt.detectors.outcomes import DETECTORS, OUTCOMES
from veriloc_rt.studies.fbs_bias import biased_fix_outcomes

from .test_cli import ROOT, cli
from .test_detection_roc import check_statistics_and_roc

#: FBS target error: the multilateration of exact spoofed RSTDs lands within the receiver's
#: noise-limited accuracy of the target (benign p95 ~1.5 m on UMa path loss); 5 m is 3x that
FBS_TOL_M = 5.0


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _clopper_pearson(flags):
    """The exact 95 % interval of the share of true flags from the beta quantiles (Clopper &
    Pearson 1934), None without flags; rel 1e-9 against binomtest's root finding."""
    from scipy.stats import beta

    n, k = len(flags), sum(flags)
    if not n:
        return None
    return [0.0 if k == 0 else beta.ppf(0.025, k, n - k + 1),
            1.0 if k == n else beta.ppf(0.975, k + 1, n - k)]


def _pct(flags):
    """The share of true flags, a fraction (metrics.json's unit)."""
    return sum(flags) / len(flags) if flags else None


def check_run(res, out) -> None:
    """Files, metrics recomputed from the CSVs, and the attack physics of a finished run."""
    cfg = res.config
    for name in ("metrics.json", "run.json", "outcomes.png", "detection_rates.png",
                 "scene_top_view.png"):
        assert (out / name).stat().st_size > 0
    metrics = json.loads((out / "metrics.json").read_text())
    adv_path = res.propagation.adv_ue.valid.any(axis=(1, 2))          # [num_points]
    for scenario in cfg.run.scenarios:
        rows = _csv(out / f"{scenario}_results.csv")
        assert tuple(rows[0].keys()) == CSV_COLUMNS
        assert list(rows[0])[:6] == ["Time", "HMAC", "DigSig", "ABSA", "Handshake", "Tracking"]
        assert len(rows) == res.geometry.num_points
        m = metrics["scenarios"][scenario]
        sel = rows if scenario == "none" else [r for r in rows if r["attack"] == "1"]
        for k in OUTCOMES:
            assert m["outcomes"][k] == pytest.approx(_pct([r["outcome"] == k for r in sel]))
            assert m["outcomes"][k + "_ci95"] == pytest.approx(
                _clopper_pearson([r["outcome"] == k for r in sel]), rel=1e-9, abs=1e-15)
        for d in DETECTORS:
            if scenario == "none":
                fixes = [r for r in sel if r["outcome"] != "service_failure"]
                want = _pct([r[d] == "1" for r in fixes])
            else:
                want = _pct([r[d] == "0" for r in sel])
            assert m["correct_decision_rate"][d] == pytest.approx(want)
            flags = ([r[d] == "1" for r in fixes] if scenario == "none"
                     else [r[d] == "0" for r in sel])
            assert m["correct_decision_rate"][d + "_ci95"] == pytest.approx(
                _clopper_pearson(flags), rel=1e-9, abs=1e-15)
        for r in sel:
            i = int(r["index"])
            if scenario == "jamming" and adv_path[i]:
                assert r["outcome"] == "service_failure", f"jammed point {i} kept a fix"
        if scenario == "fbs":
            err = np.array([float(r["error_m"]) for r in sel
                            if r["outcome"] != "service_failure" and adv_path[int(r["index"])]])
            assert err.size > 0
            off = cfg.threats.fbs.target_offset_m
            assert np.median(np.abs(err - off)) < FBS_TOL_M
        assert (out / f"{scenario}_timeseries.png").stat().st_size > 0
    check_statistics_and_roc(out, cfg)


def test_uma_four_scenarios_and_resume(tmp_path):
    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                            "trajectory": {"num_points": 12}, "seed": 5})
    full = run(cfg, tmp_path / "full")
    check_run(full, tmp_path / "full")
    # an interrupted run: 'none' finished, 'fbs' stopped after 7 points (with a torn last line),
    # nothing after; --resume must end with exactly the uninterrupted files
    part = tmp_path / "part"
    run(cfg, part)
    lines = (part / "fbs_results.csv").read_text().splitlines(keepends=True)
    (part / "fbs_results.csv").write_text("".join(lines[:8]) + lines[8][:15])
    for s in ("meaconing", "jamming"):
        (part / f"{s}_results.csv").unlink()
    (part / "metrics.json").unlink()
    resumed = run(cfg, part, resume=True)
    for s in cfg.run.scenarios:
        assert (part / f"{s}_results.csv").read_bytes() == (tmp_path / "full" / f"{s}_results.csv").read_bytes()
    assert resumed.metrics["scenarios"] == full.metrics["scenarios"]


def test_resume_refuses_another_config(tmp_path):
    cfg = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
           "trajectory": {"num_points": 4}, "run": {"scenarios": ["none"]}}
    f = tmp_path / "c.json"
    f.write_text(json.dumps(cfg))
    assert cli("run", f, "--out", tmp_path / "o").returncode == 0
    r = cli("run", f, "--out", tmp_path / "o", "--resume", "--seed", "9")
    assert r.returncode == 2 and r.stderr.startswith("error: --resume: ")
    assert len(r.stderr.strip().splitlines()) == 1
    r = cli("run", f, "--out", tmp_path / "empty", "--resume")
    assert r.returncode == 2 and "nothing to resume" in r.stderr


@pytest.mark.raytrace
def test_raytraced_tiny_canyon_four_scenarios(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    data = json.loads((ROOT / "configs" / "ci-tiny.json").read_text())
    data["trajectory"]["num_points"] = 16
    cfg = config_from_dict(data)
    res = run(cfg, tmp_path / "r")
    check_run(res, tmp_path / "r")
    # the adversary's links are traced only in the attack window, where the scenarios use them
    from veriloc_rt.propagation.cir import NO_TX

    window = cfg.run.attack_points(res.geometry.num_points)
    assert 0 < window.sum() < window.size
    assert np.array_equal(res.propagation.adv_ue.tx_index[:, 0] != NO_TX, window)
    assert np.array_equal(np.all(res.propagation.bs_adv.tx_index != NO_TX, axis=1), window)


def test_two_workers_give_the_serial_result(tmp_path):
    """Chains in forked workers, detectors in the parent: the same bytes as the serial run."""
    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                            "trajectory": {"num_points": 8}, "seed": 4,
                            "run": {"scenarios": ["none", "meaconing"]}})
    serial = run(cfg, tmp_path / "s", workers=1)
    parallel = run(cfg, tmp_path / "p", workers=2)
    for s in cfg.run.scenarios:
        assert (tmp_path / "s" / f"{s}_results.csv").read_bytes() == (tmp_path / "p" / f"{s}_results.csv").read_bytes()
    assert parallel.metrics["scenarios"] == serial.metrics["scenarios"]
    with pytest.raises(ValueError, match="workers"):
        run(cfg, tmp_path / "x", workers=0)


def test_fbs_bias_mode_outcomes_follow_the_geometry():
    """Mode 'bias' on UMa path loss: the 48 dBm spoofer overshadows the spoofed BS by tens of dB,
    so the chain measures the true RSTDs plus the bias, and each attack point's outcome must be
    the one the geometry alone gives (threats.biased_fix_outcomes: exact RSTDs, the same
    solver). Tolerance: 1 point in 20, for a point whose biased hyperbolas meet within the
    receiver's ~1 m noise of the residual check or the success threshold."""
    cfg = config_from_dict({
        "seed": 4, "propagation": {"model": "uma"}, "trajectory": {"num_points": 40},
        "run": {"scenarios": ["fbs"], "evaluate_encrypted": False},
        "threats": {"fbs": {"mode": "bias", "bias_s": 1.5e-6, "spoofed_slots": [1]}}})
    res = run(cfg)
    rows = [r for r in res.rows["fbs"] if r.attack]
    assert len(rows) == 20
    geo = res.geometry
    idx = [r.index for r in rows]
    want = biased_fix_outcomes(geo.bs_pos[geo.serving[idx]], geo.ue.pos[idx], 1.5e-6, [1],
                               cfg.run.success_threshold_m, cfg.receiver.max_residual_m)
    got = [r.outcome for r in rows]
    assert sum(g != w for g, w in zip(got, want)) <= 1, list(zip(got, want))
    assert len(set(want)) > 1 or want[0] != "success"  # the bias did something to the fix


def test_ds_chain_on_the_hmac_timing_matches_its_own_call(tmp_path):
    """run.digsig 'separate' decodes the DS-tagged grid's tags on the HMAC-tagged chain's timing
    (``ChainPlan.tags_on(...)``). Second method: the DS chain's own full call, its own
    ToA on its own grid. The two grids share the PRS REs (same noise stream; the tags sit on
    other REs) up to the relay's gain control, which sees the tags: every verdict must agree."""
    from veriloc_rt.sim.engine import compute_propagation
    from veriloc_rt.sim.run_folder import run_keys
    from veriloc_rt.sim.runner import ScenarioRunner
    from veriloc_rt.world.geometry import build_geometry

    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                            "trajectory": {"num_points": 12}, "seed": 4,
                            "run": {"evaluate_encrypted": False}})
    geo = build_geometry(cfg, tmp_path)
    prop = compute_propagation(cfg, geo)
    runner = ScenarioRunner(cfg, geo, prop, run_keys(cfg, len(geo.bs_pos)))
    seen = []
    for scenario in cfg.run.scenarios:
        for i in range(geo.num_points):
            runner.clear_cache()
            std = runner.chain_result("standard", scenario, i)
            runner.clear_cache()
            reuse = runner.chain_result("ds", scenario, i, std)
            runner.clear_cache()
            own = runner.chain_result("ds", scenario, i)
            np.testing.assert_array_equal(reuse.tags_valid, own.tags_valid)
            np.testing.assert_array_equal(reuse.detected, own.detected)
            seen.extend(own.tags_valid)
    assert 0 < sum(seen) < len(seen)   # both verdicts occur


def test_progress_counts_the_point_scenarios_each_scenario_computes(tmp_path):
    """The first scenario computes the later attack scenarios in the attack window with its own
    chains, so its progress runs over n + 3 x (window points) point-scenarios (counted from the
    config's window: independent of the runner), every call increasing; the later scenarios find
    every chain computed and report their points."""
    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                            "trajectory": {"num_points": 12}, "seed": 5})
    calls = []
    run(cfg, None, progress=lambda label, done, total: calls.append((label, done, total)), workers=1)
    window = int(np.sum(cfg.run.attack_points(12)))
    assert window > 0
    none = [(d, t) for lab, d, t in calls if lab == "none"]
    assert {t for _, t in none} == {12 + 3 * window}
    assert [d for d, _ in none] == sorted({d for d, _ in none}) and none[-1][0] == 12 + 3 * window
    for s in ("fbs", "meaconing", "jamming"):
        assert [(d, t) for lab, d, t in calls if lab == s] == [(i, 12) for i in range(1, 13)]
