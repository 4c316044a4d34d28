"""Statistical equivalence of two versions of the chain: what users conclude from, compared.

A speed-up that changes the random numbers (not the distributions) cannot be checked by
comparing files. This runs a config (stochastic or ray traced: a seed's links are traced once,
into a cache both versions read) over many seeds under two *versions* and compares, version A
against version B, what a user reads off a run:

* **outcome shares** per scenario (success / large error / service failure over the evaluated
  points, standard and encrypted PRS): each share with its Wilson 95 % interval, the two
  versions by the two-sided two-proportion z-test (pooled variance);
* **position error CDFs** per scenario (points with a fix): the two-sample Kolmogorov-Smirnov
  test and the Anderson-Darling k-sample test (its p-value is floored at 0.001 and capped at
  0.25 by SciPy);
* **detectors**: each detector's reject share per scenario (two-proportion test), its decision
  statistic's distribution (KS on the finite values) and the share of non-finite statistics.
  In an attack scenario the points of one run are not independent samples: ABSA's and the
  handshake's reference is the last benign fix before the attack window, one noisy value per
  run that moves every statistic of the window together (measured: the FBS ABSA statistic of
  20 window points of one run spread 0.003 deg around a value that another noise draw moved
  by 0.04 deg). There the unit is the run: the per-seed reject shares and the per-seed
  medians of the statistic are compared (two-sample KS, exact for few seeds). So are the
  tracker's in every scenario: its state runs from point to point, one lost track rejects a
  stretch of points (measured: 10 of 80 benign points of one version rejected, 0 of the other's,
  from one lost track; pooled, the two-proportion test took that burst for a difference);
* **ToA error per SNR bin** (the benign scenario's links, 5 dB bins of the per-RE SNR): the
  share of TRPs heard (two-proportion test) and the ToA error's distribution (KS).

Every p-value enters one Holm-Bonferroni family at ``--alpha`` (0.05): the versions are
reported *different* when any test rejects at its Holm level, else *not distinguished*, with
the power the sample had to see a 1-point shift in an outcome share (written out in the report:
the normal approximation of the two-sided two-proportion z-test, at the observed share).

A **version** is a set of environment variables (read when the chains are built; e.g.
``VERILOC_RT_REFERENCE=all``, the chain's reference path: :mod:`veriloc_rt.phy.shortcuts`) plus
config changes at dotted paths (``--b-set channel.ue_noise_figure_db=10``), so one checkout
compares its shortcuts against its reference path. By default both versions run the same seeds
(the same trajectories and large-scale fading, each version's own noise): the points of the two
samples are then positively correlated, which makes the unpaired tests conservative. With
``--b-seed-offset`` version B runs other seeds: two independent samples (how the harness is
tested on two identical versions).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/equivalence.py [CONFIG] --seeds 8 \\
        --points 150 [--a-env VERILOC_RT_REFERENCE=all] [--b-env NAME=VALUE] \\
        [--b-set FIELD=JSON] [--b-seed-offset N] [--out REPORT.md] [--trace-cache DIR]

It also reports each version's chain CPU a trajectory point (``time.process_time`` around every
``ScenarioRunner.compute_chains`` call, all scenarios' chains of the point; the versions
alternate seed by seed, so both see the same machine load).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: SNR bin edges of the ToA-error comparison, dB (per-RE SNR of the links table)
SNR_EDGES_DB = (-np.inf, -20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0, np.inf)
#: fewest samples per version for a distribution or share test to be run
MIN_SAMPLES = 20
#: detectors whose verdicts carry state from point to point in every scenario: compared with the
#: run as the unit (the tracker's rejects come in bursts: one lost track rejects a stretch)
RUN_LEVEL = ("Tracking",)
#: the shift in an outcome share whose detection power the report states (1 percentage point)
SHIFT = 0.01


@dataclass(frozen=True)
class Version:
    """Environment variables and config changes (dotted paths) of one version."""

    env: dict = field(default_factory=dict)
    changes: dict = field(default_factory=dict)
    seed_offset: int = 0

    def label(self) -> str:
        parts = [f"{k}={v}" for k, v in self.env.items()] + [f"{k}={json.dumps(v)}" for k, v in self.changes.items()]
        if self.seed_offset:
            parts.append(f"seeds +{self.seed_offset}")
        return ", ".join(parts) or "(as checked out)"


@dataclass
class Sample:
    """What one version's runs gave, pooled over the seeds."""

    outcomes: dict = field(default_factory=dict)    # (scenario, prs) -> [outcome str]
    errors: dict = field(default_factory=dict)      # scenario -> [error m] (points with a fix)
    rejects: dict = field(default_factory=dict)     # (scenario, detector) -> per run [bool rejected]
    stats: dict = field(default_factory=dict)       # (scenario, detector) -> per run [statistic]
    links: list = field(default_factory=list)       # benign links: (snr_re_db, heard, toa_error_m)
    chain_cpu_s: float = 0.0
    points: int = 0
    tracer_calls: int = 0   # ray-tracing (PathSolver) calls its runs made: the cache's misses

    def add(self, key, store: dict, values) -> None:
        store.setdefault(key, []).extend(values)


@contextmanager
def environment(env: dict):
    """``os.environ`` with ``env`` set, restored after."""
    old = {k: os.environ.get(k) for k in env}
    os.environ.update({k: str(v) for k, v in env.items()})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class ChainClock:
    """Process CPU seconds spent in ``ScenarioRunner.compute_chains`` while installed."""

    def __init__(self):
        self.seconds = 0.0

    @contextmanager
    def installed(self):
        from veriloc_rt.sim.runner import ScenarioRunner

        real = ScenarioRunner.compute_chains

        def timed(runner, scenario, i):
            t = time.process_time()
            try:
                return real(runner, scenario, i)
            finally:
                self.seconds += time.process_time() - t

        ScenarioRunner.compute_chains = timed
        try:
            yield self
        finally:
            ScenarioRunner.compute_chains = real


def run_rows(config: str | None, seed: int, points: int, version: Version,
             cache_dir: Path | None = None) -> tuple[dict, float, int]:
    """One run (no output folder, one process) of ``config`` at ``seed`` under ``version``:
    (rows by scenario, chain CPU seconds, ray-tracing calls made: none when the cache held them
    all or the config is stochastic).

    :param cache_dir: the ray tracer's cache (None: none, every traced link traced again)
    """
    from veriloc_rt.config import load_config, with_overrides
    from veriloc_rt.sim.engine import run

    cfg = load_config(config)
    if version.changes:
        cfg = cfg.updated(version.changes)
    cfg = with_overrides(cfg, points=points, seed=seed + version.seed_offset)
    clock = ChainClock()
    with environment(version.env), clock.installed():
        res = run(cfg, None, progress=None, workers=1, cache_dir=cache_dir)
    return res.rows, clock.seconds, int(res.propagation.stats.get("calls", 0))


def add_rows(sample: Sample, rows: dict, points: int) -> None:
    """Pool one run's rows into ``sample``: every point of 'none', the attack window of an
    attack (the evaluated points, as the run's metrics count them)."""
    from veriloc_rt.detectors.outcomes import DETECTORS

    for scenario, rs in rows.items():
        ev = [r for r in rs if scenario == "none" or r.attack]
        sample.add((scenario, "standard"), sample.outcomes, [r.outcome for r in ev])
        enc = [r.outcome_enc for r in ev if r.outcome_enc]
        if enc:
            sample.add((scenario, "encrypted"), sample.outcomes, enc)
        sample.add(scenario, sample.errors, [r.error_m for r in ev if np.isfinite(r.error_m)])
        for d in DETECTORS:
            sample.add((scenario, d), sample.rejects, [[not r.verdicts[d] for r in ev]])
            sample.add((scenario, d), sample.stats, [[float(r.stats.get(d, np.nan)) for r in ev]])
        if scenario == "none":
            for r in ev:
                for link in r.links or ():
                    # LINK_COLUMNS after index: trp, bs_id, distance, rx dBm, snr_re_db, heard,
                    # toa_error_m, ...
                    sample.links.append((link[4], bool(link[5]), link[6]))
    sample.points += points


def collect(config: str | None, seeds: list[int], points: int, versions: dict[str, Version],
            log=print, cache_dir: str | Path | None = None) -> dict[str, Sample]:
    """Both versions over ``seeds``, alternating seed by seed. A ray-traced config's links are
    traced into one cache that every run reads (``cache_dir``, else a temporary folder removed
    at the end): a seed's drive is traced once, by its first version, and the other reads it
    (the cache's key holds the scene, the drive and the tracing settings, so a version that
    changes those traces its own)."""
    samples = {name: Sample() for name in versions}
    with tempfile.TemporaryDirectory(prefix="equivalence_trace_") as tmp:
        cache = Path(cache_dir) if cache_dir is not None else Path(tmp)
        for seed in seeds:
            for name, v in versions.items():
                rows, cpu, calls = run_rows(config, seed, points, v, cache)
                add_rows(samples[name], rows, points)
                samples[name].chain_cpu_s += cpu
                samples[name].tracer_calls += calls
                log(f"seed {seed + v.seed_offset} version {name}: chain {1000 * cpu / points:.1f} ms a point"
                    + (f", {calls} ray-tracing calls" if calls else ""))
    return samples


# -- the tests ---------------------------------------------------------------------------------

def wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a binomial share k / n (95 % by default)."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (c - h, c + h)


def two_proportion_p(k1: int, n1: int, k2: int, n2: int) -> float:
    """Two-sided p-value of the pooled two-proportion z-test (1 when both shares are 0 or 1)."""
    from scipy.stats import norm

    p = (k1 + k2) / (n1 + n2)
    se = math.sqrt(p * (1 - p) * (1 / n1 + 1 / n2))
    if se == 0:
        return 1.0
    return float(2 * norm.sf(abs(k1 / n1 - k2 / n2) / se))


def power_two_proportion(p0: float, n1: int, n2: int, shift: float, alpha: float) -> float:
    """Power of the two-sided pooled two-proportion z-test at level ``alpha`` to detect shares
    p0 and p0 + shift (p0 - shift when that leaves [0, 1]) with n1 and n2 samples:
    Phi((|d| - z sigma0) / sigma1) + Phi((-|d| - z sigma0) / sigma1), sigma0 the pooled
    standard error under H0, sigma1 the standard error under the alternative."""
    from scipy.stats import norm

    p1 = p0
    p2 = p0 + shift if p0 + shift <= 1 else p0 - shift
    pbar = (n1 * p1 + n2 * p2) / (n1 + n2)
    s0 = math.sqrt(pbar * (1 - pbar) * (1 / n1 + 1 / n2))
    s1 = math.sqrt(p1 * (1 - p1) / n1 + p2 * (1 - p2) / n2)
    z = norm.isf(alpha / 2)
    d = abs(p2 - p1)
    return float(norm.cdf((d - z * s0) / s1) + norm.cdf((-d - z * s0) / s1))


def n_for_power(p0: float, shift: float, alpha: float, power: float = 0.8) -> int:
    """Samples per version the two-proportion z-test needs for ``power`` (equal sizes)."""
    from scipy.stats import norm

    p1, p2 = p0, (p0 + shift if p0 + shift <= 1 else p0 - shift)
    pbar = (p1 + p2) / 2
    za, zb = norm.isf(alpha / 2), norm.isf(1 - power)
    n = (za * math.sqrt(2 * pbar * (1 - pbar)) + zb * math.sqrt(p1 * (1 - p1) + p2 * (1 - p2))) ** 2 / shift**2
    return int(math.ceil(n))


@dataclass
class Test:
    family: str
    name: str
    a: str
    b: str
    p: float
    holm_alpha: float = math.nan
    rejected: bool = False


def share_text(k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    return f"{100 * k / n:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] (n {n})"


def share_test(family: str, name: str, xa, xb) -> Test | None:
    xa, xb = np.asarray(xa, bool), np.asarray(xb, bool)
    if xa.size < MIN_SAMPLES or xb.size < MIN_SAMPLES:
        return None
    ka, kb = int(xa.sum()), int(xb.sum())
    return Test(family, name, share_text(ka, xa.size), share_text(kb, xb.size),
                two_proportion_p(ka, xa.size, kb, xb.size))


def distribution_tests(family: str, name: str, xa, xb, ad: bool = False) -> list[Test]:
    from scipy.stats import anderson_ksamp, ks_2samp

    xa, xb = np.asarray(xa, float), np.asarray(xb, float)
    xa, xb = xa[np.isfinite(xa)], xb[np.isfinite(xb)]
    if xa.size < MIN_SAMPLES or xb.size < MIN_SAMPLES:
        return []

    def summary(x):
        q = np.percentile(x, [50, 95])
        return f"p50 {q[0]:.3g}, p95 {q[1]:.3g} (n {x.size})"

    with warnings.catch_warnings():
        # SciPy falls back from the exact p-value to the asymptotic one on some tied samples,
        # with a warning
        warnings.filterwarnings("ignore", "ks_2samp: Exact calculation unsuccessful", RuntimeWarning)
        p = float(ks_2samp(xa, xb).pvalue)
    out = [Test(family, f"{name}: KS", summary(xa), summary(xb), p)]
    if ad:
        with warnings.catch_warnings():
            # SciPy warns when it floors (0.001) or caps (0.25) the p-value: the bounds are
            # stated in the report
            warnings.simplefilter("ignore", UserWarning)
            res = anderson_ksamp([xa, xb])
        out.append(Test(family, f"{name}: Anderson-Darling", "", "", float(res.pvalue)))
    return out


def run_level_tests(name: str, rej_a, rej_b, stat_a, stat_b) -> list[Test]:
    """An attack scenario's detector, one value per run: the reject shares and the medians of
    the finite statistics, by the two-sample KS test (exact p-value)."""
    from scipy.stats import ks_2samp

    def per_run(runs, f):
        return np.array([f(np.asarray(r, float)) for r in runs if len(r)])

    def median(x):
        x = x[np.isfinite(x)]
        return float(np.median(x)) if x.size else np.nan

    out = []
    for what, va, vb in (("reject share per run", per_run(rej_a, np.mean), per_run(rej_b, np.mean)),
                         ("median statistic per run", per_run(stat_a, median), per_run(stat_b, median))):
        va, vb = va[np.isfinite(va)], vb[np.isfinite(vb)]
        if va.size < 2 or vb.size < 2:
            continue
        text = lambda v: f"mean {np.mean(v):.3g}, range {np.min(v):.3g}-{np.max(v):.3g} ({v.size} runs)"  # noqa: E731
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", "ks_2samp: Exact calculation unsuccessful", RuntimeWarning)
            p = 1.0 if np.array_equal(np.sort(va), np.sort(vb)) else float(ks_2samp(va, vb, method="exact").pvalue)
        out.append(Test("detector (runs)", f"{name}: {what}", text(va), text(vb), p))
    return out


def compare(a: Sample, b: Sample, alpha: float = 0.05) -> list[Test]:
    """Every test of the module docstring, with the Holm-Bonferroni verdicts at ``alpha``."""
    from veriloc_rt.detectors.outcomes import OUTCOMES

    tests: list[Test] = []
    for key in sorted(set(a.outcomes) & set(b.outcomes)):
        oa, ob = np.asarray(a.outcomes[key]), np.asarray(b.outcomes[key])
        for o in OUTCOMES:
            t = share_test("outcome share", f"{key[0]} {key[1]}: {o}", oa == o, ob == o)
            tests += [t] if t else []
    for s in sorted(set(a.errors) & set(b.errors)):
        tests += distribution_tests("position error", s, a.errors[s], b.errors[s], ad=True)
    for key in sorted(set(a.rejects) & set(b.rejects)):
        name = f"{key[0]} {key[1]}"
        if key[0] != "none" or key[1] in RUN_LEVEL:   # the run is the unit (module docstring)
            tests += run_level_tests(name, a.rejects[key], b.rejects[key], a.stats[key], b.stats[key])
            continue
        pool = lambda runs: np.concatenate([np.asarray(r, float) for r in runs])   # noqa: E731
        t = share_test("detector rejects", name, pool(a.rejects[key]) > 0, pool(b.rejects[key]) > 0)
        tests += [t] if t else []
        sa, sb = pool(a.stats[key]), pool(b.stats[key])
        t = share_test("detector statistic", f"{name}: non-finite", ~np.isfinite(sa), ~np.isfinite(sb))
        tests += [t] if t else []
        tests += distribution_tests("detector statistic", name, sa, sb)
    la, lb = np.asarray(a.links, float).reshape(-1, 3), np.asarray(b.links, float).reshape(-1, 3)
    for lo, hi in zip(SNR_EDGES_DB[:-1], SNR_EDGES_DB[1:]):
        ia = (la[:, 0] >= lo) & (la[:, 0] < hi)
        ib = (lb[:, 0] >= lo) & (lb[:, 0] < hi)
        name = f"SNR [{lo:g}, {hi:g}) dB"
        t = share_test("ToA per SNR bin", f"{name}: heard", la[ia, 1] > 0, lb[ib, 1] > 0)
        tests += [t] if t else []
        tests += distribution_tests("ToA per SNR bin", f"{name}: ToA error m",
                                    la[ia & (la[:, 1] > 0), 2], lb[ib & (lb[:, 1] > 0), 2])
    holm(tests, alpha)
    return tests


def holm(tests: list[Test], alpha: float) -> None:
    """Holm-Bonferroni step-down at family level ``alpha``: sets each test's level and verdict."""
    m = len(tests)
    order = sorted(range(m), key=lambda i: tests[i].p)
    still = True
    for rank, i in enumerate(order):
        tests[i].holm_alpha = alpha / (m - rank)
        still = still and tests[i].p <= tests[i].holm_alpha
        tests[i].rejected = still


def power_lines(a: Sample, b: Sample, m: int, alpha: float) -> list[str]:
    """The power calculation for a 1-point shift in each outcome share, as report lines."""
    lines = [
        f"Power to detect a {100 * SHIFT:g}-point shift in an outcome share (two-sided pooled "
        "two-proportion z-test, normal approximation): shares p0 (the pooled observed share) and "
        f"p0 + {SHIFT:g}; sigma0 = sqrt(pbar (1 - pbar) (1/nA + 1/nB)) under H0, "
        "sigma1 = sqrt(p0 (1 - p0)/nA + p1 (1 - p1)/nB) under the shift; "
        "power = Phi((d - z sigma0)/sigma1) + Phi((-d - z sigma0)/sigma1), z = z(1 - level/2). "
        "p0 is clamped to [0.0001, 0.9999] (a share of 0 or 100 % is tested as 0.01 %). "
        f"Levels: {alpha:g} (one test alone) and {alpha:g}/{m} (the family's strictest Holm level). "
        "n80: points per version for 80 % power at the single-test level.",
        "",
        f"| share | nA | nB | p0 | power at {alpha:g} | power at {alpha:g}/{m} | n80 |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    from veriloc_rt.detectors.outcomes import OUTCOMES

    for key in sorted(set(a.outcomes) & set(b.outcomes)):
        oa, ob = np.asarray(a.outcomes[key]), np.asarray(b.outcomes[key])
        for o in OUTCOMES:
            na, nb = oa.size, ob.size
            if na == 0 or nb == 0:
                continue
            p0 = float(((oa == o).sum() + (ob == o).sum()) / (na + nb))
            p0 = min(max(p0, 1e-4), 1 - 1e-4)
            lines.append(f"| {key[0]} {key[1]}: {o} | {na} | {nb} | {100 * p0:.1f} % | "
                         f"{power_two_proportion(p0, na, nb, SHIFT, alpha):.2f} | "
                         f"{power_two_proportion(p0, na, nb, SHIFT, alpha / m):.2f} | "
                         f"{n_for_power(p0, SHIFT, alpha)} |")
    return lines


def report(config: str, seeds: list[int], points: int, versions: dict[str, Version],
           samples: dict[str, Sample], tests: list[Test], alpha: float) -> tuple[str, bool]:
    """The report (markdown) and whether the versions were distinguished."""
    a, b = samples["A"], samples["B"]
    rejected = [t for t in tests if t.rejected]
    lines = [f"# Statistical equivalence: {Path(config).name if config else 'built-in default'}",
             "",
             f"{len(seeds)} seeds ({seeds[0]}-{seeds[-1]}) x {points} points, all scenarios.",
             f"- version A: {versions['A'].label()}",
             f"- version B: {versions['B'].label()}",
             f"- chain CPU a trajectory point (process time, all scenarios' chains): "
             f"A {1000 * a.chain_cpu_s / a.points:.1f} ms, B {1000 * b.chain_cpu_s / b.points:.1f} ms "
             f"(B / A {b.chain_cpu_s / a.chain_cpu_s:.3f})",
             "",
             f"**Verdict: {'DIFFERENT' if rejected else 'not distinguished'}** "
             f"({len(rejected)} of {len(tests)} tests reject at the Holm-Bonferroni family level {alpha:g}).",
             ""]
    lines += power_lines(a, b, len(tests), alpha)
    lines += ["", "| family | comparison | A | B | p | Holm level | rejects |",
              "| --- | --- | --- | --- | --- | --- | --- |"]
    for t in tests:
        lines.append(f"| {t.family} | {t.name} | {t.a} | {t.b} | {t.p:.3g} | {t.holm_alpha:.2g} | "
                     f"{'**yes**' if t.rejected else 'no'} |")
    return "\n".join(lines) + "\n", bool(rejected)


def main(argv=None) -> int:
    from harness import parse_assignments   # this folder's (the tests load this module alone)

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", default=str(ROOT / "configs" / "paper-uma.json"))
    ap.add_argument("--seeds", type=int, default=8, help="seeds 1..N (each a run per version)")
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--points", type=int, default=150, help="trajectory points of each run")
    ap.add_argument("--alpha", type=float, default=0.05, help="the tests' family level")
    for v in ("a", "b"):
        ap.add_argument(f"--{v}-env", action="append", metavar="NAME=VALUE",
                        help=f"an environment variable of version {v.upper()}")
        ap.add_argument(f"--{v}-set", action="append", metavar="FIELD=JSON",
                        help=f"a config change of version {v.upper()} (dotted path)")
        ap.add_argument(f"--{v}-seed-offset", type=int, default=0,
                        help=f"version {v.upper()} runs seeds shifted by this")
    ap.add_argument("--out", help="write the report (markdown) here too")
    ap.add_argument("--trace-cache", metavar="DIR",
                    help="a ray-traced config's cache folder, kept for later comparisons on the "
                         "same seeds (default: a temporary one, removed at the end)")
    args = ap.parse_args(argv)
    if args.seeds < 1 or args.points < 4 or not 0 < args.alpha < 1:
        print("error: --seeds, --points, --alpha: out of range", file=sys.stderr)
        return 2
    from veriloc_rt.errors import InputError

    try:
        versions = {v.upper(): Version(parse_assignments(getattr(args, f"{v}_env"), f"--{v}-env", False),
                                       parse_assignments(getattr(args, f"{v}_set"), f"--{v}-set", True),
                                       getattr(args, f"{v}_seed_offset"))
                    for v in ("a", "b")}
    except (ValueError, json.JSONDecodeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    t = time.perf_counter()
    try:
        samples = collect(args.config, seeds, args.points, versions,
                          log=lambda s: print(s, file=sys.stderr, flush=True),
                          cache_dir=args.trace_cache)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    tests = compare(samples["A"], samples["B"], args.alpha)
    text, _ = report(args.config, seeds, args.points, versions, samples, tests, args.alpha)
    text += f"\nWall time of the comparison: {time.perf_counter() - t:.0f} s.\n"
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
