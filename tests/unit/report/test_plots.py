"""Result figures write valid PNGs on synthetic data; the results CSV reader round-trips exactly."""

import math

import numpy as np
import pytest

from veriloc_rt.errors import InputError
from veriloc_rt.report.plots import (COLUMNS, DETECTORS, clear_figure_cache, plot_detection_rates,
                                     plot_outcomes, plot_time_series, plot_trajectory_map,
                                     read_results_csv)

# A PNG with axes, bars and text is tens of kB; a blank or truncated file is far below this.
MIN_PNG_BYTES = 5_000
NUM_POINTS = 40
WINDOW = (10, 30)  # 0-based attack points 10..29


def assert_png(path):
    data = path.read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n")
    assert len(data) > MIN_PNG_BYTES


def outcomes(s, le, sf):
    """Outcome shares given in percent, as metrics.json holds them: fractions."""
    return {"success": s / 100, "large_error": le / 100, "service_failure": sf / 100}


def rates(*v):
    """Correct-decision rates given in percent, as metrics.json holds them: fractions."""
    return dict(zip(DETECTORS, (None if x is None else x / 100 for x in v)))


def pct_rates(*v):
    """A reference in percent (the paper's figures)."""
    return dict(zip(DETECTORS, v))


@pytest.fixture
def metrics():
    return {"scenarios": {
        "none": {"outcomes": outcomes(98.9, 1.1, 0.0), "outcomes_encrypted": outcomes(99, 1, 0),
                 "correct_decision_rate": rates(99.1, 98.7, 96.8, 99.4, 95.7)},
        "fbs": {"outcomes": outcomes(0.7, 19.8, 79.5), "outcomes_encrypted": outcomes(49, 1, 50),
                "correct_decision_rate": rates(99.5, 100.0, 99.4, 99.0, 98.3)},
        "meaconing": {"outcomes": outcomes(3.8, 95.5, 0.7),
                      "outcomes_encrypted": outcomes(2.5, 91.7, 5.8),
                      "correct_decision_rate": rates(31.8, 31.7, 99.8, 92.7, None)},
        "jamming": {"outcomes": outcomes(0, 0, 100), "outcomes_encrypted": outcomes(0, 0, 100),
                    "correct_decision_rate": rates(100, 100, 100, 100, 100)},
    }}


@pytest.fixture
def rows(rng):
    i = np.arange(NUM_POINTS)
    attack = (i >= WINDOW[0]) & (i < WINDOW[1])
    t = np.linspace(0.0, 2 * np.pi, NUM_POINTS)
    x_true, y_true = 100 * np.cos(t), 100 * np.sin(t)
    err = np.where(attack, 400.0, rng.uniform(0.5, 5.0, NUM_POINTS))
    err[::7] = np.nan  # service failures
    outcome = np.where(np.isnan(err), "service_failure",
                       np.where(err > 15.0, "large_error", "success"))
    x_est = x_true + np.where(i == 20, 1e5, err)  # one absurd spoofed outlier
    r = {"Time": i.astype(float), "index": i, "attack": attack.astype(float),
         "x_true": x_true, "y_true": y_true, "x_est": x_est, "y_est": y_true.copy(),
         "error_m": err, "outcome": outcome}
    for k, d in enumerate(DETECTORS):
        r[d] = np.where(attack & (i % (k + 2) == 0), 0.0, 1.0)
    return r


BS_POS = np.array([[0.0, 250.0, 25.0], [-216.5, -125.0, 25.0], [216.5, -125.0, 25.0]])


def test_outcomes_png(metrics, tmp_path):
    out = plot_outcomes(metrics, tmp_path / "outcomes.png", title="Outcomes")
    assert out == tmp_path / "outcomes.png"
    assert_png(out)


def test_outcomes_without_encrypted_and_with_missing_scenarios(metrics, tmp_path):
    sc = {s: {k: v for k, v in m.items() if k != "outcomes_encrypted"}
          for s, m in metrics["scenarios"].items() if s in ("none", "jamming")}
    sc["none"]["outcomes"]["large_error"] = None
    assert_png(plot_outcomes({"scenarios": sc}, str(tmp_path / "o.png")))
    assert_png(plot_outcomes({"scenarios": {}}, tmp_path / "empty.png"))


def test_detection_rates_png_with_reference(metrics, tmp_path):
    ref = {"none": pct_rates(99.16, 98.75, 96.77, 99.39, 95.72),
           "fbs": pct_rates(99.5, 100, 99.37, 99, 98.33)}
    assert_png(plot_detection_rates(metrics, tmp_path / "rates.png", title="Rates", reference=ref))


def test_detection_rates_missing_scenarios(metrics, tmp_path):
    del metrics["scenarios"]["fbs"], metrics["scenarios"]["jamming"]
    assert_png(plot_detection_rates(metrics, tmp_path / "rates.png"))
    assert_png(plot_detection_rates({"scenarios": {}}, tmp_path / "empty.png"))


def test_metrics_of_the_wrong_type_raise_type_error(tmp_path):
    with pytest.raises(TypeError, match="metrics"):
        plot_outcomes([1, 2], tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def test_time_series_png(rows, tmp_path):
    assert_png(plot_time_series(rows, tmp_path / "ts.png", WINDOW, title="FBS"))


def test_time_series_all_nan_error_and_no_window(rows, tmp_path):
    rows["error_m"] = np.full(NUM_POINTS, np.nan)
    assert_png(plot_time_series(rows, tmp_path / "ts.png", None))


def pixels(path):
    from PIL import Image

    return np.asarray(Image.open(path))


def test_time_series_reused_figure_gives_a_new_figures_pixels(rows, rng, tmp_path):
    """The time-series figure is built once and updated per scenario; each update must give
    exactly the pixels a figure built for that scenario alone gives (the oracle: the cache
    cleared before each). Scenarios differ in data, length, window (or none) and title."""
    other = {k: (v[:25] if isinstance(v, np.ndarray) else v) for k, v in rows.items()}
    other["error_m"] = rng.uniform(20.0, 30.0, 25)      # about one decade: minor labels too
    for d in DETECTORS:
        other[d] = rng.integers(0, 2, 25).astype(float)
    cases = [(rows, WINDOW, "fbs"), (other, None, "none"), (rows, (0, 5), "jamming")]
    clear_figure_cache()
    for k, (r, window, title) in enumerate(cases):      # one figure, updated
        plot_time_series(r, tmp_path / f"reused{k}.png", window, title=title)
    for k, (r, window, title) in enumerate(cases):      # a new figure each
        clear_figure_cache()
        plot_time_series(r, tmp_path / f"new{k}.png", window, title=title)
    for k in range(len(cases)):
        assert np.array_equal(pixels(tmp_path / f"reused{k}.png"), pixels(tmp_path / f"new{k}.png")), k


def test_trajectory_map_reused_figure_gives_a_new_figures_pixels(rows, tmp_path):
    """The map's axes are kept and redrawn per scenario; each map must give the pixels of a
    figure built for it alone. Maps with an estimate beyond the view and an adversary, without
    fixes, and on another (smaller) area without adversary."""
    no_fix = dict(rows, x_est=np.full(NUM_POINTS, np.nan), y_est=np.full(NUM_POINTS, np.nan))
    small = {k: (v[:12] if isinstance(v, np.ndarray) else v) for k, v in rows.items()}
    small["x_est"] = small["x_true"] + 3.0
    adversary = np.column_stack([np.linspace(-50, 50, NUM_POINTS), np.zeros(NUM_POINTS)])
    cases = [(rows, adversary, "fbs"), (no_fix, None, "jamming"), (small, None, "none")]
    clear_figure_cache()
    for k, (r, adv, title) in enumerate(cases):
        plot_trajectory_map(r, BS_POS, tmp_path / f"reused{k}.png", adversary_xy=adv, title=title)
    for k, (r, adv, title) in enumerate(cases):
        clear_figure_cache()
        plot_trajectory_map(r, BS_POS, tmp_path / f"new{k}.png", adversary_xy=adv, title=title)
    for k in range(len(cases)):
        assert np.array_equal(pixels(tmp_path / f"reused{k}.png"), pixels(tmp_path / f"new{k}.png")), k


def test_time_series_rejects_bad_window_and_missing_column(rows, tmp_path):
    with pytest.raises(InputError, match="attack_window"):
        plot_time_series(rows, tmp_path / "ts.png", (30, 10))
    del rows["ABSA"]
    with pytest.raises(InputError, match="ABSA"):
        plot_time_series(rows, tmp_path / "ts.png", WINDOW)


def test_trajectory_map_png(rows, tmp_path):
    adv = np.stack([rows["x_true"] + 20.0, rows["y_true"]], axis=-1)
    assert_png(plot_trajectory_map(rows, BS_POS, tmp_path / "map.png", adversary_xy=adv,
                                   title="Map"))


def test_trajectory_map_without_fixes(rows, tmp_path):
    for c in ("x_est", "y_est", "error_m"):
        rows[c] = np.full(NUM_POINTS, np.nan)
    rows["outcome"] = np.full(NUM_POINTS, "service_failure")
    assert_png(plot_trajectory_map(rows, BS_POS[:, :2], tmp_path / "map.png"))


def test_trajectory_map_rejects_bad_bs_shape(rows, tmp_path):
    with pytest.raises(InputError, match="bs_pos"):
        plot_trajectory_map(rows, np.zeros(3), tmp_path / "map.png")


CSV_TEXT = (",".join(COLUMNS) + "\n"
            "0.0,1,1,1,1,1,10.5,-2.25,11.0,-2.0,0.559,success,0,0,10.75,-2.5,0.25,success,"
            "1.0,1.0,3.5,2.0,0.0\n"
            "1.0,0,1,0,1,1,11.5,-2.25,,,,service_failure,1,1,nan,nan,nan,service_failure,"
            "0.0,0.5,inf,12.0,1.2\n"
            "2.0,0,0,1,1,0,12.5,-2.25,80.0,40.0,79.7,large_error,2,1,,,,,0.25,0.0,19.9,5.5,inf\n")


def test_read_results_csv_round_trip(tmp_path):
    p = tmp_path / "fbs_results.csv"
    p.write_text(CSV_TEXT)
    r = read_results_csv(p)
    assert tuple(r) == COLUMNS
    assert r["Time"].tolist() == [0.0, 1.0, 2.0]
    assert r["HMAC"].tolist() == [1.0, 0.0, 0.0] and r["Tracking"].tolist() == [1.0, 1.0, 0.0]
    assert r["x_true"].tolist() == [10.5, 11.5, 12.5]
    assert r["index"].dtype == np.int64 and r["index"].tolist() == [0, 1, 2]
    assert r["attack"].tolist() == [0.0, 1.0, 1.0]
    assert r["outcome"].tolist() == ["success", "service_failure", "large_error"]
    assert r["outcome_enc"].tolist() == ["success", "service_failure", ""]
    assert r["x_est"][0] == 11.0 and r["error_m"][2] == 79.7
    assert math.isnan(r["x_est"][1]) and math.isnan(r["error_m"][1])  # empty cells
    assert np.isnan(r["x_est_enc"][1:]).all()  # 'nan' and empty cells
    assert r["error_m_enc"][0] == 0.25
    assert r["absa_stat"].tolist() == [3.5, math.inf, 19.9]   # 'inf': rejected by a rule
    assert r["tracking_stat"].tolist() == [0.0, 1.2, math.inf]


def test_read_results_csv_header_only_and_empty_file(tmp_path):
    p = tmp_path / "none_results.csv"
    p.write_text(",".join(COLUMNS) + "\n")
    r = read_results_csv(p)
    assert tuple(r) == COLUMNS and all(len(v) == 0 for v in r.values())
    p.write_text("")
    assert tuple(read_results_csv(p)) == COLUMNS


def test_read_results_csv_names_line_of_bad_cell(tmp_path):
    p = tmp_path / "bad_results.csv"
    p.write_text(CSV_TEXT.replace("12.5", "twelve"))
    with pytest.raises(InputError, match=r"bad_results.csv:4.*x_true"):
        read_results_csv(p)
