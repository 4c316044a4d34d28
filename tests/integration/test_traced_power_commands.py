"""``topology.selection`` 'traced_power' in ``veriloc-rt compare``, ``bench`` and ``validate``
(``run`` is covered by tests/unit/world/test_traced_power.py): each command measures, at every
point, the candidates with the strongest received power.

The independent check traces every candidate link of the config's geometry directly
(:func:`veriloc_rt.propagation.raytrace.trace` with all candidates as serving, no cache), sums
|a|^2 over each link's valid paths and antenna elements by hand, ranks the candidates (power
descending, ties nearest first) and compares that ranking with the BS ids each command's files
name. The sites stand 20 m high (above the 15 m roofs) on a 50 m grid over the CI canyon, so
that a farther site in line of sight down a street outranks a nearer one behind a block: at
least one point's choice must differ from its nearest sites (else the test could not tell the
two selections apart).
"""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.cli import main
from veriloc_rt.config import load_config
from veriloc_rt.propagation.raytrace import trace
from veriloc_rt.world.geometry import build_geometry

pytestmark = [pytest.mark.raytrace, pytest.mark.heavy]

POINTS = 4
NUM_TRPS = 3


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("traced_power")
    g = np.arange(-100.0, 101.0, 50.0)
    rows = [f"{x:g},{y:g},20" for x in g for y in g]
    (d / "sites.csv").write_text("x,y,z\n" + "\n".join(rows) + "\n")
    cfg_path = d / "c.json"
    cfg_path.write_text(json.dumps({
        "seed": 3,
        "scene": {"extent_m": 140.0, "margin_m": 30.0},
        "trajectory": {"num_points": POINTS, "region_m": 70.0},
        "propagation": {"raytrace": {"rays_per_source": 3000}},
        "topology": {"sites": "sites.csv", "num_trps": NUM_TRPS, "selection": "traced_power",
                     "candidate_radius_m": 90.0},
        "run": {"scenarios": ["none"]}}))
    cfg = load_config(cfg_path)
    geo = build_geometry(cfg, d / "scene-check")
    cand = geo.candidates
    padded = np.where(cand >= 0, cand, cand[:, :1])
    cir = trace(replace(geo, serving=padded), cfg.propagation, cfg.seed, cache_dir=None,
                adversary_points=np.zeros(geo.num_points, bool)).bs_ue
    # |a|^2 summed over valid paths, averaged over the UE's elements: [P, C]
    power = (np.abs(cir.gains) ** 2 * cir.valid[:, :, None, :]).sum(axis=-1).mean(axis=-1)
    expect = []
    for k in range(geo.num_points):
        cols = [j for j in range(cand.shape[1]) if cand[k, j] >= 0]
        ranked = sorted(cols, key=lambda j: (-power[k, j], j))[:NUM_TRPS]
        expect.append([int(cand[k, j]) for j in ranked])
    expect = np.array(expect)
    nearest = cand[:, :NUM_TRPS]
    assert any(set(e) != set(n) for e, n in zip(expect, nearest)), \
        "every point's strongest candidates are its nearest: the test would not discriminate"
    return {"dir": d, "config": str(cfg_path), "expect": expect, "bs_pos": geo.bs_pos}


def _links_bs(path: Path) -> np.ndarray:
    """[points, trps] BS ids of a run's links CSV, in slot order."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    P = max(int(r["index"]) for r in rows) + 1
    T = max(int(r["trp"]) for r in rows) + 1
    out = np.full((P, T), -1)
    for r in rows:
        out[int(r["index"]), int(r["trp"])] = int(r["bs_id"])
    return out


def test_compare_both_arms_measure_the_strongest(setup, monkeypatch):
    seen = _spy_maps(monkeypatch)
    out = setup["dir"] / "compare"
    assert main(["compare", setup["config"], "--out", str(out), "--workers", "1", "-q"]) == 0
    assert len(seen) == 2            # each arm's map: the chosen BSs apart from the others
    for s in seen:
        _check_map(s, setup)
    traced = _links_bs(out / "raytrace" / "none_links.csv")
    np.testing.assert_array_equal(traced, setup["expect"])
    res = json.loads((out / "comparison.json").read_text())
    twin = res["twin"]["model"]
    # the twin measures the same TRPs: only the channel differs
    np.testing.assert_array_equal(_links_bs(out / twin / "none_links.csv"), setup["expect"])
    assert "ray-tracing arm" in res["twin"]["serving"]
    assert "serving" in json.loads((out / twin / "run.json").read_text())


def test_bench_traces_the_strongest(setup):
    out = setup["dir"] / "bench"
    assert main(["bench", setup["config"], "--quick", "--points", str(POINTS), "--only",
                 "raytrace", "--out", str(out), "-q"]) == 0
    meta = json.loads((out / "bench.json").read_text())["meta"]
    got = np.array(meta["serving"])
    np.testing.assert_array_equal(got, setup["expect"][meta["points"]])


def test_validate_traces_the_strongest(setup):
    out = setup["dir"] / "validate"
    assert main(["validate", setup["config"], "--out", str(out), "-q"]) == 0
    with open(out / "validation_links.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    got: dict[int, set] = {}
    for r in rows:
        got.setdefault(int(r["point"]), set()).add(int(r["bs"]))
    assert {k: got[k] for k in sorted(got)} == {k: set(e) for k, e in
                                              enumerate(setup["expect"])}
    res = json.loads((out / "validation.json").read_text())
    assert any("traced_power" in f for f in res["models"]["p1411"]["outside_validity"])


def _spy_maps(monkeypatch) -> list[dict]:
    """Record, for every map the run or ``veriloc-rt plot`` draws, the BS markers' positions
    by legend label (the figure drawn again without a path, then the real call)."""
    from veriloc_rt.report import plots

    real, seen = plots.plot_trajectory_map, []

    def spy(rows, bs_pos, path=None, **kw):
        fig = real(rows, bs_pos, None, **kw)
        ax = fig.axes[0]
        seen.append({ln.get_label(): np.column_stack([ln.get_xdata(), ln.get_ydata()])
                     for ln in ax.lines if ln.get_marker() == "^"})
        seen[-1]["legend"] = [t.get_text() for t in ax.get_legend().get_texts()]
        return real(rows, bs_pos, path, **kw)

    monkeypatch.setattr(plots, "plot_trajectory_map", spy)
    return seen


def _check_map(seen: dict, setup) -> None:
    """Filled markers exactly at the BSs some point measured (the independent ranking's
    union), hollow ones at every other candidate, both in the legend with their counts."""
    from veriloc_rt.report.plots import SERVING_LABEL, UNUSED_LABEL

    bs = setup["bs_pos"][:, :2]
    used = np.zeros(len(bs), bool)
    used[np.unique(setup["expect"])] = True
    assert (~used).any(), "every candidate serves some point: nothing to tell apart"
    serving_label = f"{SERVING_LABEL} ({int(used.sum())})"
    unused_label = f"{UNUSED_LABEL} ({int((~used).sum())})"
    assert set(seen) - {"legend"} == {serving_label, unused_label}
    key = lambda a: sorted(map(tuple, np.round(a, 6)))  # noqa: E731
    assert key(seen[serving_label]) == key(bs[used])
    assert key(seen[unused_label]) == key(bs[~used])
    assert serving_label in seen["legend"] and unused_label in seen["legend"]


def test_maps_draw_serving_apart_from_unused_candidates(setup, monkeypatch):
    from veriloc_rt.sim import engine

    seen = _spy_maps(monkeypatch)
    real_top, tops = engine.plot_top_view, []

    def spy_top(geometry, path=None, **kw):
        ax = real_top(geometry, None, **kw).axes[0]
        tops.append({ln.get_label(): np.column_stack([ln.get_xdata(), ln.get_ydata()])
                     for ln in ax.lines if ln.get_marker() == "^"})
        tops[-1]["legend"] = [t.get_text() for t in ax.get_legend().get_texts()]
        return real_top(geometry, path, **kw)

    monkeypatch.setattr(engine, "plot_top_view", spy_top)
    out = setup["dir"] / "maps-run"
    assert main(["run", setup["config"], "--out", str(out), "--workers", "1", "-q"]) == 0
    assert len(seen) == 1
    _check_map(seen[0], setup)
    # the summary counts the chosen sites apart from the candidates
    summary = json.loads((out / "propagation_summary.json").read_text())
    assert summary["num_bs_serving"] == len(np.unique(setup["expect"]))
    assert summary["num_bs"] > summary["num_bs_serving"]
    # the scene's top view: drawn before the choice (every candidate alike), then again
    assert len(tops) == 2 and list(tops[0]) == ["candidate sites (chosen by traced power)",
                                                "legend"]
    _check_map(tops[1], setup)
    seen.clear()
    assert main(["plot", str(out), "--out", str(setup["dir"] / "maps-plot")]) == 0
    assert len(seen) == 1
    _check_map(seen[0], setup)


def test_live_view_sends_the_serving_sites_apart_from_unused_candidates(setup):
    """``veriloc-rt view`` on the run's folder: the map's BSs are the candidate sites and the
    polled state flags exactly those some point measured (the independent ranking's union),
    as the run's maps draw them; the summary lists the same ids."""
    import urllib.request

    from veriloc_rt.live.server import TOKEN_HEADER, LiveServer

    def get(url: str):
        req = urllib.request.Request(url, headers={TOKEN_HEADER: server.token})
        with urllib.request.urlopen(req, timeout=30) as r:
            return json.loads(r.read())

    out = setup["dir"] / "live-run"
    assert main(["run", setup["config"], "--out", str(out), "--workers", "1", "-q"]) == 0
    used = np.zeros(len(setup["bs_pos"]), bool)
    used[np.unique(setup["expect"])] = True
    assert (~used).any(), "every candidate serves some point: nothing to tell apart"
    summary = json.loads((out / "propagation_summary.json").read_text())
    assert summary["serving_bs"] == np.flatnonzero(used).tolist()
    server = LiveServer(out, port=0).start()
    try:
        base = f"http://127.0.0.1:{server.port}/"
        get(base + "api/scene")          # starts building the map's layer
        server.view.wait_scene(120)
        scene = get(base + "api/scene")
        # the map's BSs are the run's candidates, in the ids' order (the page's coordinates
        # are rounded to COORD_STEP_M = 0.01 m: half a step, plus float slack)
        np.testing.assert_allclose(scene["bs"], setup["bs_pos"][:, :2], atol=0.006)
        assert get(base + "api/state")["serving"] == used.tolist()
    finally:
        server.shutdown()
