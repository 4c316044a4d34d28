"""The generated doc tables (docs/findings.md, docs/compare.md's block) carry a stamp no older
than the code's model versions; the generator (``veriloc-rt findings``) writes stamped tables
whose detection probabilities are the ROC's at 5 % false alarm."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from veriloc_rt import __version__
from veriloc_rt.cli import main
from veriloc_rt.config import load_config
from veriloc_rt.propagation.raytrace import CACHE_VERSION
from veriloc_rt.propagation.tr38901 import TR38901_VERSIONS
from veriloc_rt.studies.findings import (BEGIN, COMPARE_BLOCK, END, PRESETS, config_hash,
                                         parse_stamps, stale_stamps)

ROOT = Path(__file__).resolve().parents[2]
#: the pages whose tables are generated
PAGES = ("docs/findings.md", "docs/compare.md")
#: the stamp's comment, read here with its own pattern (not the module's)
STAMP = re.compile(r"<!-- veriloc-rt findings stamp: (\{.*?\}) -->")
#: the versions a table may be stamped with: the constants of the code, read directly
CURRENT = {"raytrace_cache": CACHE_VERSION,
           **{f"tr38901_{m}": v for m, v in TR38901_VERSIONS.items()}}


def _stamps(text: str) -> list[dict]:
    return [json.loads(m.group(1)) for m in STAMP.finditer(text)]


def _tables_outside_stamped_sections(text: str) -> list[str]:
    """The Markdown table header lines of ``text`` outside a stamped section: a stamp covers
    the rest of the section it is in, sub-sections included, up to the next heading of the
    same or a higher level."""
    bad, covered, level = [], None, 0
    lines = text.splitlines()
    for i, line in enumerate(lines):
        h = re.match(r"^(#+) ", line)
        if h:
            level = len(h.group(1))
            if covered is not None and level <= covered:
                covered = None
        if STAMP.search(line):
            covered = level
        if (line.startswith("|") and i + 1 < len(lines)
                and re.match(r"^\|(:?-+:?\|)+$", lines[i + 1].replace(" ", ""))
                and covered is None):
            bad.append(line)
    return bad


@pytest.mark.parametrize("page", PAGES)
def test_every_doc_table_is_stamped_with_the_current_models(page):
    text = (ROOT / page).read_text()
    stamps = _stamps(text)
    assert stamps, f"{page} has no generated table: run `veriloc-rt findings` (docs/findings.md)"
    for st in stamps:
        for key, version in st["models"].items():
            assert key in CURRENT, f"{page}: {st['config']}: model {key} no longer exists"
            assert version == CURRENT[key], (
                f"{page}: {st['config']} was generated with {key} {version!r}; the code has "
                f"{CURRENT[key]!r}: rerun `veriloc-rt findings`")
        assert st["package"] and st["config_sha256"] and st["points"] >= 2
        path = ROOT / st["config"]
        if path.is_file():    # the config unchanged since: the same hash at the same points
            from veriloc_rt.config import with_overrides

            cfg = with_overrides(load_config(path), points=st["points"], seed=st["seed"])
            assert config_hash(cfg) == st["config_sha256"], f"{page}: {st['config']} changed"
    assert _tables_outside_stamped_sections(text) == [], f"{page}: a table without a stamp"
    if page == "docs/compare.md":
        assert BEGIN.format(COMPARE_BLOCK) in text and END.format(COMPARE_BLOCK) in text


def test_an_older_stamp_is_reported_stale():
    fresh = {"package": __version__, "config": "x.json", "config_sha256": "0" * 16, "points": 4,
             "seed": 1, "models": dict(CURRENT)}
    older = json.loads(json.dumps(fresh))
    older["models"]["raytrace_cache"] = CACHE_VERSION - 1
    umi = json.loads(json.dumps(fresh))
    umi["models"]["tr38901_umi"] = "V17.0.0"
    page = "\n".join(f"<!-- veriloc-rt findings stamp: {json.dumps(s)} -->"
                     for s in (fresh, older, umi))
    assert parse_stamps(page) == [fresh, older, umi]
    why = stale_stamps(page)
    assert len(why) == 2 and "raytrace_cache" in why[0] and "tr38901_umi" in why[1]
    assert stale_stamps(page.splitlines()[0]) == []
    # the page checks find an unstamped table
    assert _tables_outside_stamped_sections("## a\n\n| x |\n| --- |\n| 1 |\n") == ["| x |"]
    stamped = "## a\n" + page.splitlines()[0] + "\n#### b\n| x |\n| --- |\n## c\n| y |\n| --- |\n"
    assert _tables_outside_stamped_sections(stamped) == ["| y |"]


def test_the_presets_are_one_list():
    assert len(PRESETS) == len(set(PRESETS)) >= 3


#: the generator's try on a tiny UMa config: 10 points, attacks fbs and meaconing, no tracing
TINY = {"propagation": {"model": "uma"}, "trajectory": {"num_points": 10, "adversary_lag_points": 2},
        "run": {"scenarios": ["none", "fbs", "meaconing"], "evaluate_encrypted": False,
                "digsig": "shared"}}
#: the table prints percent with one decimal: half a unit of its last digit
PRINTED = 0.05 + 1e-9


def _wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson score interval, z = 1.959964 (the 97.5 % normal quantile), written out."""
    z, p = 1.959963984540054, k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return centre - half, centre + half


@pytest.mark.heavy
def test_generator_on_a_tiny_uma_config(tmp_path):
    cfg = tmp_path / "tiny-uma.json"
    cfg.write_text(json.dumps(TINY))
    docs = tmp_path / "docs"
    docs.mkdir()
    compare_md = docs / "compare.md"
    compare_md.write_text("# c\n\n" + BEGIN.format(COMPARE_BLOCK) + "\n"
                          + END.format(COMPARE_BLOCK) + "\n")
    before = compare_md.read_text()
    assert main(["findings", "--config", str(cfg), "--models", "uma", "--out",
                 str(tmp_path / "runs"), "--docs", str(docs), "--root", str(tmp_path),
                 "--workers", "1", "-q"]) == 0
    text = (docs / "findings.md").read_text()
    assert compare_md.read_text() == before   # no twin, no comparison: untouched
    [st] = _stamps(text)
    assert st["package"] == __version__ and st["points"] == TINY["trajectory"]["num_points"]
    assert st["models"] == {"tr38901_uma": TR38901_VERSIONS["uma"]}
    assert st["config"] == "tiny-uma.json"
    assert stale_stamps(text, tmp_path) == []
    assert _tables_outside_stamped_sections(text) == []
    # the independent derivation: from the run's roc.csv, the best detection among the
    # vertices with false alarm (1 - benign acceptance) <= 5 %; the interval over its attack
    # points (the attack window of each attack's results CSV)
    run = tmp_path / "runs" / "tiny-uma" / "uma"
    metrics = json.loads((run / "metrics.json").read_text())
    best: dict = {}
    import csv

    with open(run / "roc.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            if 1.0 - float(r["benign_accept"]) <= 0.05 + 1e-12:
                key = (r["detector"], r["attack"])
                best[key] = max(best.get(key, 0.0), float(r["attack_reject"]))
    table = {}
    lines = text.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("| decision |"))
    attacks = [c.split(":")[0].strip() for c in lines[head].strip("|").split("|")[1:]]
    for ln in lines[head + 2:]:
        if not ln.startswith("|"):
            break
        cells = [c.strip() for c in ln.strip("|").split("|")]
        for a, c in zip(attacks, cells[1:]):
            table[(cells[0], a)] = c
    assert set(table) == set(best)
    for (det, attack), pd in best.items():
        with open(run / f"{attack}_results.csv", newline="") as fh:
            n = sum(1 for r in csv.DictReader(fh) if float(r["attack"]) == 1.0)
        m = re.match(r"([\d.]+) \[([\d.]+), ([\d.]+)\]", table[(det, attack)])
        assert m, table[(det, attack)]
        assert abs(float(m.group(1)) - 100 * pd) <= PRINTED
        # the interval: the run's own bootstrap of the same quantity when metrics.json holds
        # it (tested against independent derivations in tests/unit/analysis/test_intervals.py),
        # else the Wilson interval over the attack points
        held = ((metrics["roc"].get("attacks") or {}).get(attack) or {}).get(det) or {}
        ci = held.get("pd_at_false_alarm_ci95")
        if ci:
            assert abs(held["pd_at_false_alarm"] - pd) <= 1e-12   # the same 5 % operating point
        lo, hi = ci if ci else _wilson(round(pd * n), n)
        assert abs(float(m.group(2)) - 100 * lo) <= PRINTED
        assert abs(float(m.group(3)) - 100 * hi) <= PRINTED


def test_unknown_preset_and_missing_config_are_one_line(tmp_path, capsys):
    assert main(["findings", "--preset", "nope", "--out", str(tmp_path / "o"), "--root",
                 str(ROOT)]) == 2
    assert capsys.readouterr().err.strip().startswith("error: --preset: unknown preset(s) nope")
    assert main(["findings", "--config", str(tmp_path / "none.json"), "--out",
                 str(tmp_path / "o"), "--root", str(ROOT)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"error: {tmp_path / 'none.json'}: preset 'none': no such config file"


@pytest.mark.heavy
@pytest.mark.raytrace
def test_generator_with_the_twin_fills_compare_md(tmp_path):
    """The whole path: ray tracing and its twin (``compare``) on the CI canyon at 6 points;
    findings.md and compare.md's block both stamped with the tracer's and the twin's versions,
    the hand-written text around the block kept."""
    docs = tmp_path / "docs"
    docs.mkdir()
    head, tail = "# c\n\nprose before\n\n", "\nprose after\n"
    (docs / "compare.md").write_text(head + BEGIN.format(COMPARE_BLOCK) + "\nold table\n"
                                     + END.format(COMPARE_BLOCK) + tail)
    assert main(["findings", "--config", str(ROOT / "configs" / "ci-tiny.json"), "--points", "6",
                 "--out", str(tmp_path / "runs"), "--docs", str(docs), "--root", str(ROOT),
                 "--workers", "1", "-q"]) == 0
    cmp_text = (docs / "compare.md").read_text()
    assert cmp_text.startswith(head) and cmp_text.endswith(END.format(COMPARE_BLOCK) + tail)
    assert "old table" not in cmp_text
    for text in (cmp_text, (docs / "findings.md").read_text()):
        [st] = _stamps(text)
        assert st["config"] == "configs/ci-tiny.json" and st["points"] == 6
        assert st["models"]["raytrace_cache"] == CACHE_VERSION
        twin = [k for k in st["models"] if k.startswith("tr38901_")]
        assert len(twin) == 1 and st["models"][twin[0]] == CURRENT[twin[0]]
        assert stale_stamps(text, ROOT) == []
        assert _tables_outside_stamped_sections(text) == []
