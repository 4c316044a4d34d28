"""The command line as a user runs it: exit codes, one-line errors, files written."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from .strict_json import assert_strict_json_text

ROOT = Path(__file__).resolve().parents[2]


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "veriloc_rt.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd or ROOT)


@pytest.mark.parametrize("config, field", [
    ({"scene": {"street_width_m": -1}}, "scene.street_width_m"),
    ({"trajectory": {"bogus": 1}}, "trajectory.bogus"),
    ({"scene": {"source": "missing.xml"}}, "scene.source"),
    ({"trajectory": {"source": "missing.csv"}}, "trajectory.source"),
    ({"topology": {"isd_m": 5}}, "topology.isd_m"),
    ({"topology": {"bs_height_m": "high"}}, "topology.bs_height_m"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, config, field):
    f = tmp_path / "c.json"
    f.write_text(json.dumps(config))
    r = cli("run", f, "--out", tmp_path / "out")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {field}: ")
    assert "Traceback" not in r.stderr


def test_trajectory_through_a_building_is_rejected(tmp_path):
    csv = tmp_path / "t.csv"
    csv.write_text("t,x,y\n0,0,0\n1,0,10\n2,12,12\n")  # (12, 12) is inside a 30 m block
    f = tmp_path / "c.json"
    f.write_text(json.dumps({"trajectory": {"source": "t.csv"}}))
    r = cli("scene", f, "--out", tmp_path / "out")
    assert r.returncode == 2
    assert "inside a building" in r.stderr and "point 2" in r.stderr


def test_scene_command_writes_xml_ply_png(tmp_path):
    r = cli("scene", ROOT / "configs" / "ci-tiny.json", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    for name in ("scene.xml", "meshes/buildings.ply", "meshes/ground.ply", "scene_top_view.png"):
        assert (tmp_path / name).stat().st_size > 0
    assert (tmp_path / "scene_top_view.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_config_schema_and_show(tmp_path):
    r = cli("config", "schema")
    assert r.returncode == 0 and json.loads(r.stdout)["additionalProperties"] is False
    assert_strict_json_text(r.stdout, tmp_path)
    r = cli("config", "show", ROOT / "configs" / "ci-tiny.json")
    assert r.returncode == 0 and json.loads(r.stdout)["trajectory"]["num_points"] == 40
    assert_strict_json_text(r.stdout, tmp_path)


def test_keys_generate_refuse_overwrite_and_bad_key_file(tmp_path):
    keys = tmp_path / "keys"
    r = cli("keys", "--out", keys, "--num-bs", "3")
    assert r.returncode == 0, r.stderr
    assert len(list(keys.iterdir())) == 12  # AES, HMAC, Ed25519 private + public per BS
    r = cli("keys", "--out", keys, "--num-bs", "3")
    assert r.returncode == 2 and "refusing to overwrite" in r.stderr
    # a run whose key folder lacks BSs or holds a malformed key stops before tracing
    (keys / "bs1.tag.hmac").write_text("not hex\n")
    f = tmp_path / "c.json"
    f.write_text(json.dumps({"security": {"keys_dir": str(keys)},
                             "trajectory": {"num_points": 5}}))
    r = cli("run", f, "--out", tmp_path / "out")
    assert r.returncode == 2
    line = r.stderr.strip().splitlines()
    assert len(line) == 1 and line[0].startswith("error: ") and "bs" in line[0]


@pytest.mark.raytrace
def test_scene_command_on_an_external_scene_creates_the_out_folder(tmp_path):
    # regression: an external scene writes no files of its own, and the PNG went to a folder
    # nobody had created (exit 1, FileNotFoundError)
    out = tmp_path / "new" / "folder"
    r = cli("scene", ROOT / "configs" / "external-mini.json", "--out", out)
    assert r.returncode == 0, r.stderr
    assert (out / "scene_top_view.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
