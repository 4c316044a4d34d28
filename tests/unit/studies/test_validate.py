"""The geometry and bookkeeping of ``veriloc-rt validate`` (no ray tracing): street orientation
per link, path length over the street grid, incoherent path loss of a CIR, distance bins.
Expected values are closed forms written out here."""

import math

import numpy as np
import pytest

from veriloc_rt.propagation.cir import CIR
from veriloc_rt.propagation.pathloss_models import RooftopGeometry
from veriloc_rt.studies.validate import (MODELS, bin_links, covered_length_m, model_db,
                                         street_orientation_rad, traced_pathloss_db)

PITCH, WIDTH = 35.0, 5.0   # the default canyon: 30 m blocks, 5 m streets


def test_street_orientation_in_a_street_and_at_an_intersection():
    ue = np.array([[0.0, 10.0],     # street along y (x = 0 centre line), mid-block
                   [10.0, 35.0],    # street along x (y = 35 centre line)
                   [0.0, 0.0],      # intersection
                   [17.5, 17.5]])   # no street (block centre)
    bs = np.array([[100.0, 110.0],  # direct path at 45 deg to the y axis
                   [40.0, 35.0 + 30.0 * math.tan(math.radians(20.0))],  # 20 deg to the x axis
                   [10.0, 100.0],   # 5.71 deg to y (L_ori -7.98 dB), 84.29 deg to x (0.66 dB)
                   [0.0, 0.0]])
    phi, in_street = street_orientation_rad(ue, bs, PITCH, WIDTH)
    assert np.degrees(phi) == pytest.approx([45.0, 20.0, math.degrees(math.atan2(10, 100)), 90.0],
                                            abs=1e-9)
    assert in_street.tolist() == [True, True, True, False]


@pytest.mark.parametrize("ue, bs, expect", [
    ((0.0, 0.0), (200.0, 0.0), 100.0),              # leaves the square at x = 100
    ((0.0, 0.0), (50.0, 50.0), math.hypot(50, 50)),  # wholly inside
    ((150.0, 0.0), (300.0, 0.0), 0.0),               # wholly outside
    ((0.0, 0.0), (200.0, 200.0), math.sqrt(2) * 100.0),
    ((0.0, 150.0), (50.0, 150.0), 0.0),              # parallel to x, outside in y
    ((-150.0, 0.0), (150.0, 0.0), 200.0),            # crosses the whole square
])
def test_covered_length_clips_the_segment_to_the_grid(ue, bs, expect):
    got = covered_length_m(np.array([ue]), np.array([bs]), 100.0)
    assert got[0] == pytest.approx(expect, abs=1e-9)


def _cir(gains: np.ndarray, valid: np.ndarray) -> CIR:
    """One point, T links, N paths, A antennas; geometry irrelevant to the path loss."""
    p, t, a, n = gains.shape
    z = np.zeros((p, t, n))
    return CIR(delays=np.where(valid, 1e-6, -1.0), gains=gains, aoa_az=z, aoa_zen=z, aod_az=z,
               aod_zen=z, doppler=z, interactions=np.zeros((p, t, n, 4), np.uint8), valid=valid,
               tx_index=np.arange(t)[None, :].repeat(p, 0), tx_pos=np.zeros((p, t, 3)),
               rx_pos=np.zeros((p, 3)), los=np.zeros((p, t), bool), carrier_frequency=3.5e9)


def test_traced_pathloss_is_the_incoherent_sum_on_any_element():
    a = 1e-5   # |a|^2 = 1e-10: 100 dB per path
    phase = np.exp(1j * np.array([0.0, 1.0, 2.5]))[None, None, :, None]   # 3 elements
    gains = np.zeros((1, 3, 3, 2), complex)
    gains[0, 0] = a * phase[0, 0] * np.array([1.0, 1.0])     # two equal paths: 100 - 3.0103 dB
    gains[0, 1] = a * phase[0, 0] * np.array([1.0, 0.0])     # one path (second invalid)
    valid = np.array([[[True, True], [True, False], [False, False]]])
    pl, bound = traced_pathloss_db(_cir(gains, valid))
    assert pl[0, 0] == pytest.approx(100.0 - 10 * math.log10(2), abs=1e-9)
    assert pl[0, 1] == pytest.approx(100.0, abs=1e-9)
    assert np.isnan(pl[0, 2])                                # no path: NaN, not infinity
    assert bound[0].tolist() == pytest.approx([10 * math.log10(2), 0.0, 0.0])


def test_bins_count_links_and_take_median_offsets():
    geo = RooftopGeometry(25.0, 1.5, 15.0, 5.0, 35.0)
    d = np.array([60.0, 70.0, 80.0, 160.0])
    phi = np.radians([90.0, 90.0, 90.0, 30.0])
    links = {"d_2d_m": d, "pl_db": np.array([120.0, 125.0, np.nan, 140.0]),
             "has_path": np.array([True, True, False, True]), "los": np.zeros(4, bool),
             "phi_rad": phi, "covered_m": d.copy()}
    links["model_db"] = {n: model_db(n, d, phi, d, 3.5e9, geo) for n in MODELS}
    bins = bin_links(links, 50.0, 3.5e9, geo)
    assert [(b["d_lo_m"], b["links"], b["no_path"]) for b in bins] == [(50.0, 3, 1), (150.0, 1, 0)]
    b0 = bins[0]
    assert b0["traced_db"]["p50"] == pytest.approx(122.5)
    # median of the two per-link offsets (the link without a path is left out)
    off = [120.0 - links["model_db"]["p1411"][0], 125.0 - links["model_db"]["p1411"][1]]
    assert b0["offset_db"]["p1411"] == pytest.approx(np.mean(off))
    # the model column is the model at the bin centre (75 m) for the bin's phi: all 90 deg here
    assert b0["model_db"]["umi_nlos"] == pytest.approx(
        model_db("umi_nlos", np.array([75.0]), np.radians([90.0]), np.array([75.0]), 3.5e9, geo)[0])
