"""The user documentation: README size, generated pages current, every link resolving inside
the repository, and the README's commands matching what CI runs."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.config import Config, config_to_dict
from veriloc_rt.report.results import ResultsWriter
from veriloc_rt.detectors.outcomes import DETECTORS, PointRow

ROOT = Path(__file__).resolve().parents[2]

#: the README is for users: what it is, how to start, where to read on (issue #18: <= 150 lines;
#: measurement history belongs in docs/)
README_MAX_LINES = 150
#: text that points outside the repository (the shared reference folder of the development
#: machine, absolute paths of it); a clone has neither
OUTSIDE_MARKERS = ("../shared", "/work/")


def _load_gen_docs():
    spec = importlib.util.spec_from_file_location("gen_docs", ROOT / "scripts" / "gen_docs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


gen_docs = _load_gen_docs()


def doc_files(root: Path = ROOT) -> list[Path]:
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def slugs(markdown: str) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation other than '-' and '_' dropped,
    spaces to '-', repeated headings numbered -1, -2, ..."""
    out: set[str] = set()
    for line in strip_fences(markdown).splitlines():
        m = re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        s = re.sub(r"[^\w\- ]", "", m.group(1).lower()).replace(" ", "-")
        base, n = s, 1
        while s in out:
            s, n = f"{base}-{n}", n + 1
        out.add(s)
    return out


def strip_fences(markdown: str) -> str:
    """The text without fenced code blocks."""
    return re.sub(r"^```.*?^```", "", markdown, flags=re.S | re.M)


def strip_code(markdown: str) -> str:
    """The text without fenced code blocks and inline code spans (no links live there)."""
    return re.sub(r"`[^`\n]*`", "", strip_fences(markdown))


def link_problems(path: Path, text: str, root: Path = ROOT) -> list[str]:
    """Every relative link of a markdown file that leaves ``root``, names a missing file or a
    missing heading; and any mention of a place outside the repository."""
    problems = [f"{path.name}: mentions {m!r} (outside the repository)"
                for m in OUTSIDE_MARKERS if m in text]
    for target in re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", strip_code(text)):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto:
            continue
        file_part, _, anchor = target.partition("#")
        dest = (path.parent / file_part).resolve() if file_part else path.resolve()
        if not dest.is_relative_to(root.resolve()):
            problems.append(f"{path.name}: link {target!r} leaves the repository")
        elif not dest.exists():
            problems.append(f"{path.name}: link {target!r}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in slugs(dest.read_text()):
            problems.append(f"{path.name}: link {target!r}: no such heading in {dest.name}")
    return problems


def test_readme_is_short():
    n = len((ROOT / "README.md").read_text().splitlines())
    assert n <= README_MAX_LINES, (f"README.md has {n} lines, at most {README_MAX_LINES}: move "
                                   "details to docs/")


@pytest.mark.parametrize("path", doc_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_links_resolve_inside_the_repository(path):
    assert link_problems(path, path.read_text()) == []


def test_link_check_finds_broken_and_outside_links(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("# A page\n\n## Known limits\n")
    page = tmp_path / "docs" / "b.md"
    text = ("[ok](a.md#known-limits) [web](https://example.org) `[code](nowhere.md)`\n"
            "[gone](missing.md) [anchor](a.md#nope) [out](../../x.md) see ../shared/notes\n")
    found = link_problems(page, text, root=tmp_path)
    assert len(found) == 4, found
    assert any("'missing.md': no such file" in p for p in found)
    assert any("'a.md#nope': no such heading" in p for p in found)
    assert any("'../../x.md' leaves the repository" in p for p in found)
    assert any("'../shared'" in p for p in found)


def test_readme_states_the_command_ci_runs():
    # .ci/run executes "the README's test command": its last line must be in the README verbatim
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert ci == ("bash scripts/setup.sh && .venv/bin/lint-imports && .venv/bin/python -m pytest "
                  "-q -n 2 --dist loadscope && .venv/bin/python -m pytest -q -n 2 --dist loadscope "
                  "-m heavy")
    readme = (ROOT / "README.md").read_text()
    assert ci in readme
    assert "bash scripts/setup.sh && .venv/bin/veriloc-rt run --out results" in readme


@pytest.mark.parametrize("page", sorted(gen_docs.PAGES))
def test_generated_page_is_current(page):
    committed = (ROOT / page).read_text() if (ROOT / page).exists() else ""
    assert committed == gen_docs.PAGES[page](), (
        f"{page} is stale: run `.venv/bin/python scripts/gen_docs.py` and commit the result")


def _table_rows(markdown: str, first_col: str = r"`([^`]+)`") -> list[tuple[str, list[str]]]:
    rows = []
    for line in markdown.splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        if cells and (m := re.fullmatch(first_col, cells[0])):
            rows.append((m.group(1), cells))
    return rows


def test_configuration_page_has_every_field_with_its_default():
    # the leaves of the resolved default config, walked here independently of the schema
    def leaves(d, prefix=""):
        for k, v in d.items():
            yield from (leaves(v, f"{prefix}{k}.") if isinstance(v, dict) else
                        [(f"{prefix}{k}", v)])

    want = dict(leaves(config_to_dict(Config())))
    rows = {name: cells for name, cells in _table_rows(gen_docs.configuration_md())}
    assert sorted(rows) == sorted(want)
    for name, value in want.items():
        assert rows[name][2] == f"`{json.dumps(value)}`".replace("|", "\\|"), name


def test_outputs_page_lists_the_columns_a_run_writes(tmp_path):
    # the header of a CSV the run's own writer produces, in order
    row = PointRow(index=0, time_s=0.0, attack=False, verdicts=dict.fromkeys(DETECTORS, True),
                   true_xy=np.zeros(2), est_xy=np.ones(2), error_m=1.0, outcome="success")
    with ResultsWriter(tmp_path / "none_results.csv") as w:
        w.write(row)
    header = (tmp_path / "none_results.csv").read_text().splitlines()[0].split(",")
    with ResultsWriter(tmp_path / "fbs_results.csv", trps=True) as w:
        w.write(row)
    header_trps = (tmp_path / "fbs_results.csv").read_text().splitlines()[0].split(",")
    links = (tmp_path / "fbs_links.csv").read_text().splitlines()[0].split(",")
    page = gen_docs.outputs_md()
    section = page.split("### `<scenario>_results.csv`")[1].split("###")[0]
    plain, extra = section.split("appends:")
    documented = [cells[1].strip("`") for _, cells in _table_rows(plain, r"(\d+)")]
    assert documented == header
    documented += [cells[1].strip("`") for _, cells in _table_rows(extra, r"(\d+)")]
    assert documented == header_trps
    section = page.split("### `<scenario>_links.csv`")[1].split("###")[0]
    assert [cells[1].strip("`") for _, cells in _table_rows(section, r"(\d+)")] == links


def test_an_undocumented_column_stops_the_generator(monkeypatch):
    docs = dict(gen_docs.RESULTS_DOC)
    del docs["x_true"]
    monkeypatch.setattr(gen_docs, "RESULTS_DOC", docs)
    with pytest.raises(gen_docs.MissingDescription, match="results CSV column 'x_true'"):
        gen_docs.outputs_md()


#: the README's example prints the path loss with one decimal
PRINT_ROUNDING_DB = 0.05


def _uma_nlos_db(d_2d_m: float, h_bs_m: float, h_ut_m: float, fc_ghz: float) -> float:
    """TR 38.901 Table 7.4.1-1 UMa NLOS, max(PL_LOS, PL'_NLOS), written out here; the LoS
    break point d'_BP = 4 h'_BS h'_UT f_c / c with h' = h - 1 m (h_E = 1 m)."""
    d3 = math.hypot(d_2d_m, h_bs_m - h_ut_m)
    d_bp = 4 * (h_bs_m - 1) * (h_ut_m - 1) * fc_ghz * 1e9 / 299_792_458.0
    assert 10 <= d_2d_m <= d_bp  # PL1 of the LoS formula applies
    pl_los = 28.0 + 22 * math.log10(d3) + 20 * math.log10(fc_ghz)
    pl_nlos = 13.54 + 39.08 * math.log10(d3) + 20 * math.log10(fc_ghz) - 0.6 * (h_ut_m - 1.5)
    return max(pl_los, pl_nlos)


@pytest.mark.slow
def test_the_python_example_runs(tmp_path):
    # the only python block of docs/running.md ("From Python", linked from the README), run as a
    # user would: from a folder holding configs/
    block = re.search(r"^```python\n(.*?)^```", (ROOT / "docs" / "running.md").read_text(), re.S | re.M)
    (tmp_path / "tour.py").write_text(block.group(1))
    (tmp_path / "configs").symlink_to(ROOT / "configs")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "tour.py"], cwd=tmp_path, env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert [ln.split()[0] for ln in lines[:-1]] == ["none", "fbs", "meaconing", "jamming"]
    printed = float(re.fullmatch(r"UMa NLOS at 300 m: ([\d.]+) dB", lines[-1]).group(1))
    assert abs(printed - _uma_nlos_db(300.0, 25.0, 1.5, 3.5)) <= PRINT_ROUNDING_DB
    for name in ("metrics.json", "run.json", "none_results.csv"):
        assert (tmp_path / "tour" / "py" / name).stat().st_size > 0
