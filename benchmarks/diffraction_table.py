"""Traced diffraction against the exact / independent references, per case, polarization and
tracing direction, for the package's UTD materials and for Sionna RT's own coefficient.

Prints a markdown table (deviation in dB and degrees of each co-polar coefficient: V is the
hard case, H the soft one, on these edge-on geometries). The cases, harness and references are
the tests' (tests/unit/propagation/test_diffraction.py, diffraction_reference.py).

    .venv/bin/python benchmarks/diffraction_table.py
"""

from __future__ import annotations

import sys
import tempfile
import types
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
pkg = types.ModuleType("rtcheck")
pkg.__path__ = [str(ROOT / "tests" / "unit" / "propagation")]
sys.modules["rtcheck"] = pkg
from rtcheck import test_diffraction as T  # noqa: E402
from rtcheck.diffraction_reference import permittivity, sommerfeld_half_plane  # noqa: E402
from rtcheck.rt_scenes import write_test_scene  # noqa: E402


class _Factory:
    def __init__(self, root):
        self.root, self.n = Path(root), 0

    def mktemp(self, name):
        self.n += 1
        p = self.root / f"{name}{self.n}"
        p.mkdir()
        return p


def _dev(traced, want):
    r = np.diag(traced) / np.diag(want)
    return 20 * np.log10(np.abs(r)), np.degrees(np.angle(r))


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        scenes = T.scenes.__wrapped__(_Factory(tmp))
        print("| geometry | phi' / phi deg | coefficient | direction | V (hard) dB / deg | H (soft) dB / deg |")
        print("| --- | --- | --- | --- | --- | --- |")
        for coef in ("utd", "sionna"):
            h = T.Harness(scenes["screen"], coef)
            for php_d, ph_d in T.HALF_PLANE_CASES:
                php, ph = np.deg2rad(php_d), np.deg2rad(ph_d)
                far, near = T.FAR_M * T.direction(php), T.NEAR_M * T.direction(ph)
                _, soft = sommerfeld_half_plane(T.NEAR_M, ph, php, T.K, soft=True)
                _, hard = sommerfeld_half_plane(T.NEAR_M, ph, php, T.K, soft=False)
                scale = T.LAM / (4 * np.pi * T.FAR_M) * np.sqrt(T.FAR_M / (T.FAR_M + T.NEAR_M)) \
                    * np.exp(1j * T.K * T.NEAR_M)
                want = scale * T.expected(-T.direction(php), T.direction(ph), soft, hard)
                for name, (s, d, n) in (("from far end", (far, near, 200_000)),
                                        ("from near end", (near, far, 20_000))):
                    db, deg = _dev(h.diffracted(s, d, np.zeros(3), n, edge_diffraction=True), want)
                    print(f"| PEC half-plane vs exact | {php_d} / {ph_d} | {coef} | {name} | "
                          f"{db[0]:+.2f} / {deg[0]:+.1f} | {db[1]:+.2f} / {deg[1]:+.1f} |")
            for block, eta, label in (("pec_block", None, "PEC right-angle wedge vs KP"),
                                      ("concrete_block", permittivity("concrete", T.FC),
                                       "concrete right-angle wedge vs Luebbers")):
                h = T.Harness(scenes[block], coef)
                for php_d, ph_d in T.WEDGE_CASES:
                    fwd, rev, want = T.wedge_case(h, php_d, ph_d, eta=eta)
                    for name, traced in (("from far end", fwd), ("from near end", rev)):
                        db, deg = _dev(traced, want)
                        print(f"| {label} | {php_d} / {ph_d} | {coef} | {name} | "
                              f"{db[0]:+.2f} / {deg[0]:+.1f} | {db[1]:+.2f} / {deg[1]:+.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
