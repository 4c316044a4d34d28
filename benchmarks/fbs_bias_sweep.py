"""Outcome shares of the FBS 'bias' spoofer against its timing bias, from geometry alone.

The paper's selective spoofer adds "a specific timing delay" to a targeted BS's PRS and does not
give its value. This script shows what the value decides, without any waveform: for every
attack-window point of a config's trajectory it biases the spoofed slots' exact RSTDs by each
bias and runs the chain's multilaterator (same residual check), counting success (<= the run's
success threshold), large error and service failure (no fix). The waveform chain then adds
noise and hearability on top (compare with a run's metrics.json). Usage:

    python benchmarks/fbs_bias_sweep.py configs/paper-uma.json [--bias-m 150 300 450 600 750 1000]
"""

from __future__ import annotations

import argparse
import sys

from veriloc_rt.config import load_config
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.errors import InputError
from veriloc_rt.studies.fbs_bias import sweep


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--bias-m", type=float, nargs="+", default=[150, 300, 450, 600, 750, 1000],
                    help="biases as ranges (c x delay), m")
    args = ap.parse_args(argv)
    try:
        cfg = load_config(args.config)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    slots = cfg.threats.fbs.spoofed_slots or (1,)
    print(f"spoofed slots {list(slots)}, {cfg.trajectory.num_points} points, attack window only")
    print("| bias, m (us) | success % | large error % | service failure % |")
    print("| --- | --- | --- | --- |")
    for bias, s, le, sf in sweep(cfg, args.bias_m, slots):
        print(f"| {bias:.0f} ({1e6 * bias / SPEED_OF_LIGHT:.2f}) | {s:.1f} | {le:.1f} | {sf:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
