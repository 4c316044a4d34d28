"""Whole runs on tiny scenes: the procedural canyon (ray traced and UMa) and a shipped
external XML scene with a CSV trajectory."""

import json

import numpy as np
import pytest

from veriloc_rt.cli import main
from veriloc_rt.phy.chain import STAGES

from .strict_json import assert_folder_strict
from .test_cli import ROOT


@pytest.mark.raytrace
def test_run_tiny_canyon_then_cached(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    cfg = ROOT / "configs" / "ci-tiny.json"
    assert main(["run", str(cfg), "--points", "12", "--out", "r1"]) == 0
    first = json.loads((tmp_path / "r1" / "propagation_summary.json").read_text())
    assert first["bs_to_ue"]["links"] == 36 and first["raytrace_stats"]["calls"] > 0
    assert main(["run", str(cfg), "--points", "12", "--out", "r2"]) == 0
    second = json.loads((tmp_path / "r2" / "propagation_summary.json").read_text())
    assert second["raytrace_stats"]["calls"] == 0  # everything came from the cache
    assert second["bs_to_ue"] == first["bs_to_ue"]
    run = json.loads((tmp_path / "r1" / "run.json").read_text())
    assert run["seed"] == 3 and run["versions"]["sionna-rt"].startswith("2.2")
    out = capsys.readouterr().out
    assert "bs_to_ue" in out and "with path" in out


def test_run_uma(tmp_path):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps({"propagation": {"model": "uma"}, "trajectory": {"num_points": 20}}))
    assert main(["run", str(cfg), "--out", str(tmp_path / "r")]) == 0
    s = json.loads((tmp_path / "r" / "propagation_summary.json").read_text())
    assert s["bs_to_ue"]["links_with_path_share"] == 1.0
    # the chain's stages partition each chain call: their sum cannot exceed the calls' total
    t = json.loads((tmp_path / "r" / "metrics.json").read_text())["timing_s"]
    stages = [t[f"{k}_total"] for k in STAGES]
    assert all(v > 0 for v in stages)
    assert sum(stages) <= t["chain_total"]
    assert all(isinstance(v, float) for v in t.values())  # seconds only
    r = json.loads((tmp_path / "r" / "metrics.json").read_text())["resources"]
    assert r["peak_rss_main_mib"] > 50  # numpy + scipy alone take more
    names = {f.name for f in assert_folder_strict(tmp_path / "r")}
    assert {"metrics.json", "run.json", "propagation_summary.json"} <= names


@pytest.mark.raytrace
def test_run_external_scene_with_csv(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = json.loads((ROOT / "configs" / "external-mini.json").read_text())
    cfg["scene"]["source"] = str(ROOT / "scenes" / "mini_canyon" / "scene.xml")
    cfg["trajectory"] = {"source": str(ROOT / "scenes" / "mini_canyon" / "trajectory.csv"),
                         "num_points": 8}
    cfg["propagation"]["raytrace"]["rays_per_source"] = 3000
    f = tmp_path / "c.json"
    f.write_text(json.dumps(cfg))
    assert main(["run", str(f), "--out", "r"]) == 0
    s = json.loads((tmp_path / "r" / "propagation_summary.json").read_text())
    # num_buildings: the mini canyon's XML holds all its blocks in one building shape
    assert s["num_points"] == 8 and s["num_buildings"] == 1 and s["num_triangles"] > 100
    assert s["bs_to_ue"]["links_with_path_share"] > 0.5


def test_run_uma_six_trps(tmp_path):
    """Six TRPs per point (comb 12 holds six TRPs' PRS and tags): six links per point, each
    point's six nearest sites, and the chain fixes from them."""
    from veriloc_rt.config import config_from_dict
    from veriloc_rt.sim.engine import run

    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                            "topology": {"num_trps": 6}, "nr": {"comb": 12},
                            "trajectory": {"num_points": 12}, "run": {"scenarios": ["none"]}})
    res = run(cfg, tmp_path / "r")
    g = res.geometry
    assert g.serving.shape == (12, 6)
    assert res.propagation.bs_ue.num_tx == 6
    d = np.linalg.norm(g.bs_pos[g.serving][..., :2] - g.ue.pos[:, None, :2], axis=2)
    assert np.all(np.diff(d, axis=1) >= -1e-3)        # nearest first, the reference first
    rows = res.rows["none"]
    assert sum(r.outcome == "success" for r in rows) >= 6   # a working chain fixes most points
    # the row's TRP columns and the links CSV agree with each other and with the geometry
    import csv
    with open(tmp_path / "r" / "none_results.csv") as fh:
        table = list(csv.DictReader(fh))
    with open(tmp_path / "r" / "none_links.csv") as fh:
        links = list(csv.DictReader(fh))
    assert len(links) == 12 * 6
    for k, row in enumerate(table):
        mine = [ln for ln in links if ln["index"] == str(k)]
        assert [int(ln["trp"]) for ln in mine] == list(range(6))
        assert int(row["bs_heard"]) == sum(ln["heard"] == "1" for ln in mine)
        assert int(row["bs_used"]) == sum(ln["used"] == "1" for ln in mine)
        assert row["bs_excluded"] == ";".join(ln["trp"] for ln in mine if ln["excluded"] == "1") \
            or len(row["bs_excluded"].split(";")) == sum(ln["excluded"] == "1" for ln in mine)
        np.testing.assert_allclose([float(ln["distance_m"]) for ln in mine],
                                   np.linalg.norm(g.bs_pos[g.serving[k]] - g.ue.pos[k], axis=1))
        used = [ln for ln in mine if ln["used"] == "1"]
        if used:   # per-anchor authentication: the share of the fix's TRPs whose tags verified
            assert float(row["auth_share"]) == sum(ln["tag_verified"] == "1"
                                                   for ln in used) / len(used)
        if row["x_est_auth"] != "" and all(ln["tag_verified"] == "1" for ln in mine
                                           if ln["heard"] == "1"):
            assert float(row["x_est_auth"]) == float(row["x_est"])   # the same TRPs, same fix
