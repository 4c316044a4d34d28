"""``veriloc-rt bench --quick`` and ``veriloc-rt compare`` on the CI-sized default config.

Both trace a tiny canyon (configs/ci-tiny.json) with Sionna RT; the checks are on the files
and on properties that must hold whatever the traced numbers are: the reference deviates from
itself by exactly 0, every time is positive, each group has a non-empty Pareto front holding
its most accurate setting, both models of the comparison ran every scenario on the same trajectory.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binomtest

from veriloc_rt.studies.bench import ACCURACY_ALPHA, COST_RTOL, PARETO_METRIC
from veriloc_rt.cli import main
from veriloc_rt.detectors.outcomes import DETECTORS
from veriloc_rt.fileio import TMP_MARK

from .strict_json import assert_strict_json

CONFIG = str(Path(__file__).resolve().parents[2] / "configs" / "ci-tiny.json")

pytestmark = [pytest.mark.raytrace, pytest.mark.heavy]
#: the files each command placed by a rename (os.replace), by command
RENAMED: dict[str, set] = {}


@contextlib.contextmanager
def renames(command: str):
    """Record every file placed by ``os.replace`` (a temporary file renamed over the target)."""
    placed = RENAMED.setdefault(command, set())
    real = os.replace

    def spy(src, dst):
        real(src, dst)
        placed.add(Path(dst).resolve())

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(os, "replace", spy)
        yield


def assert_written_atomically(out: Path, command: str, names) -> None:
    """Each output was renamed into place (never written in place), and no temporary is left."""
    for name in names:
        assert (out / name).resolve() in RENAMED[command], name
    assert not [p for p in out.rglob("*") if TMP_MARK in p.name]


@pytest.fixture(scope="module")
def bench_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    with renames("bench"):
        assert main(["bench", CONFIG, "--quick", "--points", "4", "--out", str(out)]) == 0
    return out


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_bench_files_and_numbers(bench_out):
    assert_strict_json(bench_out / "bench.json")
    for name in ("bench.csv", "bench.json", "bench.md", "bench_pareto.png"):
        assert (bench_out / name).stat().st_size > 0, name
    rows = _rows(bench_out / "bench.csv")
    settings = json.loads((bench_out / "bench.json").read_text())["settings"]
    assert {r["group"] for r in rows} == {"raytrace", "waveform"}
    for r in rows:
        assert math.isfinite(float(r["time_s"])) and float(r["time_s"]) > 0, r["label"]
        if r["position_dev_m_p95"] != "":   # empty: no point where both have a fix
            assert math.isfinite(float(r["position_dev_m_p95"]))
        assert 0.0 <= float(r["decision_agreement_pct"]) <= 100.0
    for g in ("raytrace", "waveform"):
        grp = [r for r in rows if r["group"] == g]
        ref = next(r for r in grp if r["role"] == "reference")
        assert any(r["role"] == "config" for r in grp)
        # the reference against itself: no deviation at all (same CIRs, same noise draws)
        assert float(ref["position_dev_m_p95"]) == 0.0
        assert float(ref["position_off_pct"]) == 0.0     # the waveform front's accuracy axis
        assert float(ref["decision_agreement_pct"]) == 100.0
        front = [r for r in grp if r["pareto"] == "True"]
        assert front
        # The front recomputed from its definition, independently of pareto_front: a setting is
        # dominated by another that is not less exact (exact one-sided sign test on bench.json's
        # units, scipy's binomtest, ACCURACY_ALPHA) and either clearly cheaper (COST_RTOL) or as
        # cheap and more exact; the noise floor is not a setting of the front
        err = {id(r): float(r[PARETO_METRIC[g]]) for r in grp}
        cost = {id(r): float(r["time_s"]) for r in grp}
        units = {(s["group"], s["label"]): np.array(s["off_units"], bool) for s in settings
                 if s["off_units"] is not None}
        for r in grp:   # the JSON's units give the CSV's share
            assert 100 * units[(g, r["label"])].mean() == pytest.approx(err[id(r)])

        def resolved(o, r):   # o more exact than r
            uo, ur = units[(g, o["label"])], units[(g, r["label"])]
            b, c = int(np.sum(ur & ~uo)), int(np.sum(uo & ~ur))
            return b > c and binomtest(b, b + c, 0.5, alternative="greater").pvalue < ACCURACY_ALPHA

        def dominated(r):
            for o in grp:
                if o is r or o["role"] == "noise floor" or resolved(r, o):
                    continue
                cheaper = cost[id(o)] * (1 + COST_RTOL) < cost[id(r)]
                same = not cheaper and cost[id(o)] <= cost[id(r)] * (1 + COST_RTOL)
                if cheaper or (same and resolved(o, r)):
                    return True
            return False

        for r in grp:
            if r["role"] != "noise floor":
                assert (r["pareto"] == "True") == (not dominated(r)), r["label"]
    rt_ref = next(r for r in rows if r["group"] == "raytrace" and r["role"] == "reference")
    assert float(rt_ref["first_path_dev_m_p95"]) == 0.0
    assert float(rt_ref["first_path_off_pct"]) == 0.0
    assert float(rt_ref["power_off_pct"]) == 0.0          # the ray-tracing front's accuracy axis
    assert float(rt_ref["power_dev_db_p50"]) == 0.0 and float(rt_ref["power_absdev_db_p90"]) == 0.0
    assert float(rt_ref["strongest_found_pct"]) == 100.0
    assert float(rt_ref["first_rel_power_absdev_db_p90"]) == 0.0
    for r in rows:
        if r["group"] == "raytrace":   # a lost or gained link counts as off: at least the coverage gap
            gap = abs(float(r["links_with_path_pct"]) - float(rt_ref["links_with_path_pct"]))
            assert float(r["first_path_off_pct"]) >= gap - 1e-9
            assert float(r["power_off_pct"]) >= gap - 1e-9
            assert 0.0 <= float(r["strongest_found_pct"]) <= 100.0
            assert float(r["first_rel_power_db_p50"]) <= 0.0   # the first path is never stronger
    meta = json.loads((bench_out / "bench.json").read_text())["meta"]
    assert meta["num_points"] == 4 and meta["quick"] is True


def test_bench_writes_each_file_atomically(bench_out):
    assert_written_atomically(bench_out, "bench",
                              ["bench.csv", "bench.json", "bench.md", "bench_pareto.png"])


@pytest.fixture(scope="module")
def compare_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    with renames("compare"):
        assert main(["compare", CONFIG, "--points", "8", "--workers", "1", "--out", str(out)]) == 0
    return out


def test_compare_writes_each_file_atomically(compare_out):
    assert_written_atomically(compare_out, "compare", [
        "comparison.md", "comparison.json", "comparison_points.csv", "comparison_channel.csv",
        "comparison_cdf.png", "comparison_detectors.png", "raytrace/metrics.json",
        "uma/metrics.json", "raytrace/scene/scene.xml", "raytrace/scene/meshes/ground.ply"])


def test_compare_files_and_numbers(compare_out):
    assert_strict_json(compare_out / "comparison.json")
    md = (compare_out / "comparison.md").read_text()
    # every table row has as many cells as its header (a bare "|" in a cell would split it)
    assert "| \\|RSTD error\\|, m |" in md
    table = []
    for line in md.splitlines() + [""]:
        if line.startswith("|"):
            table.append(len(re.findall(r"(?<!\\)\|", line)))
        elif table:
            assert len(set(table)) == 1, table
            table = []
    data_ = json.loads((compare_out / "comparison.json").read_text())
    for model, scen in data_["detectors"].items():
        for s, m in scen.items():
            for d in set(m.get("uninformative_detectors") or ()) & set(DETECTORS):
                row = next(ln for ln in md.splitlines() if ln.startswith(f"| {s} | {model} |"))
                cells = [c.strip() for c in row.strip("|").split("|")]
                assert cells[2 + DETECTORS.index(d)] == "uninf.", row
    for name in ("comparison.md", "comparison.json", "comparison_points.csv",
                 "comparison_channel.csv", "comparison_cdf.png", "comparison_detectors.png",
                 "raytrace/metrics.json", "uma/metrics.json"):
        assert (compare_out / name).stat().st_size > 0, name
    data = json.loads((compare_out / "comparison.json").read_text())
    # rooftop sites (25 m over 15 m roofs): the auto twin is UMa
    assert data["twin"]["model"] == "uma" and data["twin"]["rule"].startswith("auto")
    assert data["twin"]["bs_height_m"] > data["twin"]["roof_height_m"]
    for model in ("raytrace", "uma"):
        ch = data["channel"][model]["all"]
        assert ch["links"] == 8 * 3
        assert ch["links"] == data["channel"][model]["los"]["links"] + \
            data["channel"][model]["nlos"]["links"]
        assert 0.0 <= ch["links_with_path_share"] <= 1.0
        assert set(data["detectors"][model]) == {"none", "fbs", "meaconing", "jamming"}
        err = data["errors"][model]
        assert err["position_error_m"]["n"] <= 8
    # UMa draws every link with paths; the table values are the standard's
    assert data["channel"]["uma"]["all"]["links_with_path_share"] == 1.0
    assert data["channel"]["tr38901_table"]["scenario"] == "uma"
    assert data["channel"]["tr38901_table"]["los"]["k_db"] == 9.0
    pts = _rows(compare_out / "comparison_points.csv")
    assert len(pts) == 2 * 8 * 3
    # the same trajectory in both runs: identical true positions in the two CSVs
    a = _rows(compare_out / "raytrace" / "none_results.csv")
    b = _rows(compare_out / "uma" / "none_results.csv")
    assert [(r["x_true"], r["y_true"]) for r in a] == [(r["x_true"], r["y_true"]) for r in b]


# -- street-level sites: the UMi twin ----------------------------------------------------------
#: street centrelines of the canyon lie at multiples of its pitch (block 30 m + street 5 m)
STREET_SITES = "x,y,z\n-35,20,10\n35,-15,10\n10,35,10\n-20,-35,10\n0,0,10\n"


@pytest.fixture(scope="module")
def compare_umi_out(tmp_path_factory):
    """ci-tiny with 10 m BSs standing in the streets (below the 15 m roofs), --match-pathloss."""
    out = tmp_path_factory.mktemp("compare-umi")
    (out / "sites.csv").write_text(STREET_SITES)
    cfg = json.loads(Path(CONFIG).read_text())
    cfg["topology"] = {"sites": str(out / "sites.csv"), "bs_height_m": 10.0}
    (out / "street.json").write_text(json.dumps(cfg))
    assert main(["compare", str(out / "street.json"), "--points", "8", "--workers", "1",
                 "--match-pathloss", "--out", str(out / "cmp")]) == 0
    return out / "cmp"


def test_compare_uses_umi_for_street_level_sites(compare_umi_out):
    from veriloc_rt.propagation.umi import umi_pathloss_db

    data = json.loads((compare_umi_out / "comparison.json").read_text())
    twin = data["twin"]
    assert twin["model"] == "umi" and twin["rule"].startswith("auto")
    assert twin["bs_height_m"] == 10.0 and twin["roof_height_m"] == 15.0
    assert (compare_umi_out / "umi" / "metrics.json").stat().st_size > 0
    assert not (compare_umi_out / "uma").exists()
    run = json.loads((compare_umi_out / "umi" / "propagation_summary.json").read_text())
    assert run["raytrace_stats"]["model"].startswith("umi/")
    tab = data["channel"]["tr38901_table"]
    assert tab["scenario"] == "umi" and tab["los"]["k_db"] == 9.0      # UMi mu_K (Table 7.5-6)
    for cond, los in (("los", True), ("nlos", False)):
        expect = umi_pathloss_db(tab["d_2d_m"][cond], 10.0, 1.5, 3.5e9, los)
        assert tab[cond]["pathloss_db"] == pytest.approx(expect, abs=1e-9)
    md = (compare_umi_out / "comparison.md").read_text()
    assert "UMi-Street Canyon" in md and "### LoS links" in md and "### NLoS links" in md


def test_match_pathloss_sets_the_twin_median_on_the_trace(compare_umi_out):
    data = json.loads((compare_umi_out / "comparison.json").read_text())
    off = data["twin"]["pathloss_offset_db"]
    assert data["twin"]["match_pathloss"] is True
    for cond in ("los", "nlos"):
        rt = data["channel"]["raytrace"][cond].get("pathloss_db")
        tw = data["channel"]["umi"][cond].get("pathloss_db")
        if off["basis"][cond] == cond:
            # the same draws shifted by a constant: medians equal up to float rounding
            assert tw["p50"] == pytest.approx(rt["p50"], abs=1e-6), cond
        else:
            assert off[cond] == off["all"]
