"""The recipes of docs/extending.md: each example plug-in of examples/plugins/ (a threat, a
detector, a propagation model, a scene source, each one file that registers itself) runs end to
end through ``veriloc_rt.run`` on a tiny config, and its numbers match an independent
derivation."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

import veriloc_rt
from veriloc_rt.attacks.threats import THREAT_REGISTRY
from veriloc_rt.config import config_from_dict
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.detectors.registry import DETECTOR_REGISTRY
from veriloc_rt.errors import InputError
from veriloc_rt.propagation.models import PROPAGATION_REGISTRY
from veriloc_rt.world.scene.external import MeshScene
from veriloc_rt.world.sources import SCENE_SOURCE_REGISTRY
from veriloc_rt.world.streets import CLEARANCE_M

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "plugins"
NUM_POINTS = 8
#: the run: free-space links, the benign run and the constant-bias spoofer, the ToA-spread
#: detector after the built-in five; no power control, so each TRP sends bs_max_power_dbm
CONFIG = {"seed": 3, "propagation": {"model": "free_space"},
          "trajectory": {"num_points": NUM_POINTS}, "channel": {"power_control": False},
          "run": {"scenarios": ["none", "constant_bias"], "evaluate_encrypted": False,
                  "digsig": "shared"},
          "detectors": {"extra": ["ToASpread"]}}


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"veriloc_example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)   # registers the plug-in
    return module


@pytest.fixture(scope="module")
def plugins():
    mods = {n: _load(n) for n in ("constant_bias", "toa_spread", "free_space")}
    yield mods
    THREAT_REGISTRY.unregister("constant_bias")
    DETECTOR_REGISTRY.unregister("ToASpread")
    PROPAGATION_REGISTRY.unregister("free_space")


@pytest.fixture(scope="module")
def run_dir(plugins, tmp_path_factory):
    out = tmp_path_factory.mktemp("extending")
    res = veriloc_rt.run(config_from_dict(CONFIG), out)
    return out, res


def _csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_free_space_model_received_power_is_friis(run_dir):
    """Every link row's received power equals P_max + 20 log10(lambda / (4 pi d)) (Friis, 3-D
    distance d of the row) to 1e-9 dB: the CSV holds repr-exact floats, so only the rounding of
    the two log10s separates them."""
    out, res = run_dir
    cfg = res.config
    lam = SPEED_OF_LIGHT / cfg.propagation.carrier_frequency_hz
    rows = _csv(out / "none_links.csv")
    assert len(rows) == NUM_POINTS * cfg.topology.num_trps
    for r in rows:
        friis_db = 20.0 * math.log10(lam / (4.0 * math.pi * float(r["distance_m"])))
        assert float(r["rx_power_dbm"]) == pytest.approx(cfg.channel.bs_max_power_dbm + friis_db,
                                                         abs=1e-9)
    assert res.metrics["propagation_model"] == "free_space"


def test_constant_bias_threat_moves_one_toa_by_the_bias(run_dir, plugins):
    """At every attack point the biased TRP's ToA error is c * BIAS_S (-149.9 m) to 0.5 m (the
    ToA estimate on one free-space path errs by under 0.01 m in the benign run; the other
    copies' leakage stays well under the tolerance, 1/300 of the bias); outside the attack
    window the fixes equal the benign run's (common random numbers)."""
    out, _ = run_dir
    ex = plugins["constant_bias"]
    bias_m = SPEED_OF_LIGHT * ex.BIAS_S
    attack = {int(r["index"]) for r in _csv(out / "constant_bias_results.csv")
              if r["attack"] == "1"}
    assert attack   # the window holds points
    links = _csv(out / "constant_bias_links.csv")
    biased = [float(r["toa_error_m"]) for r in links
              if int(r["index"]) in attack and int(r["trp"]) == ex.SLOT and r["heard"] == "1"]
    assert len(biased) == len(attack)
    np.testing.assert_allclose(biased, bias_m, atol=0.5)
    # before the window every column equals the benign run's; after it the fixes do (the
    # tracker carries the attack's state on)
    benign = {r["index"]: r for r in _csv(out / "none_results.csv")}
    fix = ("x_est", "y_est", "error_m", "outcome")
    for r in _csv(out / "constant_bias_results.csv"):
        i = int(r["index"])
        if i < min(attack):
            assert r == benign[r["index"]]
        elif i not in attack:
            assert [r[c] for c in fix] == [benign[r["index"]][c] for c in fix]


def test_toa_spread_detector_statistic_by_hand(run_dir, plugins):
    """Each row's toaspread_stat equals c (max - min ToA) over the heard TRPs, rebuilt from the
    links CSV as toa_error_m + distance_m (= c ToA), to 1e-6 m (float rounding of sums of
    ~1 km); its verdict is stat <= MAX_SPREAD_M; metrics.json's correct-decision rate of the
    benign run is the share of valid fixed points."""
    out, res = run_dir
    limit = plugins["toa_spread"].MAX_SPREAD_M
    for scenario in ("none", "constant_bias"):
        ranges: dict[str, list[float]] = {}
        for r in _csv(out / f"{scenario}_links.csv"):
            if r["heard"] == "1":
                ranges.setdefault(r["index"], []).append(float(r["toa_error_m"])
                                                         + float(r["distance_m"]))
        rows = _csv(out / f"{scenario}_results.csv")
        for r in rows:
            c = ranges.get(r["index"], [])
            if len(c) < 2:
                assert r["toaspread_stat"] == "" and r["ToASpread"] == "1"
                continue
            spread = max(c) - min(c)
            assert float(r["toaspread_stat"]) == pytest.approx(spread, abs=1e-6)
            assert r["ToASpread"] == str(int(spread <= limit))
    rows = _csv(out / "none_results.csv")
    fixed = [r for r in rows if r["outcome"] != "service_failure"]
    rate = sum(r["ToASpread"] == "1" for r in fixed) / len(fixed)   # a fraction, as metrics.json holds rates
    got = res.metrics["scenarios"]["none"]["correct_decision_rate"]["ToASpread"]
    assert got == pytest.approx(rate, abs=1e-9)


def test_registered_names_and_unknown_ones(plugins, tmp_path):
    """A registered plug-in is a choice of its field; an unknown name is one InputError naming
    the field, raised before the output folder is created."""
    from veriloc_rt.sim.plugins import registered_choices

    ch = registered_choices()
    assert ch["run.scenarios"][:4] == ("none", "fbs", "meaconing", "jamming")
    assert "constant_bias" in ch["run.scenarios"] and "free_space" in ch["propagation.model"]
    assert ch["detectors.extra"] == ("ToASpread",)
    cases = {"run.scenarios[1]": {"run": {"scenarios": ["none", "no_such_threat"]}},
             "detectors.extra[0]": {"detectors": {"extra": ["NoSuchDetector"]}},
             "propagation.model": {"propagation": {"model": "no_such_model"}}}
    for field, patch in cases.items():
        cfg = config_from_dict({"trajectory": {"num_points": 4}, **patch})
        with pytest.raises(InputError) as e:
            veriloc_rt.run(cfg, tmp_path / "never")
        assert e.value.field == field and "unknown" in str(e.value)
        assert not (tmp_path / "never").exists()
    # the built-in detectors always run: naming one in detectors.extra is refused
    with pytest.raises(InputError, match="detectors.extra"):
        veriloc_rt.run(config_from_dict({"detectors": {"extra": ["ABSA"]}}), tmp_path / "never")


#: the scene-source recipe's run: one 35 m building (examples/plugins/one_building.py), BSs at
#: their fixed height (rooftop placement would put every BS on the one roof), UMa links
SCENE_HEIGHT_M = 35.0
SCENE_CONFIG = {"seed": 3, "scene": {"source": f"one_building:{SCENE_HEIGHT_M:g}"},
                "topology": {"placement": "fixed"}, "propagation": {"model": "uma"},
                "trajectory": {"num_points": 6},
                "run": {"scenarios": ["none"], "evaluate_encrypted": False}}


@pytest.fixture(scope="module")
def scene_run(tmp_path_factory):
    mod = _load("one_building")
    out = tmp_path_factory.mktemp("one-building")
    res = veriloc_rt.run(config_from_dict(SCENE_CONFIG), out)
    yield mod, out, res
    SCENE_SOURCE_REGISTRY.unregister("one_building")


def test_scene_source_plugin_builds_the_run_scene(scene_run):
    """The run's written scene (read back from scene/scene.xml) holds the plug-in's one building
    with the footprint the module sets and the height the config gives, exactly (integers in
    metres survive the PLY's float32); the generated drive keeps at least the street
    clearance from its walls (the distance to the rectangle computed here)."""
    mod, out, res = scene_run
    scene = MeshScene.from_xml(out / "scene" / "scene.xml")
    assert len(scene.buildings) == 1
    lo, hi = scene.buildings[0].bounds
    (cx, cy), s = mod.CENTRE_XY, mod.SIDE_M / 2.0
    assert lo.tolist() == [cx - s, cy - s, 0.0]
    assert hi.tolist() == [cx + s, cy + s, SCENE_HEIGHT_M]
    rows = _csv(out / "none_results.csv")
    assert len(rows) == SCENE_CONFIG["trajectory"]["num_points"]
    for r in rows:
        dx = max(abs(float(r["x_true"]) - cx) - s, 0.0)
        dy = max(abs(float(r["y_true"]) - cy) - s, 0.0)
        # tolerance 1e-9 m: the CSV's repr-exact floats, subtraction rounding only
        assert math.hypot(dx, dy) >= CLEARANCE_M - 1e-9
    assert res.config.scene.source_name == "one_building"


def test_scene_source_names_checked(scene_run, tmp_path):
    """The plug-in is a registered choice of scene.source; an unknown source (before the output
    folder exists) or a bad argument (when the plug-in builds the scene) is one InputError
    naming scene.source."""
    from veriloc_rt.sim.plugins import registered_choices

    assert registered_choices()["scene.source"] == ("canyon", "xml", "sionna", "osm",
                                                    "one_building")
    for source, words, made in (("no_such_scene", "unknown scene source", False),
                                ("one_building:tall", "height of 2 to 500 m", True)):
        cfg = config_from_dict({**SCENE_CONFIG, "scene": {"source": source}})
        with pytest.raises(InputError) as e:
            veriloc_rt.run(cfg, tmp_path / source)
        assert e.value.field == "scene.source" and words in str(e.value)
        assert (tmp_path / source).exists() == made
