#!/usr/bin/env python3
"""Calibrate the Gaussian range-error overbound table of ``receiver.range_error_model``
'overbound' from benign runs of this simulator.

The weighted fix's integrity test assumes each ToA's range error is zero-mean Gaussian with the
std the fix gives it. On a multipath channel first arrivals are late and heavy-tailed, so the
CRLB model understates the error and the test fires on benign fixes. GNSS integrity (ARAIM)
answers with an *overbound*: a Gaussian whose tails are at least as heavy as the measured error
distribution's (DeCleene, "Defining pseudorange integrity - overbounding", ION GPS 2000;
Blanch et al., "Gaussian bounds of sample distributions for integrity analysis", IEEE Trans.
AES 55(4), 2019; references as recalled). This script measures it:

1. benign runs (scenario ``none``) of the stochastic channel the table is for (by default
   ``configs/uma-9trps.json``: TR 38.901 UMa with fast fading, 9 TRPs, power control off), on
   seeds other than the evaluation runs' (seed 1);
2. every heard link of their ``none_links.csv``: the ToA range error ``toa_error_m`` and the
   correlation peak's SNR ``peak_snr_db`` (what the receiver knows);
3. the errors centred by their overall median (an error common to every TRP cancels in the
   RSTDs, so only the spread about it matters);
4. peak-SNR bins of ``--bin-db`` dB, merged upwards until each holds ``--min-count`` links;
5. per bin the smallest sigma whose zero-mean Gaussian has at least the empirical probability
   in each tail (``veriloc_rt.phy.chain.receiver.gaussian_overbound``): for every centred
   error y of the bin with empirical tail probability P(Y >= y) = q (right tail, y > 0; the
   left tail alike) and ``--p-min`` <= q <= 10 % (the tails; near the median the ratio is the
   median's sampling noise over z ~ 0), sigma >= y / z(1 - q). Below ``--p-min`` the sample cannot speak for the tail (a bin of a
   few hundred links), and the table says so.

It writes the table (JSON) and prints it. Usage:

    .venv/bin/python scripts/calibrate_range_overbound.py --out out/overbound-calibration

rewrites ``veriloc_rt/data/range_overbound.json`` (``--table`` elsewhere).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def bins(snr: np.ndarray, width_db: float, min_count: int) -> np.ndarray:
    """Edges of peak-SNR bins ``width_db`` wide, merged upwards to ``min_count`` links each."""
    lo, hi = np.floor(snr.min() / width_db) * width_db, np.ceil(snr.max() / width_db) * width_db
    fine = np.arange(lo, hi + width_db / 2, width_db)
    if fine.size < 2:
        fine = np.array([lo, lo + width_db])
    counts = np.histogram(snr, fine)[0]
    edges, acc = [fine[0]], 0
    for e, c in zip(fine[1:], counts):
        acc += c
        if acc >= min_count:
            edges.append(e)
            acc = 0
    if acc:                      # the remainder joins the last bin
        if len(edges) > 1:
            edges[-1] = fine[-1]
        else:
            edges.append(fine[-1])
    return np.asarray(edges, dtype=float)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default="configs/uma-9trps.json",
                    help="the channel and layout to calibrate on (benign runs of it)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[101])
    ap.add_argument("--points", type=int, default=200, help="trajectory points per seed")
    ap.add_argument("--out", default="out/overbound-calibration", help="folder of the runs")
    ap.add_argument("--table", default=str(ROOT / "veriloc_rt" / "data" / "range_overbound.json"))
    ap.add_argument("--bin-db", type=float, default=3.0)
    ap.add_argument("--min-count", type=int, default=150)
    ap.add_argument("--p-min", type=float, default=0.005)
    a = ap.parse_args(argv)
    from veriloc_rt.cli import main as veriloc_main
    from veriloc_rt.phy.chain.receiver import OVERBOUND_TAIL_MAX, gaussian_overbound

    base = json.loads(Path(a.config).read_text())
    err, snr = [], []
    for seed in a.seeds:
        cfg = json.loads(json.dumps(base))
        cfg["seed"] = seed
        cfg.setdefault("trajectory", {})["num_points"] = a.points
        cfg.setdefault("run", {}).update({"scenarios": ["none"], "evaluate_encrypted": False})
        run = Path(a.out) / f"seed{seed}"
        run.mkdir(parents=True, exist_ok=True)
        (run.parent / f"seed{seed}.json").write_text(json.dumps(cfg, indent=1))
        if not (run / "none_links.csv").exists():
            if veriloc_main(["run", str(run.parent / f"seed{seed}.json"), "--out", str(run)]):
                return 1
        with open(run / "none_links.csv", newline="") as fh:
            for r in csv.DictReader(fh):
                if r["heard"] == "1" and r["toa_error_m"] not in ("", "nan"):
                    err.append(float(r["toa_error_m"]))
                    snr.append(float(r["peak_snr_db"]))
    err, snr = np.asarray(err), np.asarray(snr)
    from veriloc_rt.config import config_from_dict
    resolved = config_from_dict(base)
    centre = float(np.median(err))
    y = err - centre
    edges = bins(snr, a.bin_db, a.min_count)
    which = np.clip(np.searchsorted(edges, snr, side="right") - 1, 0, edges.size - 2)
    sigma, count, p95 = [], [], []
    for b in range(edges.size - 1):
        yb = y[which == b]
        sigma.append(round(gaussian_overbound(yb, a.p_min), 3))
        count.append(int(yb.size))
        p95.append(round(float(np.percentile(np.abs(yb), 95)), 3))
    table = {
        "what": "Gaussian overbound (zero mean) of the ToA range error per correlation-peak "
                "SNR bin, for receiver.range_error_model 'overbound'. A calibration from "
                "benign runs of this simulator (veriloc-rt), not a measurement of any real "
                "channel.",
        "channel": (f"TR 38.901 {resolved.propagation.model} "
                    f"({resolved.propagation.uma_mode}), {resolved.topology.num_trps} TRPs, "
                    f"power control {'on' if resolved.channel.power_control else 'off'}, "
                    "benign (scenario none); calibration config: " + json.dumps(base)),
        "made_by": "scripts/calibrate_range_overbound.py " + " ".join(
            f"--{k.replace('_', '-')} {' '.join(map(str, v)) if isinstance(v, list) else v}"
            for k, v in (("config", a.config), ("seeds", a.seeds), ("points", a.points),
                         ("bin_db", a.bin_db), ("min_count", a.min_count),
                         ("p_min", a.p_min))),
        "links": int(err.size), "centre_m": round(centre, 3),
        "tail_probabilities": [a.p_min, OVERBOUND_TAIL_MAX],
        "snr_edges_db": [float(e) for e in edges], "sigma_m": sigma, "count": count,
        "abs_p95_m": p95,
    }
    Path(a.table).write_text(json.dumps(table, indent=1) + "\n")
    print(json.dumps(table, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
