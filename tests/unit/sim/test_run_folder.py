"""The run folder: its lock, and which folders a new run may write into."""

import json
import os
import platform

import pytest

from veriloc_rt.config import Config
from veriloc_rt.errors import InputError
from veriloc_rt.sim.run_folder import LOCK_FILE, OWNER_FILE, check_fresh, locked, write_run_json


def test_a_locked_folder_refuses_a_second_holder_until_released(tmp_path):
    out = tmp_path / "run"
    with locked(out):
        assert (out / LOCK_FILE).exists()
        want = f"--out {out}: locked by another run (pid {os.getpid()} on {platform.node()})"
        with pytest.raises(InputError) as err:
            with locked(out):
                pass
        assert str(err.value) == want
    assert not (out / OWNER_FILE).exists()
    with locked(out):   # released: free again
        pass


def test_a_file_is_not_a_run_folder(tmp_path):
    f = tmp_path / "results"
    f.write_text("x")
    with pytest.raises(InputError, match=r"^--out .*results: not a folder$"):
        with locked(f):
            pass


def test_which_folders_a_new_run_may_write_into(tmp_path):
    cfg = Config()
    check_fresh(tmp_path / "missing", cfg)            # created by the run
    empty = tmp_path / "empty"
    with locked(empty):                              # the lock's own files do not count
        check_fresh(empty, cfg)
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="holds no veriloc-rt run"):
        check_fresh(other, cfg)
    check_fresh(other, cfg, force=True)
    same = tmp_path / "same"
    same.mkdir()
    write_run_json(same, cfg, "running", {})
    check_fresh(same, cfg)              # an unfinished run of this config, no point: started over
    (same / "none_results.csv").write_text("header\n0\n1\n")
    with pytest.raises(InputError, match=r"holds an unfinished run of this config with 2 "
                       r"finished points: add --resume to continue it, or --force to start it over$"):
        check_fresh(same, cfg)
    write_run_json(same, cfg, "complete", {})
    with pytest.raises(InputError, match=r"holds a complete run of this config: its results are "
                       r"kept; use a new --out, or --force to replace them$"):
        check_fresh(same, cfg)           # finished results are never replaced without --force
    check_fresh(same, cfg, force=True)
    with pytest.raises(InputError, match="holds a run of another config"):
        check_fresh(same, cfg.replace(seed=cfg.seed + 1))
    assert json.loads((same / "run.json").read_text())["status"] == "complete"


def test_a_run_stopped_while_building_its_scene_is_started_again(tmp_path):
    """A run stopped before run.json exists leaves scene/ only: --resume has nothing to resume
    (it says to run without it), so the run without it must be let in."""
    cfg = Config()
    out = tmp_path / "o"
    (out / "scene" / "meshes").mkdir(parents=True)
    (out / "scene" / "scene.xml").write_text("<scene/>")
    check_fresh(out, cfg)
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="holds no veriloc-rt run"):
        check_fresh(out, cfg)
