"""``--version``, ``-q/--no-progress`` and ``run(..., progress=True)`` (issue #40)."""

from __future__ import annotations

import io

import pytest

import veriloc_rt
from veriloc_rt.cli import ProgressBar, build_parser
from veriloc_rt.sim.progress import progress_callback


def test_version_flag(capsys):
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"veriloc-rt {veriloc_rt.__version__}"


@pytest.mark.parametrize("argv", [["-q", "run"], ["run", "-q"], ["--no-progress", "compare",
                                  "--out", "x"], ["bench", "--out", "x", "--no-progress"],
                                  ["validate", "--out", "x", "-q"]])
def test_quiet_before_or_after_the_command(argv):
    args = build_parser().parse_args(argv)
    assert args.no_progress is True


def test_progress_bars_by_default():
    args = build_parser().parse_args(["run"])
    assert args.no_progress is False


def test_progress_callback_forms():
    assert isinstance(progress_callback(True), ProgressBar)
    assert progress_callback(False) is None and progress_callback(None) is None
    f = lambda s, d, t: None  # noqa: E731
    assert progress_callback(f) is f
    with pytest.raises(TypeError, match="progress"):
        progress_callback(3)
    out = io.StringIO()
    bar = ProgressBar(out)
    bar("none", 1, 2)
    bar("none", 2, 2)
    assert "none" in out.getvalue() and "2/2" in out.getvalue()


def test_dir_lists_the_lazy_exports():
    names = dir(veriloc_rt)
    assert set(veriloc_rt.__all__) <= set(names)
    assert {"load_run", "run", "Config", "CIR"} <= set(names)
    assert veriloc_rt.load_run is veriloc_rt.report.tables.load_run  # noqa: the lazy export
