"""The heavy packages a run needs only to compute chains are imported when a chain is computed.

A resume whose points are all in --out computes no chain: its time is the interpreter's start,
the imports, the stored results and the plots (docs/running.md). scipy.signal (which loads
scipy.stats), scipy.optimize and the ldpc package (which loads its quantum-code decoders) were
half of that start; they are imported where they are used.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy.special import chdtri

ROOT = Path(__file__).resolve().parents[2]
#: loaded by the chain's estimators, decoder and tag verifier only, and by a ray-traced
#: scene's meshes (trimesh: the PLY files are written without it)
LAZY = ("scipy.stats", "scipy.signal", "scipy.optimize", "ldpc", "scipy.ndimage", "trimesh", "numba")


def test_the_run_modules_load_no_chain_only_package():
    code = ("import sys, veriloc_rt.cli, veriloc_rt.sim.engine, veriloc_rt.report.plots, "
            "veriloc_rt.world.scene.export; "
            f"print(' '.join(m for m in {LAZY!r} if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                       check=True)
    assert r.stdout.strip() == "", r.stdout


#: loaded by the OpenStreetMap import only (veriloc_rt.world.scene.osm imports them on use)
OSM_ONLY = ("osmnx", "pyrosm", "pyproj", "shapely", "geopandas")


def test_the_run_modules_load_no_osm_package():
    code = ("import sys, veriloc_rt.cli, veriloc_rt.sim.engine, veriloc_rt.sim.checks, "
            "veriloc_rt.world.geometry, veriloc_rt.world.scene.osm; "
            f"print(' '.join(m for m in {OSM_ONLY!r} if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                       check=True)
    assert r.stdout.strip() == "", r.stdout


#: chdtri inverts the regularised incomplete gamma function iteratively: agreement with the
#: closed forms to ~1e-14 relative (1.9e-14 measured for k = 1); 1e-10 is ample
CHI2_RTOL = 1e-10


def test_chi_square_gate_without_scipy_stats():
    # the multilaterator's gate chdtri(k, q) is chi2.isf(q, k); closed forms at q = 1e-3:
    # k = 1: (Phi^-1(1 - q/2))^2 with Phi^-1(0.9995) = 3.2905267314919 (normal quantile);
    # k = 2: -2 ln q = 13.8155
    assert np.isclose(chdtri(1, 1e-3), 3.2905267314919255 ** 2, rtol=CHI2_RTOL, atol=0)
    assert np.isclose(chdtri(2, 1e-3), -2.0 * np.log(1e-3), rtol=CHI2_RTOL, atol=0)


def test_ldpc_decoder_built_on_first_decode():
    from veriloc_rt.phy.security.ldpc import NRLDPC

    code = NRLDPC(256, iterations=25)
    assert "_decoder" not in vars(code)            # nothing of the ldpc package yet
    bits = np.random.default_rng(0).integers(0, 2, 256).astype(np.uint8)
    cw = code.encode(bits)
    llr = np.where(cw == 0, 4.0, -4.0)             # confident LLRs, but for one sent bit
    wrong = int(np.flatnonzero(cw[:256] == 0)[0])  # flipped, weakly: not a codeword, so belief
    llr[wrong] = -0.5                              # propagation runs (a codeword skips it)
    decoded, ok = code.decode(llr)
    assert "_decoder" in vars(code)
    assert bool(ok) and np.array_equal(decoded, bits)


def test_writing_a_canyon_scene_loads_no_trimesh(tmp_path):
    # the PLY writer is the package's own (trimesh's bytes, tests/unit/world/scene): a run on a
    # generated canyon writes its meshes without importing trimesh
    code = ("import sys, numpy as np; from veriloc_rt.world.scene.export import write_ply; "
            f"write_ply(__import__('pathlib').Path({str(tmp_path / 'm.ply')!r}), "
            "np.zeros((3, 3)), np.array([[0, 1, 2]])); print('trimesh' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                       check=True)
    assert r.stdout.strip() == "False"
    assert (tmp_path / "m.ply").stat().st_size > 0
