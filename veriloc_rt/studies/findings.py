"""``docs/findings.md`` and the tables of ``docs/compare.md``, regenerated from runs of the
current code (``veriloc-rt findings``).

For each preset of :data:`PRESETS` (``configs/<name>.json``): :func:`~veriloc_rt.studies.
compare.run_compare` runs it on ray tracing and on its TR 38.901 stochastic twin (same
topology, trajectory, keys, noise and adversary draws); from both run folders each decision's
detection probability at :data:`TARGET_FALSE_ALARM` is read off its ROC (the vertex with the
highest detection among those whose false alarm on the benign fixes is at most the target:
:func:`~veriloc_rt.analysis.roc.detection_at_false_alarm`), per attack, with a 95 % interval.

Every generated table is preceded by a stamp: a visible line (package version, config and its
hash, points, seed, the model versions the table depends on) and the same in an HTML comment
``<!-- veriloc-rt findings stamp: {json} -->`` that :func:`parse_stamps` reads back;
``tests/unit/test_findings_stamps.py`` fails when a doc's stamp is older than the current
model versions (:func:`model_versions`) or its config changed since.

``docs/compare.md`` keeps its prose; its tables live between ``<!-- BEGIN veriloc-rt findings:
compare -->`` and ``<!-- END veriloc-rt findings: compare -->``, which the generator replaces.
"""

from __future__ import annotations

import hashlib
import os
import json
import logging
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__
from ..config import Config, config_to_dict, load_config, with_overrides
from ..detectors.outcomes import DETECTORS, TRP_DETECTORS
from ..errors import InputError
from ..fileio import atomic_write_text
from ..propagation import tr38901
from ..propagation.raytrace import CACHE_VERSION
from ..analysis.detection import FUSED, analyse_detection
from ..report.results import read_rows, results_path

log = logging.getLogger(__name__)

__all__ = ["PRESETS", "TARGET_FALSE_ALARM", "model_versions", "config_hash", "detection_table",
           "parse_stamps", "stale_stamps", "generate_findings", "preset_configs", "PresetFindings",
           "replace_block"]

#: the presets ``veriloc-rt findings`` runs, in the order docs/findings.md lists them: the
#: names of ``configs/<name>.json`` (a preset is added by adding its name here)
PRESETS = ("3gpp-uma", "3gpp-umi-street", "harsh-alley")
#: where the presets live, relative to the repository root
CONFIG_DIR = "configs"
#: the false-alarm rate the detection probabilities are read at (5 %)
TARGET_FALSE_ALARM = 0.05
#: the HTML comment that carries a table's stamp
STAMP_RE = re.compile(r"<!-- veriloc-rt findings stamp: (\{.*?\}) -->")
#: the markers of a generated block inside a hand-written page
BEGIN, END = "<!-- BEGIN veriloc-rt findings: {} -->", "<!-- END veriloc-rt findings: {} -->"
#: the name of docs/compare.md's generated block
COMPARE_BLOCK = "compare"


def model_versions(models=("raytrace", "uma", "umi")) -> dict:
    """The versions of the models a table of ``models`` depends on: the ray tracer's recipe
    (:data:`~veriloc_rt.propagation.raytrace.CACHE_VERSION`, bumped whenever what a trace
    returns changes: the solver settings, the UTD diffraction material, the cached layout)
    and each stochastic twin's TR 38.901 table version
    (:data:`~veriloc_rt.propagation.tr38901.TR38901_VERSIONS`)."""
    out: dict = {}
    for m in models:
        if m == "raytrace":
            out["raytrace_cache"] = CACHE_VERSION
        elif m in tr38901.TR38901_VERSIONS:
            out[f"tr38901_{m}"] = tr38901.TR38901_VERSIONS[m]
    return out


def config_hash(cfg: Config) -> str:
    """sha256 (first 16 hex digits) of the resolved config (every field, as ``veriloc-rt
    config show`` prints it), each file it names (a resolved absolute path: sites CSV, scene,
    trajectory) replaced by its content's sha256, so the hash does not depend on where the
    checkout is: two configs that run the same hash the same."""
    def located(v):
        if isinstance(v, dict):
            return {k: located(x) for k, x in v.items()}
        if isinstance(v, list):
            return [located(x) for x in v]
        if isinstance(v, str) and os.path.isabs(v) and os.path.isfile(v):
            return "sha256:" + hashlib.sha256(Path(v).read_bytes()).hexdigest()
        return v

    text = json.dumps(located(config_to_dict(cfg)), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _wilson(k: int, n: int) -> tuple[float, float] | None:
    """95 % Wilson score interval of a binomial proportion k / n (None for n = 0)."""
    if n <= 0:
        return None
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(0.95, method="wilson")
    return float(ci.low), float(ci.high)


def detection_table(run_dir: str | Path, target: float = TARGET_FALSE_ALARM) -> dict:
    """Per decision and attack of the finished run in ``run_dir``: ``{attack: {decision:
    {"pd", "false_alarm", "threshold", "n_attack", "ci95"}}}`` at false alarm <= ``target``
    (fractions), ``ci95`` the 95 % Wilson interval of ``pd`` over the attack points at that
    threshold (the threshold's own uncertainty, from the benign fixes, not included), or the
    interval metrics.json holds for the same quantity (``roc.attacks.<attack>.<decision>.
    pd_at_false_alarm_ci95``) when it holds one. Empty when the run has no ROC."""
    from ..config import config_from_dict
    from ..analysis.roc import detection_at_false_alarm

    run_dir = Path(run_dir)
    info = json.loads((run_dir / "run.json").read_text())
    cfg = config_from_dict(info["config"])
    metrics = json.loads((run_dir / "metrics.json").read_text())
    rows = {s: read_rows(results_path(run_dir, s)) for s in cfg.run.scenarios
            if results_path(run_dir, s).exists()}
    analysis = analyse_detection(rows, cfg)
    if analysis is None:
        return {}
    held = (metrics.get("roc") or {}).get("attacks") or {}
    out: dict = {}
    for (name, attack), curve in analysis.curves.items():
        thr, fa, pd = detection_at_false_alarm(curve, target)
        n = sum(1 for r in rows[attack] if r.attack)
        if name == "NPFusion":      # evaluated on the test third of the indices only
            n = 0
        ci = ((held.get(attack) or {}).get(name) or {}).get("pd_at_false_alarm_ci95")
        if not (isinstance(ci, list) and len(ci) == 2):
            ci = _wilson(round(pd * n), n)
        out.setdefault(attack, {})[name] = {"pd": pd, "false_alarm": fa, "threshold": thr,
                                            "n_attack": n, "ci95": ci}
    return out


def stamp(cfg: Config, config_name: str, models, points: int) -> tuple[str, dict]:
    """The stamp lines (visible sentence and HTML comment) of a table generated from ``cfg``
    (``config_name`` as given, ``points`` trajectory points) with ``models``; and its dict."""
    st = {"package": __version__, "config": config_name, "config_sha256": config_hash(cfg),
          "points": int(points), "seed": int(cfg.seed), "models": model_versions(models)}
    vers = "; ".join(f"{k} {v}" for k, v in st["models"].items())
    text = (f"*Generated by `veriloc-rt findings` with veriloc-rt {st['package']} from "
            f"`{config_name}` (config sha256 {st['config_sha256']}), {points} points, seed "
            f"{st['seed']}; models: {vers}.*\n"
            f"<!-- veriloc-rt findings stamp: {json.dumps(st, sort_keys=True)} -->")
    return text, st


def parse_stamps(text: str) -> list[dict]:
    """The stamps (dicts) of the generated tables in a page's ``text``, in page order."""
    return [json.loads(m.group(1)) for m in STAMP_RE.finditer(text)]


def stale_stamps(text: str, root: str | Path | None = None) -> list[str]:
    """Why the stamped tables of ``text`` no longer describe the current code: a model version
    other than :func:`model_versions`' (or a model it no longer has), or, with ``root`` (the
    repository), a preset whose config file (resolved at the stamped points and seed) hashes
    otherwise. Empty when every stamp is current."""
    current = model_versions()
    why = []
    for st in parse_stamps(text):
        for k, v in st.get("models", {}).items():
            if current.get(k) != v:
                why.append(f"{st.get('config')}: {k} {v!r}, the code has {current.get(k)!r}")
        if root is not None and st.get("config", "").startswith(CONFIG_DIR + "/"):
            path = Path(root) / st["config"]
            if not path.exists():
                why.append(f"{st['config']}: no such preset any more")
                continue
            cfg = with_overrides(load_config(path), points=st["points"], seed=st["seed"])
            if config_hash(cfg) != st["config_sha256"]:
                why.append(f"{st['config']}: the config changed since (sha256 "
                           f"{config_hash(cfg)}, stamped {st['config_sha256']})")
    return why


def replace_block(text: str, name: str, body: str) -> str:
    """``text`` with the generated block ``name`` (between its :data:`BEGIN` and :data:`END`
    markers) replaced by ``body``.

    :raises InputError: the page has no such block
    """
    b, e = BEGIN.format(name), END.format(name)
    i, j = text.find(b), text.find(e)
    if i < 0 or j < i:
        raise InputError("docs", f"no generated block {name!r} (markers {b} ... {e})")
    return text[:i] + b + "\n" + body.rstrip("\n") + "\n" + text[j:]


@dataclass
class PresetFindings:
    """What one preset's runs gave: its config, name as given, the models run (ray tracing
    first), each model's :func:`detection_table` and run folder, the comparison's markdown
    (None without a twin), the uninformative decisions per model and the wall time, s."""

    name: str
    config_name: str
    cfg: Config
    models: list
    detection: dict
    folders: dict
    uninformative: dict
    compare_md: str | None
    wall_s: float
    twin: dict = field(default_factory=dict)


def run_preset(name: str, config_name: str, cfg: Config, out: Path, workers: int = 1,
               models: tuple | None = None, progress=None) -> PresetFindings:
    """Run one preset into ``out/<name>``: ray tracing and its twin (``models`` None, through
    :func:`~veriloc_rt.studies.compare.run_compare`), or only the given ``models`` (e.g.
    ``("uma",)``, each a plain run; no comparison)."""
    import dataclasses

    t = time.perf_counter()
    folder = out / name
    compare_md, twin = None, {}
    if models is None:
        from .compare import markdown, run_compare

        res = run_compare(cfg, folder, progress=progress, workers=workers)
        models = list(res.models)
        compare_md, twin = markdown(res), dict(res.twin)
    else:
        from ..sim.engine import run

        for m in models:
            c = cfg.replace(propagation=dataclasses.replace(cfg.propagation, model=m))
            run(c, folder / m, progress=progress, workers=workers, force=True)
    folders = {m: folder / m for m in models}
    detection = {m: detection_table(f) for m, f in folders.items()}
    uninf = {}
    for m, f in folders.items():
        roc = json.loads((f / "metrics.json").read_text()).get("roc") or {}
        uninf[m] = list(roc.get("uninformative") or ())
    return PresetFindings(name, config_name, cfg, list(models), detection, folders, uninf,
                          compare_md, time.perf_counter() - t, twin)


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.1f}"


def _cell(e: dict | None) -> str:
    if e is None:
        return "n/a"
    ci = e.get("ci95")
    return _pct(e["pd"]) + (f" [{_pct(ci[0])}, {_pct(ci[1])}]" if ci else "")


_MODEL_NAMES = {"raytrace": "ray tracing", "uma": "TR 38.901 UMa",
                "umi": "TR 38.901 UMi-Street Canyon"}


def findings_section(p: PresetFindings) -> str:
    """The preset's section of docs/findings.md: its stamp and the Pd table."""
    text, _ = stamp(p.cfg, p.config_name, p.models, p.cfg.trajectory.num_points)
    attacks = list(dict.fromkeys(a for m in p.models for a in p.detection[m]))
    names = [n for n in (*DETECTORS, *TRP_DETECTORS, *FUSED)
             if any(n in p.detection[m].get(a, {}) for m in p.models for a in attacks)]
    L = [f"## {p.name}", "", text, ""]
    if p.twin:
        L += [f"Stochastic twin: {_MODEL_NAMES.get(p.models[-1], p.models[-1])} "
              f"({p.twin.get('rule')}).", ""]
    if not attacks:
        return "\n".join(L + ["No ROC: the run has no attack points or no benign fixes.", ""])
    head = "| decision | " + " | ".join(f"{a}: {_MODEL_NAMES.get(m, m)}" for a in attacks
                                       for m in p.models) + " |"
    L += [f"Detection probability, % [95 % interval], at false alarm <= "
          f"{100 * TARGET_FALSE_ALARM:g} % on the benign fixes, per attack:", "",
          head, "| --- |" + " --- |" * (len(attacks) * len(p.models))]
    for n in names:
        cells = [_cell(p.detection[m].get(a, {}).get(n)) for a in attacks for m in p.models]
        L.append(f"| {n} | " + " | ".join(cells) + " |")
    flagged = {m: u for m, u in p.uninformative.items() if u}
    L += ["", "Intervals: 95 %, the run's percentile bootstrap over its points (metrics.json "
          "`pd_at_false_alarm_ci95`: benign and attack points resampled, so the threshold's "
          "own uncertainty is in it); where the run holds none, the Wilson score interval over "
          "the attack points at the chosen threshold. "
          "NP fusion is evaluated on the test third of the indices and given without one. "
          "A detector's ROC does not depend on its configured threshold, so an uninformative "
          "one (too few benign fixes accepted at that threshold) still has a Pd here."]
    if flagged:
        L += ["Uninformative at the configured thresholds: " + "; ".join(
            f"{_MODEL_NAMES.get(m, m)}: {', '.join(u)}" for m, u in flagged.items()) + "."]
    L += [f"Wall time of this preset's runs: {p.wall_s:.0f} s.", ""]
    return "\n".join(L)


def compare_section(p: PresetFindings) -> str:
    """The preset's part of docs/compare.md's generated block: its stamp and the
    comparison's tables (headings two levels down, under the preset's)."""
    text, _ = stamp(p.cfg, p.config_name, p.models, p.cfg.trajectory.num_points)
    body = re.sub(r"^(#+) ", lambda m: "##" + m.group(1) + " ", p.compare_md or "", flags=re.M)
    return "\n".join([f"### {p.name}", "", text, "", body.rstrip("\n"), ""])


FINDINGS_HEAD = """# Findings, regenerated from the current code

Generated by `veriloc-rt findings` (do not edit by hand: rerun it). For each preset in
`configs/`, the same topology, trajectory, keys and attacks run on ray tracing and on its
TR 38.901 stochastic twin (`veriloc-rt compare`, [compare](compare.md)); for each decision and
attack, the probability of detecting the attack at a false-alarm rate of at most 5 % on the
benign fixes, read off its ROC (`roc.csv` of each run). Each table's stamp names the package
version, the config and its hash, and the model versions it was computed with;
`tests/unit/test_findings_stamps.py` fails when a stamp is older than the code's models.
"""


def preset_configs(root: str | Path, presets: tuple | None = None,
                   configs: dict | None = None) -> dict:
    """``{name: config path}`` of the runs: ``configs`` as given, or the ``presets`` (default
    every one of :data:`PRESETS`) under ``root/configs/``.

    :raises InputError: an unknown preset or a missing config file
    """
    if configs is None:
        names = tuple(presets) if presets else PRESETS
        unknown = [n for n in names if n not in PRESETS]
        if unknown:
            raise InputError("--preset", f"unknown preset(s) {', '.join(unknown)}; the presets "
                             f"are {', '.join(PRESETS)}")
        configs = {n: Path(root) / CONFIG_DIR / f"{n}.json" for n in names}
    for name, path in configs.items():
        if not Path(path).is_file():
            raise InputError(str(path), f"preset {name!r}: no such config file")
    return dict(configs)


def generate_findings(out: str | Path, docs_dir: str | Path, root: str | Path,
                      presets: tuple | None = None, configs: dict | None = None,
                      points: int | None = None, seed: int | None = None, workers: int = 1,
                      models: tuple | None = None, progress=None) -> list[PresetFindings]:
    """Run the presets and write ``docs_dir/findings.md`` and the tables of
    ``docs_dir/compare.md`` (when every preset ran with its twin and the page has the
    block).

    :param presets: names in :data:`PRESETS` (default all), read from
        ``root/configs/<name>.json``
    :param configs: ``{name: path}`` instead (e.g. a tiny config for a test)
    :param models: None: ray tracing and its twin; else only these models (no comparison)
    :raises InputError: an unknown preset, a missing config file, or a compare.md without
        its block
    """
    root, out, docs = Path(root), Path(out), Path(docs_dir)
    configs = preset_configs(root, presets, configs)
    done = []
    for name, path in configs.items():
        path = Path(path)
        cfg = load_config(path)
        if points is not None or seed is not None:
            cfg = with_overrides(cfg, points=points, seed=seed)
        try:
            shown = path.resolve().relative_to(root.resolve()).as_posix()
        except ValueError:
            shown = path.name
        log.info("findings: preset %s (%s), %d points", name, shown, cfg.trajectory.num_points)
        done.append(run_preset(name, shown, cfg, out, workers=workers, models=models,
                               progress=progress))
    page = FINDINGS_HEAD + "\n" + "\n".join(findings_section(p) for p in done)
    atomic_write_text(docs / "findings.md", page)
    if all(p.compare_md for p in done):
        cmp_path = docs / "compare.md"
        text = cmp_path.read_text() if cmp_path.exists() else ""
        body = "\n".join(compare_section(p) for p in done)
        atomic_write_text(cmp_path, replace_block(text, COMPARE_BLOCK, body))
    return done
