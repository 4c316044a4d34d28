"""Monte Carlo over realisations and the Dask executors: same bytes as serial, CI arithmetic.

Independent references:
* the serial run (``workers=1``, no Dask) for every Dask result, byte for byte;
* Student-t quantiles from a printed table (t_{0.975, 1} = 12.706, t_{0.975, 4} = 2.776, e.g.
  NIST/SEMATECH e-Handbook, Table 1.3.6.7.2) and the mean and sample standard deviation worked
  out by hand for small integer samples.
"""

from __future__ import annotations

import json
import math

import pytest

from veriloc_rt.sim import executors, montecarlo
from veriloc_rt.cli import main
from veriloc_rt.config import config_from_dict
from veriloc_rt.sim.engine import run
from veriloc_rt.errors import InputError
from veriloc_rt.sim.montecarlo import aggregate, mean_ci, realisation_config
from veriloc_rt.sim.executors import local_cluster

from .test_cli import cli

#: the printed t-table values have 3 decimals
T_TABLE_TOL = 5e-4

#: small UMa run (path loss only, no tracing): 8 points, attack window points 2..5. The runs go
#: through the CLI, which pins BLAS to one thread (multithreaded BLAS is ~10x slower here)
SMALL = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
         "trajectory": {"num_points": 8}, "seed": 5,
         "run": {"scenarios": ["none", "fbs"], "digsig": "shared", "evaluate_encrypted": False}}


def _same_files(a, b, names) -> None:
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def _config(path, realisations: int):
    path.write_text(json.dumps({**SMALL, "run": {**SMALL["run"], "realisations": realisations}}))
    return path


@pytest.fixture(scope="module")
def serial_mc(tmp_path_factory):
    """Two realisations, one after the other (the reference of every Dask run here)."""
    tmp = tmp_path_factory.mktemp("mc")
    f = _config(tmp / "mc.json", 2)
    r = cli("run", f, "--out", tmp / "serial", "--workers", "1")
    assert r.returncode == 0, r.stderr
    assert "Monte Carlo: 2 realisations" in r.stdout and "mean [95 % interval" in r.stdout
    return f, tmp / "serial"


@pytest.mark.heavy
def test_two_worker_local_cluster_gives_the_serial_result(serial_mc, tmp_path):
    """Acceptance (issue #6): realisations as tasks on a 2-worker LocalCluster == serial."""
    f, serial = serial_mc
    cfg = config_from_dict(json.loads(f.read_text()))
    r = cli("run", f, "--out", tmp_path / "d", "--workers", "2")
    assert r.returncode == 0, r.stderr
    dask = tmp_path / "d"
    for name in ("realisation_000", "realisation_001"):
        _same_files(serial / name, dask / name, [f"{s}_results.csv" for s in cfg.run.scenarios])
    _same_files(serial, dask, ["montecarlo.csv"])
    agg = json.loads((serial / "metrics.json").read_text())
    agg_dask = json.loads((dask / "metrics.json").read_text())
    assert agg_dask["scenarios"] == agg["scenarios"]
    assert agg_dask["resources"]["workers"] == 2 and agg["resources"]["workers"] == 1

    # the aggregate is the mean and t-interval of the realisations' own metrics.json
    per = [json.loads((serial / r / "metrics.json").read_text())
           for r in ("realisation_000", "realisation_001")]
    assert agg["realisations"] == 2
    for s in cfg.run.scenarios:
        m = agg["scenarios"][s]
        assert m["num_points"] == 8 and m["realisations"] == 2
        assert "outcomes_encrypted" not in m
        for group in ("outcomes", "correct_decision_rate", "position_error_m"):
            for k, v in m[group].items():
                if k.endswith("_ci95"):   # [mean -+ half] clipped to [0, 1]
                    mean, half = m[group][k[:-5]], m["ci95"][group][k[:-5]]
                    assert v == pytest.approx([max(0.0, mean - half), min(1.0, mean + half)])
                    continue
                a, b = (p["scenarios"][s][group][k] for p in per)
                assert v == pytest.approx((a + b) / 2)
                assert m["ci95"][group][k] == pytest.approx(12.706 * abs(a - b) / 2, rel=1e-4)
    for name in ("montecarlo_detection_rates.png", "outcomes.png"):
        assert (serial / name).stat().st_size > 0
    rows = (serial / "montecarlo.csv").read_text().splitlines()
    assert rows[0].startswith("realisation,seed,topology_iteration,scenario,success,")
    assert len(rows) == 1 + 2 * len(cfg.run.scenarios)
    info = json.loads((serial / "run.json").read_text())
    assert info["status"] == "complete"
    assert [r["topology_iteration"] for r in info["realisations"]] == [0, 1]
    # realisation 0 is the plain run; realisation 1 has its own layout and seed, and its
    # run.json holds the single-run config that reproduces it
    assert info["realisations"][0]["seed"] == cfg.seed != info["realisations"][1]["seed"]
    r1 = json.loads((serial / "realisation_001" / "run.json").read_text())["config"]
    assert r1["seed"] == info["realisations"][1]["seed"] and r1["run"]["realisations"] == 1


@pytest.mark.heavy
def test_single_run_chunks_on_a_scheduler_give_the_serial_result(serial_mc, tmp_path):
    """``--scheduler`` with one realisation: trajectory chunks as tasks, detectors in order;
    the reference is the serial Monte Carlo's realisation 0 (the plain run)."""
    f, serial = serial_mc
    cfg = config_from_dict(SMALL)  # in this process: only the detectors run here
    with local_cluster(2) as client:
        res = run(cfg, tmp_path / "one", scheduler=client.scheduler.address)
    _same_files(serial / "realisation_000", tmp_path / "one",
                [f"{s}_results.csv" for s in cfg.run.scenarios])
    ref = json.loads((serial / "realisation_000" / "metrics.json").read_text())
    assert res.metrics["scenarios"] == ref["scenarios"]
    r = res.metrics["resources"]
    assert r["workers"] == 2 and r["scheduler"].startswith("tcp://")


def test_realisation_zero_is_the_plain_run():
    cfg = config_from_dict({**SMALL, "topology": {"iteration": 3},
                            "run": {**SMALL["run"], "realisations": 4}})
    plain = config_from_dict({**SMALL, "topology": {"iteration": 3}})
    assert realisation_config(cfg, 0) == plain
    r2 = realisation_config(cfg, 2)
    assert r2.topology.iteration == 5 and r2.run.realisations == 1 and r2.seed != cfg.seed
    assert realisation_config(cfg, 2) == r2  # derived from the seed: the same every time


def test_scene_variants_cycle_over_the_realisations():
    cfg = config_from_dict({**SMALL, "run": {**SMALL["run"], "realisations": 3,
                                             "street_width_variants_m": [5, 20],
                                             "height_jitter_variants_m": [0, 4, 8]}})
    got = [(realisation_config(cfg, r).scene.street_width_m,
            realisation_config(cfg, r).scene.height_jitter_m) for r in range(4)]
    assert got == [(5.0, 0.0), (20.0, 4.0), (5.0, 8.0), (20.0, 0.0)]
    r1 = realisation_config(cfg, 1)   # a single run: no variant list left
    assert r1.run.street_width_variants_m == () == r1.run.height_jitter_variants_m
    for bad, field in (({"street_width_variants_m": [1.0]}, "run.street_width_variants_m[0]"),
                       # jitter as large as the 15 m mean height
                       ({"height_jitter_variants_m": [15.0]}, "run.height_jitter_variants_m[0]")):
        with pytest.raises(InputError) as e:
            config_from_dict({**SMALL, "run": {**SMALL["run"], **bad}})
        assert e.value.field == field
    with pytest.raises(InputError) as e:   # a mesh scene has no street width to vary
        config_from_dict({**SMALL, "scene": {"source": "scene.xml"},
                          "run": {**SMALL["run"], "street_width_variants_m": [5.0]}})
    assert e.value.field == "run.street_width_variants_m"


def test_roc_aggregate_is_the_mean_with_a_bootstrap_interval():
    def m(auc_value):
        return {"scenarios": {"none": {"num_points": 4, "num_evaluated": 4}},
                "roc": {"uninformative": [], "fusion": {"false_alarm": 0.05},
                        "attacks": {"fbs": {"HMAC": {"auc": auc_value, "pd_at_false_alarm": 1.0,
                                                     "benign_accept": 0.9,
                                                     "attack_reject": 1.0}}}}}

    vals = [0.6, 0.7, 0.8, 0.9]
    e = aggregate([m(v) for v in vals], seed=3)["roc"]["attacks"]["fbs"]["HMAC"]
    assert e["auc"] == pytest.approx(0.75, abs=1e-15)
    lo, hi = e["auc_ci95"]
    # a mean of 4 resampled values lies between the smallest and the largest; its sd is
    # 0.112 / sqrt(4) = 0.056, so its 2.5 % and 97.5 % percentiles lie about 0.11 from 0.75,
    # past 0.7 and 0.8 (the discrete steps are 0.025)
    assert 0.6 <= lo < 0.7 and 0.8 < hi <= 0.9
    assert e["pd_at_false_alarm_ci95"] == [1.0, 1.0]   # no spread, no width
    assert aggregate([m(v) for v in vals], seed=3)["roc"] == aggregate(
        [m(v) for v in vals], seed=3)["roc"]   # seeded


def test_confidence_interval_by_hand():
    # 1..5: mean 3, s^2 = (4+1+0+1+4)/4 = 2.5, half = t_{0.975,4} * sqrt(2.5) / sqrt(5)
    mean, half, n = mean_ci([1, 2, 3, 4, 5])
    assert (mean, n) == (3.0, 5)
    assert half == pytest.approx(2.776 * math.sqrt(2.5 / 5), rel=T_TABLE_TOL)
    # None (undefined in a realisation) is left out; one value has no interval
    mean, half, n = mean_ci([0.9, None, 1.0])
    assert mean == pytest.approx(0.95, abs=1e-15) and n == 2
    assert half == pytest.approx(12.706 * math.sqrt(0.005 / 2), rel=T_TABLE_TOL)
    assert mean_ci([7.0]) == (7.0, None, 1)
    assert mean_ci([None]) == (None, None, 0)

    def m(hmac, success):
        return {"scenarios": {"none": {"num_points": 4, "num_evaluated": 4,
                                       "outcomes": {"success": success},
                                       "correct_decision_rate": {"HMAC": hmac}}}}

    agg = aggregate([m(0.9, 1.0), m(None, 0.5), m(1.0, 0.75)])   # fractions
    s = agg["scenarios"]["none"]
    assert agg["realisations"] == s["realisations"] == 3 and s["num_points"] == 4
    assert s["correct_decision_rate"]["HMAC"] == pytest.approx(0.95, abs=1e-15)
    assert s["realisations_defined"]["correct_decision_rate"]["HMAC"] == 2
    assert s["outcomes"]["success"] == 0.75
    # s^2 = (0.0625 + 0.0625 + 0) / 2, t_{0.975,2} = 4.303
    assert s["ci95"]["outcomes"]["success"] == pytest.approx(4.303 * math.sqrt(0.0625 / 3),
                                                             rel=T_TABLE_TOL)


@pytest.mark.parametrize("realisations", [1, 2])
def test_unreachable_scheduler_is_one_line_exit_2(tmp_path, monkeypatch, capsys, realisations):
    monkeypatch.setattr(executors, "CONNECT_TIMEOUT_S", 1.0)  # the CLI waits 10 s
    f = tmp_path / "c.json"
    f.write_text(json.dumps({**SMALL, "run": {"realisations": realisations}}))
    out = tmp_path / "out"
    rc = main(["run", str(f), "--out", str(out), "--scheduler", "tcp://127.0.0.1:1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and err[0].startswith(
        "error: --scheduler: cannot connect to tcp://127.0.0.1:1 (")
    assert not out.exists()  # refused before any work
    rc = main(["run", str(f), "--out", str(out), "--scheduler", "tcp://[::1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("error: --scheduler: ")
    rc = main(["run", str(f), "--out", str(out), "--scheduler", "tcp://127.0.0.1:1",
               "--workers", "2"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("error: --workers: ")


@pytest.mark.parametrize("value, words", [(0, ">= 1"), (1.5, "an integer"), ("2", "an integer")])
def test_realisations_is_validated(value, words):
    with pytest.raises(InputError) as exc:
        config_from_dict({"run": {"realisations": value}})
    assert exc.value.field == "run.realisations"
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_link_budget_aggregate_by_hand():
    def m(heard, p50):
        return {"scenarios": {"none": {"num_points": 4, "num_evaluated": 4}},
                "link_budget": {"scenario": "none", "links": 12, "rx_antennas": 5,
                                "tag_threshold_db": {"hmac": -2.5}, "multipath_penalty_db": 0.0,
                                "heard_share": heard, "heard_share_ci95": [0.0, 1.0],
                                "snr_re_db": {"p5": -10.0, "p50": p50, "p95": 10.0}}}

    b = aggregate([m(0.5, -1.0), m(1.0, 3.0)])["link_budget"]
    assert b["links"] == 24 and b["realisations"] == 2 and b["rx_antennas"] == 5
    assert b["snr_re_db"] == {"p5": -10.0, "p50": 1.0, "p95": 10.0}   # means of the percentiles
    assert b["heard_share"] == 0.75
    # t_{0.975,1} s / sqrt 2 = 12.706 x 0.3536 / 1.414 = 3.18: clipped to [0, 1]
    assert b["heard_share_ci95"] == [0.0, 1.0]
