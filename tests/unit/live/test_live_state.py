"""The live view's reading of a run folder: CSV tailing (torn lines, added columns, a replaced
file), the rate and ETA, the status from run.json and the owner file, the points' JSON."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from veriloc_rt.config import Config, config_from_dict, config_to_dict
from veriloc_rt.detectors.outcomes import DETECTORS, OUTCOMES, PointRow
from veriloc_rt.report.results import CSV_COLUMNS, ResultsWriter, row_to_fields
from veriloc_rt.live.state import RateMeter, ResultsTail, RunFolderState, points_json
from veriloc_rt.sim.run_folder import OWNER_FILE

#: rates and ETAs below are exact ratios of small integers; float rounding only
EXACT = 1e-12


def _row(i: int, outcome: str = "success", valid: bool = True) -> PointRow:
    est = np.array([i + 0.5, -i]) if outcome != "service_failure" else np.full(2, np.nan)
    err = 0.5 if outcome != "service_failure" else float("nan")
    return PointRow(index=i, time_s=float(i), attack=i % 2 == 1,
                    verdicts=dict.fromkeys(DETECTORS, valid), true_xy=np.array([float(i), -i]),
                    est_xy=est, error_m=err, outcome=outcome)


def _line(fields: list[str]) -> str:
    return ",".join(fields) + "\n"


def test_tail_reads_complete_lines_only_and_keeps_the_rest_for_the_next_poll(tmp_path):
    path = tmp_path / "none_results.csv"
    with ResultsWriter(path) as w:
        w.write(_row(0))
    tail = ResultsTail(path)
    assert tail.poll() == 1
    line = _line(row_to_fields(_row(1)))
    with open(path, "a") as fh:          # the run has written half of point 1's line
        fh.write(line[:17])
    assert tail.poll() == 0 and len(tail.rows) == 1
    with open(path, "a") as fh:
        fh.write(line[17:])
    assert tail.poll() == 1
    assert [r.index for r in tail.rows] == [0, 1]
    assert tail.rows[1].est_xy[0] == 1.5 and tail.generation == 0


def test_tail_finds_columns_by_name_when_columns_are_added_at_the_end(tmp_path):
    path = tmp_path / "fbs_results.csv"
    header = [*CSV_COLUMNS, "HMAC_stat", "ABSA_stat"]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for i in range(3):
            w.writerow(row_to_fields(_row(i, "large_error", valid=i != 1)) + ["0.25", "3.5"])
    tail = ResultsTail(path)
    assert tail.poll() == 3
    assert [r.verdicts["Tracking"] for r in tail.rows] == [True, False, True]
    assert [r.outcome for r in tail.rows] == ["large_error"] * 3


def test_tail_rejects_a_file_without_the_documented_columns(tmp_path):
    path = tmp_path / "none_results.csv"
    path.write_text("Time,HMAC\n0.0,1\n")
    tail = ResultsTail(path)
    assert tail.poll() == 0 and tail.rows == []


def test_tail_starts_over_when_the_run_replaces_the_file(tmp_path):
    path = tmp_path / "none_results.csv"
    with ResultsWriter(path) as w:
        for i in range(3):
            w.write(_row(i))
    tail = ResultsTail(path)
    tail.poll()
    with ResultsWriter(path) as w:       # a new run: written aside and renamed (a new inode)
        w.write(_row(0, "service_failure"))
    assert tail.poll() == 1
    assert tail.generation == 1 and tail.rows[0].outcome == "service_failure"


def test_rate_is_points_over_the_observed_time_and_falls_while_stalled():
    m = RateMeter(window_s=60.0)
    m.observe(0.0, 0)              # before the first point (propagation): not point time
    m.observe(4.0, 2)
    assert m.rate(4.0) is None
    m.observe(8.0, 6)
    assert m.rate(8.0) == pytest.approx((6 - 2) / (8 - 4), abs=EXACT)
    # no new point for 4 s: the same 4 points over 8 s
    m.observe(12.0, 6)
    assert m.rate(12.0) == pytest.approx((6 - 2) / (12 - 4), abs=EXACT)


def test_rate_forgets_observations_older_than_its_window():
    m = RateMeter(window_s=10.0)
    for t, d in ((5.0, 50), (20.0, 60), (25.0, 70)):
        m.observe(t, d)
    # the latest observation at least 10 s before t=25 is (5, 50)
    assert m.rate(25.0) == pytest.approx((70 - 50) / (25 - 5), abs=EXACT)
    for t, d in ((30.0, 80), (45.0, 90)):
        m.observe(t, d)
    # the latest observation at least 10 s before t=45 is (30, 80): the older ones are gone
    assert m.rate(45.0) == pytest.approx((90 - 80) / (45 - 30), abs=EXACT)


def test_points_json_columns():
    rows = [_row(0), _row(1, "service_failure", valid=False), _row(2, "large_error")]
    p = points_json(rows, 1)
    assert p["from"] == 1 and p["index"] == [1, 2]
    assert p["x_est"] == [None, 2.5] and p["y_true"] == [-1.0, -2.0]
    assert p["outcome"] == [OUTCOMES.index("service_failure"), OUTCOMES.index("large_error")]
    assert p["attack"] == [1, 0]
    assert p["verdicts"] == {d: [0, 1] for d in DETECTORS}
    json.dumps(p, allow_nan=False)     # no NaN reaches the page


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def _run_json(folder, cfg: Config, status: str) -> None:
    folder.mkdir(exist_ok=True)
    (folder / "run.json").write_text(json.dumps({"config": config_to_dict(cfg), "status": status}))


def test_status_progress_and_eta_of_a_running_folder(tmp_path):
    cfg = config_from_dict({"propagation": {"model": "uma"}, "trajectory": {"num_points": 10},
                            "run": {"scenarios": ["none", "fbs"]}})
    clock = Clock()
    folder = tmp_path / "run"
    view = RunFolderState(folder, clock=clock)
    assert view.state()["status"] == "waiting"
    _run_json(folder, cfg, "running")
    (folder / OWNER_FILE).write_text("pid 1 on host\n")
    st = view.state()
    assert (st["status"], st["stage"]) == ("running", "propagation")
    (folder / "propagation_summary.json").write_text("{}")
    w = ResultsWriter(folder / "none_results.csv")
    w.write(_row(0))
    clock.t = 1.0
    view.state()
    for i in (1, 2, 3):
        w.write(_row(i))
    clock.t = 3.0
    st = view.state("none")
    assert (st["status"], st["stage"]) == ("running", "scenarios")
    none, fbs = st["scenarios"]
    assert (none["done"], none["total"], fbs["done"]) == (4, 10, 0)
    # from the first point seen (t=1, 1 done) to t=3, 4 done: 1.5 points/s; 'none' has 6 left, the run 6 + 10
    assert st["rate_points_per_s"] == pytest.approx(1.5, abs=EXACT)
    assert none["eta_s"] == pytest.approx(6 / 1.5, abs=EXACT)
    assert fbs["eta_s"] == pytest.approx(16 / 1.5, abs=EXACT)
    assert st["eta_s"] == pytest.approx(16 / 1.5, abs=EXACT)
    assert st["points"]["index"] == [0, 1, 2, 3]
    assert view.state("none", 3)["points"]["index"] == [3]
    w.close()
    (folder / OWNER_FILE).unlink()           # the run ended without finishing
    assert view.state()["status"] == "stopped"
    _run_json(folder, cfg, "complete")
    st = view.state()
    assert (st["status"], st["eta_s"]) == ("complete", 0.0)
    view.wait_scene(60)
    assert view.scene()["num_points"] == 10


def test_monte_carlo_folder_follows_the_running_realisation(tmp_path):
    cfg = config_from_dict({"propagation": {"model": "uma"}, "trajectory": {"num_points": 6},
                            "run": {"scenarios": ["none"]}})
    top = tmp_path / "mc"
    top.mkdir()
    names = ["realisation_0", "realisation_1", "realisation_2"]
    (top / "run.json").write_text(json.dumps({
        "config": config_to_dict(cfg), "status": "running",
        "realisations": [{"index": i, "dir": n} for i, n in enumerate(names)]}))
    (top / OWNER_FILE).write_text("pid 1\n")
    _run_json(top / names[0], cfg, "complete")
    with ResultsWriter(top / names[0] / "none_results.csv") as w:
        for i in range(6):
            w.write(_row(i))
    _run_json(top / names[1], cfg, "running")
    with ResultsWriter(top / names[1] / "none_results.csv") as w:
        w.write(_row(0, "large_error"))
    view = RunFolderState(top, clock=Clock())
    st = view.state("none")
    assert st["montecarlo"] == {"done": 1, "total": 3, "following": "realisation_1"}
    assert (st["status"], st["folder"], st["eta_s"]) == ("running", str(top), None)
    assert st["scenarios"][0]["done"] == 1
    assert st["points"]["outcome"] == [OUTCOMES.index("large_error")]
    assert str(st["points"]["generation"]).startswith("realisation_1:")
    view.wait_scene(60)
    assert view.scene()["num_points"] == 6


def test_map_of_a_mesh_scene_has_the_roofs_not_walls_or_ground():
    from pathlib import Path

    from veriloc_rt.live.state import scene_layer
    from veriloc_rt.world.scene.external import MeshScene

    mini = Path(__file__).resolve().parents[3] / "scenes" / "mini_canyon"
    cfg = config_from_dict({"scene": {"source": str(mini / "scene.xml")},
                            "trajectory": {"source": str(mini / "trajectory.csv"),
                                           "num_points": 8}})
    layer = scene_layer(cfg)
    tri = MeshScene.from_xml(mini / "scene.xml").triangles
    # the mini canyon: box buildings of 12 triangles (2 per face) and a ground of 2 triangles;
    # the top view keeps each box's 2 roof triangles
    num_boxes = (len(tri) - 2) // 12
    assert (len(tri) - 2) % 12 == 0
    assert len(layer["triangles"]) == 2 * num_boxes
    assert "buildings" not in layer and len(layer["ue"]) == 8


@pytest.mark.parametrize("summary, expect", [
    ({"num_bs": 4, "serving_bs": [0, 2]}, [True, False, True, False]),
    ({"num_bs": 3, "serving_bs": [0, 1, 2]}, [True, True, True]),
    ({"num_bs": 4, "serving_bs": None}, None),       # no choice among candidates: alike
    ({"num_bs": 4}, None),                           # a summary written before the field
    ({"num_bs": 4, "serving_bs": [0, 4]}, None),     # not an id of the run's BSs
    ({"num_bs": 4, "serving_bs": [0, -1]}, None),
    ({"num_bs": 4, "serving_bs": [True]}, None),     # JSON true is no id
    ({"num_bs": 4, "serving_bs": [1.0]}, None),
    ({"num_bs": "4", "serving_bs": [1]}, None),
    ([1, 2], None),
])
def test_serving_flags_follow_the_folders_propagation_summary(tmp_path, summary, expect):
    """The polled state's ``serving``: one flag per BS from the summary's ``serving_bs`` ids
    (None before the file exists, and whenever its ids are not ids of its ``num_bs`` BSs);
    read again when the file is replaced."""
    view = RunFolderState(tmp_path)
    assert view.state()["serving"] is None
    path = tmp_path / "propagation_summary.json"
    path.write_text(json.dumps(summary))
    assert view.state()["serving"] == expect
    path.unlink()
    path.write_text(json.dumps({"num_bs": 2, "serving_bs": [1], "pad": "x" * 40}))
    assert view.state()["serving"] == [False, True]
