"""scripts/street_sites.py and scripts/roof_sites.py on bad input: one line
``error: <field or file>: <problem>``, exit code 2, no traceback, nothing written (the
project's contract, :mod:`veriloc_rt.errors`); and on good input a sites CSV that the run's
reader takes back (:func:`veriloc_rt.world.sites.load_sites`)."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.config.world import MIN_ANTENNA_HEIGHT_M
from veriloc_rt.world.sites import load_sites

from .test_bad_inputs import MINI, TINY, assert_one_line

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = {name: ROOT / "scripts" / f"{name}.py" for name in ("street_sites", "roof_sites")}
#: seconds a script may take on the mini canyon (start-up ~2 s on a loaded machine)
SCRIPT_LIMIT_S = 120.0


def _module(name: str):
    spec = importlib.util.spec_from_file_location(name, SCRIPTS[name])
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _call(name: str, *args) -> tuple[int, str, str]:
    """The script's ``main(ARGS)`` in this process -> (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = _module(name).main([str(a) for a in args])
        except SystemExit as exc:  # argparse
            code = exc.code
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def mini(tmp_path) -> Path:
    """A config of the shipped mini canyon (a mesh scene with roofs and one street)."""
    cfg = tmp_path / "mini.json"
    cfg.write_text(json.dumps({"scene": {"source": str(MINI / "scene.xml")},
                               "trajectory": {"source": str(MINI / "trajectory.csv")}}))
    return cfg


#: (script, arguments after CONFIG, the field the line names); {tmp}: the test's folder
BAD_FLAGS = [
    ("street_sites", ["--spacing", "0"], "--spacing"),
    ("street_sites", ["--spacing", "nan"], "--spacing"),
    ("street_sites", ["--spacing", "abc"], "--spacing"),
    ("street_sites", ["--height", str(MIN_ANTENNA_HEIGHT_M)], "--height"),
    ("street_sites", ["--along", "0"], "--along"),
    ("street_sites", ["--region", "-5"], "--region"),
    ("street_sites", ["--bogus", "1"], "--bogus"),
    # the mini canyon's one street has no junction: no site without --along
    ("street_sites", ["--spacing", "20"], "--spacing"),
    ("roof_sites", ["--isd", "0"], "--isd"),             # divided by it
    ("roof_sites", ["--isd", "inf"], "--isd"),
    ("roof_sites", ["--mast", "-1"], "--mast"),           # the antenna inside the roof
    ("roof_sites", ["--region", "0"], "--region"),
    ("roof_sites", ["--isd", "5000", "--region", "10"], "--isd"),   # one site: fewer than 3
]


@pytest.mark.parametrize("name, args, field", BAD_FLAGS)
def test_a_bad_flag_is_one_line_and_writes_nothing(tmp_path, mini, name, args, field):
    out = tmp_path / "sites.csv"
    code, stdout, err = _call(name, mini, "--out", out, *args)
    assert_one_line(code, err, field)
    assert stdout == "" and not out.exists()


@pytest.mark.parametrize("name", SCRIPTS)
def test_bad_files_are_one_line(tmp_path, mini, name):
    out = tmp_path / "sites.csv"
    missing = tmp_path / "nope.json"
    assert_one_line(*_call(name, missing, "--out", out)[::2], str(missing))
    assert_one_line(*_call(name, mini)[::2], "--out")                  # no --out
    # the canyon has no mesh to search
    canyon = tmp_path / "canyon.json"
    canyon.write_text(json.dumps(TINY))
    line = assert_one_line(*_call(name, canyon, "--out", out)[::2], "scene.source")
    assert "a mesh scene is needed" in line
    # a scene file that is not XML, and one that is not there
    bad = tmp_path / "bad.xml"
    bad.write_text("<scene><bogus")
    for scene in (bad, tmp_path / "none.xml"):
        cfg = tmp_path / "bad.json"
        cfg.write_text(json.dumps({"scene": {"source": str(scene)}}))
        assert_one_line(*_call(name, cfg, "--out", out)[::2], "scene.source")
    # an --out that cannot be written (its folder does not exist)
    flags = ["--spacing", "20", "--along", "10"] if name == "street_sites" else ["--isd", "20"]
    nodir = tmp_path / "missing" / "sites.csv"
    line = assert_one_line(*_call(name, mini, "--out", nodir, *flags)[::2], "--out")
    assert str(nodir) in line and "no such file" in line
    assert not out.exists()


@pytest.mark.parametrize("name, flags", [
    ("street_sites", ["--spacing", "20", "--along", "10", "--height", "6"]),
    ("roof_sites", ["--isd", "20", "--mast", "3"]),
])
def test_the_script_as_a_user_runs_it(tmp_path, mini, name, flags):
    """A separate interpreter: a bad config is one line (no traceback) with exit code 2; a good
    run writes a sites CSV whose every site the run's reader accepts, as many as it says."""
    def run(*args):
        return subprocess.run([sys.executable, str(SCRIPTS[name]), *map(str, args)],
                              capture_output=True, text=True, timeout=SCRIPT_LIMIT_S, cwd=tmp_path)

    missing = tmp_path / "nope.json"
    bad = run(missing, "--out", tmp_path / "x.csv")
    assert_one_line(bad.returncode, bad.stderr, str(missing))
    out = tmp_path / "sites.csv"
    good = run(mini, "--out", out, *flags)
    assert good.returncode == 0 and good.stderr == "", good.stderr
    pos, _ = load_sites(out)
    assert good.stdout.startswith(f"wrote {out}: {len(pos)} ")
    if name == "street_sites":   # every site at the height given, at least the spacing apart
        np.testing.assert_array_equal(pos[:, 2], 6.0)
        d = np.linalg.norm(pos[:, None, :2] - pos[None, :, :2], axis=-1)
        assert d[~np.eye(len(pos), dtype=bool)].min() >= 20.0 - 0.1   # 0.1 m: CSV rounding
