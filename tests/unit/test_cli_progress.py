"""The CLI's progress callback: one bar per stage, each closed at its total."""

import io

from veriloc_rt.cli import ProgressBar


def test_one_bar_per_stage_each_ending_at_its_total():
    out = io.StringIO()
    bar = ProgressBar(out)
    for done in (5, 275, 600):
        bar("ray tracing", done, 600)
    for done in (1, 150):           # a stage left before its total is closed by the next one
        bar("none", done, 300)
    for done in (10, 40):
        bar("fbs", done, 40)
    text = out.getvalue()
    assert "ray tracing" in text and "600/600" in text
    assert "150/300" in text and "40/40" in text
    assert bar.bar is None               # the last stage reached its total: closed
    # each bar is left on its own line (its last redraw after the carriage returns)
    lines = [ln.split("\r")[-1] for ln in text.split("\n") if ln.strip()]
    assert [ln.split()[0] for ln in lines] == ["ray", "none", "fbs"]
