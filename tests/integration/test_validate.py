"""``veriloc-rt validate`` on the CI-sized canyon (configs/ci-tiny.json): files, bins and a
physical invariant that holds whatever the traced numbers are; bad input is one line, exit 2."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from veriloc_rt.cli import main
from veriloc_rt.fileio import TMP_MARK
from veriloc_rt.studies.validate import MODELS

from .strict_json import assert_strict_json

ROOT = Path(__file__).resolve().parents[2]
CONFIG = str(ROOT / "configs" / "ci-tiny.json")
POINTS = 6
C = 299_792_458.0
#: Sionna RT's CPU variant computes in float32 (about 6e-8 relative per operation): a free-space
#: path comes out within 1e-5 dB of Friis (1.6e-6 dB measured on this scene); 0.01 dB is ample
FLOAT32_TOL_DB = 0.01


@pytest.fixture(scope="module")
def validate_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("validate")
    real, placed = os.replace, set()

    def spy(src, dst):   # every file placed by renaming a temporary file over it
        real(src, dst)
        placed.add(Path(dst).resolve())

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(os, "replace", spy)
        assert main(["validate", CONFIG, "--points", str(POINTS), "--out", str(out)]) == 0
    RENAMED.update(placed)
    return out


#: the files ``validate`` placed by a rename (os.replace)
RENAMED: set = set()


@pytest.mark.raytrace
def test_validate_writes_each_file_atomically(validate_out):
    for name in ("validation.json", "validation.md", "validation_links.csv",
                 "validation_pathloss.png", "scene/scene.xml", "scene/meshes/buildings.ply",
                 "scene/meshes/ground.ply"):
        assert (validate_out / name).resolve() in RENAMED, name
    assert not [p for p in validate_out.rglob("*") if TMP_MARK in p.name]


@pytest.mark.raytrace
def test_validate_files_bins_and_free_space_bound(validate_out):
    assert_strict_json(validate_out / "validation.json")
    for name in ("validation.json", "validation.md", "validation_links.csv",
                 "validation_pathloss.png"):
        assert (validate_out / name).stat().st_size > 0, name
    assert (validate_out / "validation_pathloss.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    data = json.loads((validate_out / "validation.json").read_text())
    s = data["summary"]
    assert s["links"] == 3 * POINTS and s["with_path"] + s["no_path"] == s["links"]
    assert data["bins"] and sum(b["links"] for b in data["bins"]) == s["links"]
    for b in data["bins"]:
        assert b["d_lo_m"] <= b["d_centre_m"] <= b["d_hi_m"]
        assert set(b["model_db"]) == set(MODELS) and set(b["offset_db"]) == set(MODELS)
        if b["links"] > b["no_path"]:
            t = b["traced_db"]
            assert t["p10"] <= t["p50"] <= t["p90"]
    # COST-231 WI is stated for 800-2000 MHz; the CI scene runs at 3.5 GHz: said, not hidden
    assert "f = 3.5 GHz > 2 GHz" in data["models"]["cost231_wi"]["outside_validity"]
    with open(validate_out / "validation_links.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 * POINTS
    fc = data["inputs"]["carrier_frequency_hz"]
    checked = 0
    for r in rows:
        if r["has_path"] != "1":
            assert r["pl_db"] == ""        # a link without a path has no loss, not infinity
            continue
        # Passive scene: each path is at most as strong as free space over the straight 3-D
        # distance (|reflection / diffraction coefficients| <= 1, longer unfolded paths), and the
        # loss sums n paths incoherently, so it beats free space by at most 10 lg n
        friis = 20 * math.log10(4 * math.pi * float(r["d_3d_m"]) * fc / C)
        bound = 10 * math.log10(int(r["num_paths"]))
        assert float(r["pl_db"]) >= friis - bound - FLOAT32_TOL_DB, r
        checked += 1
    assert checked == s["with_path"] > 0


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "veriloc_rt.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=ROOT)


@pytest.mark.parametrize("args, field", [
    (["--points", "0"], "--points"),
    (["missing.json"], "missing.json"),
    ([str(ROOT / "configs" / "external-mini.json")], "scene.source"),
])
def test_validate_bad_input_is_one_line_exit_2(tmp_path, args, field):
    r = _cli("validate", *args, "--out", tmp_path / "out")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {field}: ")
    assert "Traceback" not in r.stderr
