"""A run folder as tables (issue #40): ``load_run`` against the run's own CSV and JSON files
read independently (``csv``, ``json``), and the Parquet and MATLAB exports read back with
pandas and ``scipy.io``. The run is a tiny UMa run whose handshake threshold (1 mm) no benign
fix meets, so that some detectors are flagged uninformative."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import scipy.io

import veriloc_rt
from veriloc_rt.cli import main
from veriloc_rt.report.tables import TABLES, load_run

CONFIG = {"seed": 2, "propagation": {"model": "uma", "uma_mode": "pathloss_only"},
          "trajectory": {"num_points": 32}, "run": {"evaluate_encrypted": False},
          "detectors": {"handshake": {"threshold_m": 0.001}, "fusion": {"split_block": 4}}}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("tables")
    (d / "c.json").write_text(json.dumps(CONFIG))
    assert main(["run", str(d / "c.json"), "--out", str(d / "r")]) == 0
    return d / "r"


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_load_run_matches_the_files(run_dir):
    t = veriloc_rt.load_run(run_dir)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    scenarios = list(metrics["scenarios"])
    # points: one row per CSV row, the CSV's columns by name after realisation and scenario
    for s in scenarios:
        rows = _csv(run_dir / f"{s}_results.csv")
        mine = t.points[t.points["scenario"] == s]
        assert len(mine) == len(rows) == 32
        header = list(rows[0])
        assert list(t.points.columns) == ["realisation", "scenario", *header]
        assert (mine["realisation"] == 0).all()
        np.testing.assert_array_equal(mine["HMAC"].to_numpy(), [int(r["HMAC"]) for r in rows])
        err = [float(r["error_m"]) if r["error_m"] else np.nan for r in rows]
        np.testing.assert_array_equal(mine["error_m"].to_numpy(), err)
    assert len(t.points) == 32 * len(scenarios)
    assert len(t.roc) == len(_csv(run_dir / "roc.csv"))
    # every scenario's per-TRP links file, row for row (3 TRPs a point here)
    for s in scenarios:
        links = _csv(run_dir / f"{s}_links.csv")
        mine = t.links[t.links["scenario"] == s]
        assert len(mine) == len(links) == 32 * 3
        np.testing.assert_array_equal(mine["index"].to_numpy(), [int(r["index"]) for r in links])
    # every scenario share, with its unit, equals metrics.json's
    sm = t.scenario_metrics
    for s in scenarios:
        rates = metrics["scenarios"][s]["correct_decision_rate"]
        for d, v in rates.items():
            if d.endswith("_ci95"):
                continue
            row = sm[(sm.scenario == s) & (sm.metric == "correct_decision_rate") & (sm.item == d)]
            assert row["value"].item() == v and row["unit"].item() == "fraction"
            assert [row["ci95_lo"].item(), row["ci95_hi"].item()] == rates[d + "_ci95"]
        assert not sm["item"].str.endswith("_ci95").any()
    # the flattened metrics: every leaf once, numbers as floats
    assert t.metrics.loc[t.metrics.key == "scenarios.none.num_points", "value"].item() == 32
    uninf = set(metrics["roc"]["uninformative"])
    assert uninf  # the 1 mm handshake
    op = t.operating_points
    assert set(op.loc[op.uninformative, "detector"]) == uninf
    e = metrics["roc"]["attacks"]["fbs"]["ABSA"]
    row = op[(op.attack == "fbs") & (op.detector == "ABSA")]
    assert row["attack_reject"].item() == e["attack_reject"] and row["auc"].item() == e["auc"]
    assert [row["auc_ci95_lo"].item(), row["auc_ci95_hi"].item()] == e["auc_ci95"]
    assert row["pd_at_false_alarm"].item() == e["pd_at_false_alarm"]
    # an interval is two numeric leaves of the flattened metrics
    lo = t.metrics.loc[t.metrics.key == "roc.attacks.fbs.ABSA.auc_ci95.lo", "value"].item()
    assert lo == e["auc_ci95"][0]


def test_parquet_and_mat_round_trip(run_dir, tmp_path):
    t = load_run(run_dir)
    assert main(["export", str(run_dir), "--format", "parquet", "--out",
                 str(tmp_path / "pq")]) == 0
    assert main(["export", str(run_dir), "--format", "mat", "--out", str(tmp_path / "r.mat")]) == 0
    for name, df in t.tables().items():
        back = pd.read_parquet(tmp_path / "pq" / f"{name}.parquet")
        pd.testing.assert_frame_equal(back, df, check_dtype=False, check_index_type=False)
    mat = scipy.io.loadmat(tmp_path / "r.mat", simplify_cells=True)
    assert set(TABLES) <= set(mat)
    for name, df in t.tables().items():
        assert list(mat[name]) == [str(c) for c in df.columns], name
        for c in df.columns:
            got = np.atleast_1d(mat[name][c])
            assert len(got) == len(df), (name, c)
            col = df[c]
            if pd.api.types.is_numeric_dtype(col) or pd.api.types.is_bool_dtype(col):
                np.testing.assert_array_equal(got.astype(float), col.to_numpy(dtype=float))
            else:
                # MATLAB's '' (0x0 char) reads back as an empty array
                text = ["" if isinstance(v, np.ndarray) and v.size == 0 else str(v) for v in got]
                assert text == ["" if pd.isna(v) else str(v) for v in col], (name, c)


def test_export_bad_input_is_one_line_exit_2(tmp_path, run_dir):
    for args, field in ((["export", str(tmp_path / "none"), "--format", "mat", "--out",
                          str(tmp_path / "x.mat")], str(tmp_path / "none")),
                        (["export", str(run_dir), "--format", "mat", "--out",
                          str(tmp_path / "x.txt")], "--out")):
        r = subprocess.run([sys.executable, "-m", "veriloc_rt.cli", *args], capture_output=True,
                           text=True, cwd=tmp_path)
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {field}: "), r.stderr


# --- honest figures and tables (issue #40): no attack rate for an uninformative detector ---

def _bars(ax) -> dict:
    """``{label: [bar heights]}`` of the axes' bar containers."""
    return {c.get_label(): [p.get_height() for p in c.patches] for c in ax.containers
            if hasattr(c, "patches")}   # not the error bars' containers


def test_no_attack_rate_for_an_uninformative_detector(run_dir, tmp_path):
    from matplotlib.figure import Figure

    from veriloc_rt.report.plots import plot_comparison_detectors, plot_detection_rates
    from veriloc_rt.report import plots
    from veriloc_rt.report.roc_report import format_detection

    metrics = json.loads((run_dir / "metrics.json").read_text())
    sc = metrics["scenarios"]
    order = list(sc)   # none, fbs, meaconing, jamming: the plot's order
    attacks = [s for s in order if s != "none"]
    flagged = set(metrics["roc"]["uninformative"])
    assert flagged and all(set(sc[s]["uninformative_detectors"]) == flagged for s in attacks)
    assert "Handshake" in flagged  # the 1 mm threshold
    fig = plot_detection_rates(metrics, None, ax=Figure().subplots())
    ax = fig.axes[0]
    bars = _bars(ax)
    texts = [t.get_text() for t in ax.texts]
    for d in ("HMAC", "DigSig", "ABSA", "Handshake", "Tracking"):   # the CSVs' names
        heights = bars[d]
        for s, h in zip(order, heights):
            if s != "none" and d in flagged:
                assert h == 0.0, (d, s)     # no bar ...
            else:
                # drawn in percent: 100 x the fraction, exactly as the plot computes it
                assert h == 100.0 * sc[s]["correct_decision_rate"][d], (d, s)
    # ... and the label says why, once per flagged detector and attack scenario
    single = flagged & {"HMAC", "DigSig", "ABSA", "Handshake", "Tracking"}   # not KofN
    assert texts.count("uninf.") == len(single) * len(attacks)

    # compare's figure, its scenarios blocks given per model
    captured = {}
    real = plots.figure

    def keep(*a, **k):
        cm = real(*a, **k)

        class Wrap:
            def __enter__(self):
                captured["fa"] = cm.__enter__()
                return captured["fa"]

            def __exit__(self, *exc):   # before the figure is cleared
                _, axes = captured["fa"]
                captured["axes"] = [(_bars(ax), [t.get_text() for t in ax.get_xticklabels()])
                                    for ax in axes[0]]
                return cm.__exit__(*exc)
        return Wrap()

    plots.figure = keep
    try:
        plot_comparison_detectors({"raytrace": sc, "uma": sc}, tmp_path / "cmp.png")
    finally:
        plots.figure = real
    assert len(captured["axes"]) == len(order)
    for (bars, ticks), s in zip(captured["axes"], order):
        for model, heights in bars.items():
            for d, h in zip(("HMAC", "DigSig", "ABSA", "Handshake", "Tracking"), heights):
                want = (0.0 if (s != "none" and d in flagged)
                        else 100.0 * sc[s]["correct_decision_rate"][d])   # drawn in percent
                assert h == want, (model, s, d)
        assert ticks == [
            "HMAC", "DigSig", "ABSA", "Handshake", "Tracking"]
    # the printed ROC table: "uninf." in place of the flagged detectors' rates
    text = format_detection(metrics["roc"])
    for line in text.splitlines()[1:1 + len(attacks)]:
        assert line.count("uninf.") == len(flagged), line


def test_roc_command_writes_only_to_out_and_states_its_target(run_dir, tmp_path, capsys):
    before = {p.name: p.read_bytes() for p in run_dir.iterdir() if p.is_file()}
    assert main(["roc", str(run_dir), "--out", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --out: ") and err.count("\n") == 1, err
    # the run's own settings: the analysis from the files is the one the run made
    assert main(["roc", str(run_dir), "--out", str(tmp_path / "same")]) == 0
    capsys.readouterr()
    assert (json.loads((tmp_path / "same" / "roc_metrics.json").read_text())
            == json.loads((run_dir / "metrics.json").read_text())["roc"])
    assert (tmp_path / "same" / "roc.csv").read_bytes() == (run_dir / "roc.csv").read_bytes()
    out = tmp_path / "roc"
    assert main(["roc", str(run_dir), "--out", str(out), "--set",
                 "detectors.fusion.false_alarm=0.01"]) == 0
    stdout = capsys.readouterr().out
    assert {p.name: p.read_bytes() for p in run_dir.iterdir() if p.is_file()} == before
    roc = json.loads((out / "roc_metrics.json").read_text())
    assert roc["fusion"]["false_alarm"] == 0.01 and roc["fusion"]["test"]
    assert "false alarm <= 1 %" in stdout
    # every NP fusion line states its measured test false alarm, "> target 1" when above it
    for s, t in roc["fusion"]["test"].items():
        fa = 100 * t["NPFusion"]["false_alarm"]
        line = next(ln for ln in stdout.splitlines()
                    if ln.strip().startswith(s + " ") and "NP fusion" in ln)
        assert f"false alarm {fa:4.1f}" in line
        assert ("> target 1" in line) == (fa > 1.0), line


@pytest.mark.parametrize("argv, field", [
    (["roc", "{tmp}/nowhere", "--out", "{tmp}/o"], "RUN_DIR"),
    (["roc", "{run}", "--out", "{tmp}/o", "--set", "detectors.fusion.k"], "--set"),
    (["roc", "{run}", "--out", "{tmp}/o", "--set", "detectors.fusion.k=two"], "--set"),
    (["roc", "{run}", "--out", "{tmp}/o", "--set", "detectors.nope=1"], "detectors.nope"),
    (["diff", "{run}", "{tmp}/nowhere"], "RUN_B"),
    (["diff", "{tmp}", "{run}"], "RUN_A"),
    (["paper-table", "{tmp}/nowhere.json"], "{tmp}/nowhere.json"),
    (["paper-table", "{run}/run.json"], "{run}/run.json"),
])
def test_post_processing_bad_input_is_one_line_exit_2(run_dir, tmp_path, capsys, argv, field):
    fill = {"tmp": str(tmp_path), "run": str(run_dir)}
    assert main([a.format(**fill) for a in argv]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith(f"error: {field.format(**fill)}: ")
    assert captured.err.count("\n") == 1, captured.err
    assert not (tmp_path / "o").exists()


def _edit_csv(path, row: int, column: str, value: str) -> str:
    """Set one cell of a results CSV; returns the cell's old text."""
    with open(path, newline="") as fh:
        lines = list(csv.reader(fh))
    col = lines[0].index(column)
    old, lines[row + 1][col] = lines[row + 1][col], value
    with open(path, "w", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows(lines)
    return old


def test_diff_command_reports_the_cells_changed(run_dir, tmp_path, capsys):
    copy = tmp_path / "copy"
    shutil.copytree(run_dir, copy)
    assert main(["diff", str(run_dir), str(copy)]) == 0
    out = capsys.readouterr().out.splitlines()
    scenarios = sorted(p.name for p in run_dir.glob("*_results.csv"))
    assert out == [f"{s}: 32 rows, identical" for s in scenarios] + [
        "the --exact columns are identical"]
    # a known change: one error moved by 0.25 m, one HMAC verdict flipped
    target = copy / "none_results.csv"
    rows = _csv(target)
    k = next(i for i, r in enumerate(rows) if r["error_m"])
    old = float(_edit_csv(target, k, "error_m", repr(float(rows[k]["error_m"]) + 0.25)))
    _edit_csv(target, 5, "HMAC", str(1 - int(rows[5]["HMAC"])))
    assert main(["diff", str(run_dir), str(copy)]) == 1
    out = capsys.readouterr().out.splitlines()
    i = out.index("none_results.csv: 32 rows")
    rel = 0.25 / max(abs(old), abs(old + 0.25))
    assert out[i + 1] == (f"  {'HMAC':16s} {1:5d} rows differ, max abs {1:.3g}, max rel {1:.3g}"
                          "  <- must be identical")
    err_line = next(ln for ln in out[i + 1:] if ln.strip().startswith("error_m"))
    # 0.25 m up to the CSV's rounding of the old value (3 significant digits printed)
    assert err_line == f"  {'error_m':16s} {1:5d} rows differ, max abs {0.25:.3g}, max rel {rel:.3g}"
    assert out[-1] == "an --exact column DIFFERS"
    # the verdict is not required to be identical: the run passes
    assert main(["diff", str(run_dir), str(copy), "--exact", "Time,index"]) == 0


def test_paper_table_counts_the_cells_within_the_band(tmp_path, capsys):
    from veriloc_rt.report.paper import PAPER_OUTCOMES, PAPER_RATES, SCENARIOS, tolerance
    from veriloc_rt.report.postprocess import rate_percent

    unit = rate_percent(1.0)   # metrics.json's rates in the unit the file holds them in
    # every rate at the paper's value, except HMAC under fbs: just outside its band
    off = PAPER_RATES["fbs"]["HMAC"] - 1.5 * tolerance(PAPER_RATES["fbs"]["HMAC"])
    sc = {s: {"correct_decision_rate": {d: v / unit for d, v in PAPER_RATES[s].items()},
              "outcomes": {k: v / unit for k, v in PAPER_OUTCOMES["outcomes"][s].items()},
              "outcomes_encrypted": {k: v / unit for k, v in
                                     PAPER_OUTCOMES["outcomes_encrypted"][s].items()}}
          for s in SCENARIOS}
    sc["fbs"]["correct_decision_rate"]["HMAC"] = off / unit
    (tmp_path / "metrics.json").write_text(json.dumps({"scenarios": sc}))
    assert main(["paper-table", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    cells = 5 * len(SCENARIOS) + 2 * 3 * len(SCENARIOS)   # 5 detectors, 2 x 3 outcomes
    assert out.rstrip().endswith(f"{cells - 1} of {cells} cells within the acceptance band "
                                 "(✗: outside)")
    hmac = next(ln for ln in out.splitlines() if ln.startswith("| HMAC |"))
    col = 1 + list(SCENARIOS).index("fbs")
    assert hmac.split(" | ")[col] == f"{PAPER_RATES['fbs']['HMAC']:.1f} / {off:.1f} ✗"
    assert out.count("✗") == 2   # the cell and the legend


def test_plot_command_redraws_in_the_chosen_format_and_dpi(run_dir, tmp_path):
    before = {p.name: p.read_bytes() for p in run_dir.iterdir() if p.is_file()}
    assert main(["plot", str(run_dir), "--out", str(tmp_path / "png"), "--plot-format", "png",
                 "--dpi", "200"]) == 0
    from PIL import Image

    # outcomes.png is 8 x 5 inches (plots.plot_outcomes): 1600 x 1000 pixels at 200 dpi
    with Image.open(tmp_path / "png" / "outcomes.png") as im:
        assert im.size == (1600, 1000)
    for fmt, magic in (("pdf", b"%PDF"), ("svg", b"<?xml")):
        assert main(["plot", str(run_dir), "--out", str(tmp_path / fmt), "--plot-format",
                     fmt]) == 0
        names = sorted(p.name for p in (tmp_path / fmt).iterdir())
        assert names == sorted([f"outcomes.{fmt}", f"detection_rates.{fmt}", f"roc.{fmt}"]
                               + [f"{s}_{kind}.{fmt}" for s in
                                  ("none", "fbs", "meaconing", "jamming")
                                  for kind in ("timeseries", "map")])
        assert all((tmp_path / fmt / n).read_bytes().startswith(magic) for n in names)
    assert main(["plot", str(run_dir), "--out", str(run_dir)]) == 2   # never the run's folder
    assert {p.name: p.read_bytes() for p in run_dir.iterdir() if p.is_file()} == before


def test_run_with_progress_true_draws_bars_on_stderr(tmp_path, capsys):
    cfg = veriloc_rt.Config().updated({"propagation.model": "uma", "trajectory.num_points": 4,
                                       "run.scenarios": ["none"]})
    res = veriloc_rt.run(cfg, tmp_path / "r", progress=True)
    err = capsys.readouterr().err
    assert "none" in err and "4/4" in err
    assert res.metrics["scenarios"]["none"]["num_points"] == 4


def test_save_cir_writes_the_run_cirs_for_sionna(tmp_path):
    import numpy as np

    from veriloc_rt.propagation.cir import CIR

    cfg = {"seed": 3, "propagation": {"model": "uma", "uma_mode": "pathloss_only"},
           "trajectory": {"num_points": 3}, "run": {"scenarios": ["none"]}}
    (tmp_path / "c.json").write_text(json.dumps(cfg))
    assert main(["run", str(tmp_path / "c.json"), "--out", str(tmp_path / "r"), "-q",
                 "--save-cir"]) == 0
    res_cir = {}
    for name, slots in (("bs_to_ue", 3), ("bs_to_adversary", 3), ("adversary_to_ue", 1)):
        with np.load(tmp_path / "r" / f"cir_{name}.npz") as z:
            res_cir[name] = CIR.from_arrays(dict(z))
        assert res_cir[name].num_points == 3 and res_cir[name].num_tx == slots
    c = res_cir["bs_to_ue"]
    a, tau = c.to_sionna(2, normalize_delays=False)
    assert a.shape == (1, c.num_ant, 3, 1, c.num_paths, 1) and tau.shape == (1, 3, c.num_paths)
    # the saved delays are the run's: the first path of each serving link (UMa path loss only:
    # the line-of-sight delay) equals its straight-line distance / c
    first = np.where(tau[0] >= 0, tau[0], np.inf).min(axis=-1)
    np.testing.assert_allclose(first, c.geometric_delay()[2], rtol=1e-12)
    # a second run into the folder (--force) clears them unless asked again
    assert main(["run", str(tmp_path / "c.json"), "--out", str(tmp_path / "r"), "-q",
                 "--force"]) == 0
    assert not list((tmp_path / "r").glob("cir_*.npz"))


def test_link_budget_in_the_links_csv_and_metrics(run_dir):
    """Each link's tag margins are its SNR per RE plus the 5-antenna combining gain less the
    bench threshold and the multipath penalty; metrics.json's link_budget summarises the
    ``none`` scenario's links CSV; the printed summary has its line."""
    from veriloc_rt.cli import format_metrics
    from veriloc_rt.report.link_budget import MULTIPATH_PENALTY_DB, TAG_THRESHOLD_DB

    penalty = MULTIPATH_PENALTY_DB["single_path"]   # UMa 'pathloss_only': one path per link

    links = _csv(run_dir / "none_links.csv")
    snr = np.array([float(r["snr_re_db"]) for r in links])
    for s in ("hmac", "ds"):
        want = snr + 10 * np.log10(5) - TAG_THRESHOLD_DB[s] - penalty
        np.testing.assert_allclose([float(r[f"{s}_margin_db"]) for r in links], want,
                                   rtol=0, atol=1e-12)   # the same sums, written with repr
    metrics = json.loads((run_dir / "metrics.json").read_text())
    b = metrics["link_budget"]
    assert b["scenario"] == "none" and b["links"] == len(links) == 32 * 3
    assert b["multipath_penalty_db"] == penalty
    assert b["snr_re_db"]["p50"] == pytest.approx(np.percentile(snr, 50), abs=1e-12)
    heard = [r["heard"] == "1" for r in links]
    assert b["heard_share"] == pytest.approx(sum(heard) / len(heard), abs=1e-15)
    used = {}
    for r in links:
        if r["used"] == "1":
            used.setdefault(r["index"], []).append(float(r["hmac_margin_db"]))
    weakest = [min(v) for v in used.values()]
    assert b["weakest_used_hmac_margin_db"]["p50"] == pytest.approx(np.percentile(weakest, 50),
                                                                     abs=1e-12)
    assert any(line.startswith("link budget (none, 96 links)")
               for line in format_metrics(metrics).splitlines())
