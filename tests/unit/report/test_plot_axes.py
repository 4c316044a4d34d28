"""Every public plotting function draws into the caller's matplotlib Axes (``ax=``) and returns
their Figure; rates with ``<key>_ci95`` siblings are drawn with those intervals as error bars,
in the unit :func:`~veriloc_rt.report.plots.rate_percent` gives; uninformative detectors keep
no attack bar. Checked on the artists (bars, error-bar segments, collections), not pixels."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.container import BarContainer, ErrorbarContainer
from matplotlib.figure import Figure

from veriloc_rt.cli import main
from veriloc_rt.config import config_from_dict
from veriloc_rt.detectors.outcomes import DETECTORS, OUTCOMES
from veriloc_rt.errors import InputError
from veriloc_rt.report import plots
from veriloc_rt.report.plots import RATE_FULL_SCALE, rate_interval, rate_percent

#: a tiny UMa run (no tracing): two scenarios, no encrypted-PRS pass
TINY = {"propagation": {"model": "uma"}, "trajectory": {"num_points": 10, "adversary_lag_points": 2},
        "run": {"scenarios": ["none", "fbs"], "evaluate_encrypted": False, "digsig": "shared"}}
#: the error bars hold the interval's own floats after one scaling to percent: rounding only
TOL = 1e-9


def stored(percent: float) -> float:
    """A rate of ``percent`` % as metrics.json stores it (:data:`RATE_FULL_SCALE`)."""
    return percent * RATE_FULL_SCALE / 100.0


def _metrics(ci_where: str) -> dict:
    """Two scenarios, fbs flagging Tracking uninformative; intervals on every rate, as the
    sibling ``correct_decision_rate_ci95`` / ``outcomes_ci95`` dicts ('sibling') or inside the
    rate dicts ('inside')."""
    rates = {"none": [99.0, 98.0, 97.0, 96.0, 95.0], "fbs": [90.0, 80.0, 70.0, 60.0, 50.0]}
    out = {"scenarios": {}}
    for s, v in rates.items():
        r = {d: stored(x) for d, x in zip(DETECTORS, v)}
        ci = {d: [stored(x - 3.0), stored(min(x + 1.0, 100.0))] for d, x in zip(DETECTORS, v)}
        o = {"success": stored(60.0), "large_error": stored(30.0), "service_failure": stored(10.0)}
        oci = {k: [stored(x - 5.0), stored(x + 5.0)] for k, x in
               (("success", 60.0), ("large_error", 30.0), ("service_failure", 10.0))}
        blk = {"num_points": 10, "correct_decision_rate": r, "outcomes": o}
        if ci_where == "sibling":
            blk.update(correct_decision_rate_ci95=ci, outcomes_ci95=oci)
        else:
            r.update({f"{d}_ci95": c for d, c in ci.items()})
            o.update({f"{k}_ci95": c for k, c in oci.items()})
        out["scenarios"][s] = blk
    out["scenarios"]["fbs"]["uninformative_detectors"] = ["Tracking"]
    return out


def _segments(ax) -> list[tuple[float, float, float]]:
    """(x, lo, hi) of every vertical error-bar segment on ``ax``."""
    segs = []
    for c in ax.containers:
        if isinstance(c, ErrorbarContainer):
            for coll in c.lines[2]:
                for seg in coll.get_segments():
                    segs.append((float(seg[0, 0]), float(min(seg[:, 1])), float(max(seg[:, 1]))))
    return sorted(segs)


def _bars(ax) -> dict:
    return {c.get_label(): [(p.get_x() + p.get_width() / 2, p.get_height()) for p in c.patches]
            for c in ax.containers if isinstance(c, BarContainer)}


def test_rate_unit_helper_and_intervals():
    assert rate_percent(stored(42.5)) == pytest.approx(42.5, abs=TOL)
    assert np.isnan(rate_percent(None))
    for where in ("sibling", "inside"):
        sc = _metrics(where)["scenarios"]["none"]
        lo, hi = rate_interval(sc, "correct_decision_rate", "HMAC")
        assert (lo, hi) == pytest.approx((96.0, 100.0), abs=TOL)
        assert rate_interval(sc, "outcomes", "success") == pytest.approx((55.0, 65.0), abs=TOL)
    # a Monte Carlo aggregate's half-width, clipped to 0..100 %
    agg = {"correct_decision_rate": {"HMAC": stored(99.0)},
           "ci95": {"correct_decision_rate": {"HMAC": stored(2.5)}}}
    assert rate_interval(agg, "correct_decision_rate", "HMAC") == pytest.approx((96.5, 100.0))
    assert rate_interval({"correct_decision_rate": {"HMAC": 1.0}}, "correct_decision_rate",
                         "HMAC") is None


@pytest.mark.parametrize("where", ["sibling", "inside"])
def test_detection_rates_error_bars_from_ci95_and_no_uninformative_bar(where):
    m = _metrics(where)
    ax = Figure().subplots()
    assert plots.plot_detection_rates(m, ax=ax, title="t") is ax.figure
    bars = _bars(ax)
    segs = _segments(ax)
    # the independent expectation: each informative bar's x with its interval in percent
    want = []
    for d in DETECTORS:
        for (x, h), s in zip(bars[d], ("none", "fbs")):
            blk = m["scenarios"][s]
            if s == "fbs" and d == "Tracking":
                assert h == 0.0     # uninformative: no attack bar, no error bar
                continue
            assert h == pytest.approx(rate_percent(blk["correct_decision_rate"][d]), abs=TOL)
            ci = (blk.get("correct_decision_rate_ci95") or {}).get(d) or \
                blk["correct_decision_rate"][f"{d}_ci95"]
            want.append((x, rate_percent(ci[0]), rate_percent(ci[1])))
    assert len(segs) == len(want) == 2 * len(DETECTORS) - 1
    assert np.allclose(segs, sorted(want), atol=TOL)
    assert [t.get_text() for t in ax.texts].count("uninf.") == 1


def test_without_ci95_no_error_bars_are_drawn():
    m = _metrics("sibling")
    for blk in m["scenarios"].values():
        del blk["correct_decision_rate_ci95"], blk["outcomes_ci95"]
    for fn in (plots.plot_detection_rates, plots.plot_outcomes, plots.plot_rates_ci):
        ax = Figure().subplots()
        fn(m, ax=ax)
        assert _segments(ax) == [] and _bars(ax)


def test_outcome_error_bars_sit_on_their_segments():
    m = _metrics("sibling")
    ax = Figure().subplots()
    assert plots.plot_outcomes(m, ax=ax) is ax.figure
    segs = _segments(ax)
    # success 60 % (interval 55..65), large error on top 30 % (55..65 moved by 60: 85..95),
    # service failure 10 % (5..15 moved by 90: 95..105), per scenario
    ys = sorted({(round(lo, 6), round(hi, 6)) for _, lo, hi in segs})
    assert ys == [(55.0, 65.0), (85.0, 95.0), (95.0, 105.0)]
    assert len(segs) == 2 * len(OUTCOMES)


def test_rates_ci_and_comparison_detectors_take_ax():
    m = _metrics("sibling")
    ax = Figure().subplots()
    assert plots.plot_rates_ci(m, ax=ax) is ax.figure
    assert len(_segments(ax)) == 2 * len(DETECTORS) - 1
    fig = Figure()
    axes = fig.subplots(1, 2)
    det = {"raytrace": m["scenarios"], "uma": m["scenarios"]}
    assert plots.plot_comparison_detectors(det, ax=axes) is fig
    for a in axes:
        assert set(_bars(a)) == {"raytrace", "uma"}
    # fbs panel: Tracking (uninformative) has no bar in either model, no error bar
    assert len(_segments(axes[1])) == 2 * (len(DETECTORS) - 1)
    with pytest.raises(InputError, match="ax"):
        plots.plot_comparison_detectors(det, ax=axes[:1])


def test_time_series_takes_six_axes(rng):
    n = 12
    rows = {d: rng.integers(0, 2, n).astype(float) for d in DETECTORS}
    rows.update(index=np.arange(n), error_m=rng.uniform(1, 50, n))
    fig = Figure()
    axes = fig.subplots(6, 1)
    assert plots.plot_time_series(rows, None, (3, 8), ax=axes) is fig
    for a, d in zip(axes, DETECTORS):
        assert np.array_equal(a.lines[0].get_ydata(), rows[d])
    assert np.allclose(axes[-1].lines[0].get_ydata(), rows["error_m"])
    assert all(len(a.patches) == 1 for a in axes)    # the attack window's span


def test_pareto_and_cdfs_take_their_axes(rng):
    rows = [{"group": "raytrace", "label": f"s{k}", "role": r, "time_s": t, "time_unit": "link",
             "pareto": p, "dev": d} for k, (r, t, p, d) in enumerate(
                 [("reference", 1.0, True, 0.0), ("config", 0.1, True, 0.5),
                  ("sweep", 0.2, False, 2.0)])]
    ax = Figure().subplots()
    assert plots.plot_pareto(rows, None, {"raytrace": ("dev", "dB")}, ax=ax) is ax.figure
    assert len(ax.collections) == 3    # one marker per setting
    benign = {m: SimpleNamespace(position_error_m=rng.uniform(0, 9, 20),
                                 toa_bias_m=rng.normal(0, 3, 20), rstd_error_m=rng.normal(0, 3, 20),
                                 aoa_error_deg=rng.uniform(0, 5, 20)) for m in ("raytrace", "uma")}
    fig = Figure()
    axes = fig.subplots(2, 2)
    assert plots.plot_comparison_cdfs(benign, ax=axes) is fig
    assert all(len(a.lines) == 2 for a in axes.ravel())


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("axes")
    (d / "c.json").write_text(json.dumps(TINY))
    assert main(["run", str(d / "c.json"), "--out", str(d / "r"), "--workers", "1", "-q"]) == 0
    return d / "r"


def test_roc_takes_one_axes_per_attack(tiny_run):
    from veriloc_rt.analysis.detection import analyse_detection
    from veriloc_rt.report.results import read_rows, results_path
    from veriloc_rt.report.roc_report import plot_roc

    cfg = config_from_dict(json.loads((tiny_run / "run.json").read_text())["config"])
    rows = {s: read_rows(results_path(tiny_run, s)) for s in ("none", "fbs")}
    analysis = analyse_detection(rows, cfg)
    ax = Figure().subplots()
    assert plot_roc(analysis, ax=[ax]) is ax.figure    # one attack: fbs
    curves = [ln for ln in ax.lines if ln.get_linestyle() in ("-", "--")]
    assert len(curves) >= len(DETECTORS)
    assert ax.get_title() == "fbs"


def test_scene_top_views_take_ax(tmp_path):
    import shapely

    from veriloc_rt.report.osm_plot import plot_osm_top_view
    from veriloc_rt.report.scene_plot import plot_top_view
    from veriloc_rt.world.geometry import build_geometry

    geo = build_geometry(config_from_dict(TINY), tmp_path / "scene")
    ax = Figure().subplots()
    assert plot_top_view(geo, ax=ax) is ax.figure
    assert any(isinstance(c, LineCollection) for c in ax.collections)   # the UE path
    assert (plot_top_view(geo, tmp_path / "top.svg")).read_bytes().startswith(b"<?xml")
    city = SimpleNamespace(
        footprints=[shapely.box(0, 0, 10, 10), shapely.box(20, 0, 30, 10)],
        materials=np.array(["brick", "glass"]), street_nodes=np.array([[0.0, 15.0], [30.0, 15.0]]),
        street_edges=np.array([[0, 1]]), origin_lonlat_deg=(11.5, 48.1), num_buildings=2,
        extent=lambda: (0.0, 0.0, 30.0, 10.0))
    ax = Figure().subplots()
    assert plot_osm_top_view(city, ax=ax) is ax.figure
    assert sum(len(c.get_paths()) for c in ax.collections if not isinstance(c, LineCollection)) == 2


def test_validation_plot_takes_ax(rng):
    from veriloc_rt.report.validation_plot import plot_validation_pathloss
    from veriloc_rt.studies.validate import MODELS, model_db

    d = rng.uniform(50, 500, 30)
    res = SimpleNamespace(
        inputs={"h_bs_m": 25.0, "h_ue_m": 1.5, "h_roof_m": 15.0, "street_width_m": 10.0,
                "building_separation_m": 40.0, "carrier_frequency_hz": 3.5e9,
                "phi_deg_median": 45.0, "covered_fraction_median": 0.8, "bin_width_m": 100.0},
        links={"d_2d_m": d, "has_path": np.ones(30, bool), "los": d < 100,
               "pl_db": 100 + 20 * np.log10(d)},
        bins=[{"d_centre_m": 150.0, "traced_db": {"p10": 140.0, "p50": 145.0, "p90": 150.0}}],
        flags={m: [] for m in MODELS})
    ax = Figure().subplots()
    assert plot_validation_pathloss(res, None, MODELS, model_db, ax=ax) is ax.figure
    assert len(ax.collections) >= 2 and any(isinstance(c, ErrorbarContainer) for c in ax.containers)
