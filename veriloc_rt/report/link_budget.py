"""Link budget of a run: received PRS power, SNR per RE and the tags' margin against their
decoding threshold, per point and TRP (``<scenario>_links.csv``) and summarised in
``metrics.json`` (``link_budget``).

Tag margin of a link, dB::

    margin = snr_re_db + 10 log10(A) - threshold_db(scheme) - MULTIPATH_PENALTY_DB

* ``snr_re_db``: the link's received PRS power per RE over the noise per RE, per UE antenna
  (``runner.trp_links``); the tag receiver combines the ``A`` antennas towards the correlation
  peak (maximum-ratio: :meth:`~veriloc_rt.phy.chain.receiver.TagStage.one`), so the decoder sees
  up to ``10 log10(A)`` dB more;
* ``threshold_db``: :data:`TAG_THRESHOLD_DB`, the per-RE SNR (after combining) from which a
  tag fails in at most 1 % of the checks, measured on the waveform bench
  ``benchmarks/bench_prs.py --rates 15.36e6 --repeats 1 --slots 60 --snr -6 -0.5 0.5``: three
  BSs' tagged grids of the default ``NRConfig`` (52 PRB, 30 kHz, comb 6, 12 PRS symbols) through
  flat channels with random phase and delay, one antenna, AWGN per RE, the channel estimated
  from the PRS; 180 checks per 0.5 dB step (docs/link-budget.md, "Thresholds");
* the multipath penalty (:data:`MULTIPATH_PENALTY_DB`, :func:`multipath_penalty_db`): what a
  multipath channel costs on top (frequency-selective channel estimation, combining weights
  from the correlation peak), measured on the chain's own links (docs/link-budget.md,
  "Multipath penalty").

The thresholds hold for the default PRS resource layout: a config with more or fewer tag REs
per slot (another bandwidth, comb or symbol count) repeats the codeword a different number of
times and moves the threshold by about the ratio of the tag REs, which this margin does not
follow (:func:`link_budget_block` states the layout it assumes).
"""

from __future__ import annotations

import math

import numpy as np

from ..analysis.intervals import binomial_ci, ci_suffix

__all__ = ["TAG_THRESHOLD_DB", "MULTIPATH_PENALTY_DB", "multipath_penalty_db", "tag_margin_db",
           "link_arrays",
           "read_link_arrays", "link_budget_block", "format_link_budget"]

#: per-RE SNR after combining, dB, from which the tag check fails in <= 1 % of the bench's 180
#: checks (benchmarks/bench_prs.py, module docstring): HMAC fails 75 / 30 / 2.8 / 0.6 / 0 % at
#: -4.0 / -3.5 / -3.0 / -2.5 / -2.0 dB; DS 96 / 57 / 11 / 0.6 % at -2.0 / -1.5 / -1.0 / -0.5 dB
TAG_THRESHOLD_DB = {"hmac": -2.5, "ds": -0.5}
#: dB a multipath channel costs the tags over the bench's flat one, by channel kind: the SNR
#: per RE (after combining) at which half the HMAC checks verify, measured on the links of a
#: 120-point drive of the default topology (3 TRPs, 24 dBm, no power control): -3.80 dB on
#: TR 38.901 UMa 'pathloss_only' (one path per link: the bench's -3.72 dB, so no penalty) and
#: +0.50 dB on UMa 'fast_fading' (TR 38.901 clusters, the same drive): 4.3 dB; the
#: multipath waterfall is also shallower (logistic slope 0.5 / dB against 6 / dB), so a link
#: at 0 dB margin verifies in roughly 50-80 % of the checks there (docs/link-budget.md)
MULTIPATH_PENALTY_DB = {"single_path": 0.0, "multipath": 4.3}


def multipath_penalty_db(propagation) -> float:
    """:data:`MULTIPATH_PENALTY_DB` for a run's ``propagation`` config: ``single_path`` for
    the stochastic models' 'pathloss_only' mode (one path per link), ``multipath`` for their
    'fast_fading' mode and for ray tracing (the traced default canyon measured 2.7 dB on 40
    points, too few links in the transition to replace the UMa clusters' figure, which stands
    in for it: docs/link-budget.md)."""
    single = (propagation.model != "raytrace"
              and getattr(propagation, "uma_mode", "") == "pathloss_only")
    return MULTIPATH_PENALTY_DB["single_path" if single else "multipath"]


def tag_margin_db(snr_re_db, num_antennas: int, scheme: str, penalty_db: float) -> np.ndarray:
    """The tags' margin, dB, of links with per-antenna SNR per RE ``snr_re_db`` (module
    docstring); NaN where the SNR is NaN.

    :raises ValueError: for a scheme without a measured threshold
    """
    if scheme not in TAG_THRESHOLD_DB:
        raise ValueError(f"Argument `scheme` must be one of {sorted(TAG_THRESHOLD_DB)}, "
                         f"not {scheme!r}")
    return (np.asarray(snr_re_db, dtype=float) + 10.0 * math.log10(num_antennas)
            - TAG_THRESHOLD_DB[scheme] - penalty_db)


def _percentiles(x: np.ndarray) -> dict:
    x = x[np.isfinite(x)]
    if not x.size:
        return {"p5": None, "p50": None, "p95": None}
    return {k: float(np.percentile(x, q)) for k, q in (("p5", 5), ("p50", 50), ("p95", 95))}


def _share(key: str, hits: np.ndarray) -> dict:
    n, k = int(hits.size), int(hits.sum())
    return {key: (k / n if n else None), ci_suffix(key): binomial_ci(k, n)}


def link_arrays(rows: list) -> dict:
    """The columns :func:`link_budget_block` reads, from rows' per-TRP ``links``
    (:data:`~veriloc_rt.report.results.LINK_COLUMNS` after ``index``): ``index`` [L] int,
    ``rx_power_dbm``, ``snr_re_db`` [L] float, ``heard``, ``tag_verified``, ``used`` [L] bool."""
    links = [(r.index, lk) for r in rows for lk in (r.links or ())]
    return {"index": np.array([i for i, _ in links], dtype=np.int64),
            "rx_power_dbm": np.array([lk[3] for _, lk in links], dtype=float),
            "snr_re_db": np.array([lk[4] for _, lk in links], dtype=float),
            "heard": np.array([lk[5] for _, lk in links], dtype=bool),
            "tag_verified": np.array([lk[9] for _, lk in links], dtype=bool),
            "used": np.array([lk[10] for _, lk in links], dtype=bool)}


def read_link_arrays(path) -> dict:
    """:func:`link_arrays` from a ``<scenario>_links.csv`` (a torn last line dropped)."""
    import csv
    import io
    from pathlib import Path

    text = Path(path).read_text(encoding="utf-8", errors="replace")
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    rows = list(csv.DictReader(io.StringIO(text)))

    def num(c):
        return np.array([float(r[c]) if r[c] not in ("", "nan") else np.nan for r in rows],
                        dtype=float)

    def flag(c):
        return np.array([r[c] == "1" for r in rows], dtype=bool)

    return {"index": np.array([int(r["index"]) for r in rows], dtype=np.int64),
            "rx_power_dbm": num("rx_power_dbm"), "snr_re_db": num("snr_re_db"),
            "heard": flag("heard"), "tag_verified": flag("tag_verified"), "used": flag("used")}


def link_budget_block(links: dict, num_antennas: int, penalty_db: float,
                      schemes=("hmac", "ds"), scenario: str = "none",
                      bs_antenna: str | None = None) -> dict:
    """The ``link_budget`` block of metrics.json from one scenario's links
    (:func:`link_arrays` or :func:`read_link_arrays`): percentiles (p5 / p50 / p95) over the
    links of the received PRS power and the SNR per RE (per antenna), and over the points with
    a fix of the weakest used TRP's tag margin per scheme; the share of links heard (the
    receiver's hearability test), above each scheme's tag threshold, and whose tags verified,
    each with its Clopper-Pearson ``_ci95``; ``bs_antenna`` (when given) names the BS
    antennas the received powers include. Empty without links."""
    idx = np.asarray(links["index"])
    if not idx.size:
        return {}
    snr = np.asarray(links["snr_re_db"], dtype=float)
    used = np.asarray(links["used"], dtype=bool)
    out: dict = {"scenario": scenario, "links": int(idx.size), "rx_antennas": int(num_antennas),
                 "tag_threshold_db": {s: TAG_THRESHOLD_DB[s] for s in schemes},
                 "multipath_penalty_db": float(penalty_db),
                 "rx_power_dbm": _percentiles(np.asarray(links["rx_power_dbm"], dtype=float)),
                 "snr_re_db": _percentiles(snr)}
    if bs_antenna is not None:
        out["bs_antenna"] = bs_antenna
    out.update(_share("heard_share", np.asarray(links["heard"], dtype=bool)))
    out.update(_share("tag_verified_share", np.asarray(links["tag_verified"], dtype=bool)))
    for s in schemes:
        margin = tag_margin_db(snr, num_antennas, s, penalty_db)
        out.update(_share(f"above_{s}_threshold_share", np.nan_to_num(margin, nan=-np.inf) >= 0))
        # per point with a fix: the least margin of the TRPs its fix used
        pts = np.unique(idx[used])
        weakest = np.array([np.min(margin[used & (idx == i)]) for i in pts], dtype=float)
        out[f"weakest_used_{s}_margin_db"] = _percentiles(weakest)
    return out


def format_link_budget(block: dict) -> str:
    """The ``link_budget`` block as one line of text (shares in percent)."""
    if not block:
        return "link budget: no links"

    def pct(key):
        v, ci = block.get(key), block.get(ci_suffix(key))
        return "n/a" if v is None else f"{100 * v:.0f} %" + (
            f" [{100 * ci[0]:.0f}-{100 * ci[1]:.0f}]" if ci else "")

    def p50(d):
        return "n/a" if d.get("p50") is None else f"{d['p50']:.1f}"

    tags = "; ".join(f"{s.upper()} threshold {block['tag_threshold_db'][s]:g} dB: weakest used "
                     f"TRP margin p50 {p50(block[f'weakest_used_{s}_margin_db'])} dB, links "
                     f"above {pct(f'above_{s}_threshold_share')}"
                     for s in block["tag_threshold_db"])
    return (f"link budget ({block['scenario']}, {block['links']} links): rx PRS p50 "
            f"{p50(block['rx_power_dbm'])} dBm, SNR/RE p50 {p50(block['snr_re_db'])} dB per "
            f"antenna (x{block['rx_antennas']} combined); heard {pct('heard_share')}; {tags}; "
            f"tags verified {pct('tag_verified_share')}"
            + (f"; BS antenna {block['bs_antenna']}" if block.get("bs_antenna") else ""))
