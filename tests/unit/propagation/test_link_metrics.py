"""Per-link comparison of two traces (link_metrics) on hand-made path sets.

Every expected value is worked out by hand in the comments from the path lists below.
"""

import numpy as np
import pytest

from veriloc_rt.propagation import link_metrics as lm

D, R = 8, 1          # Sionna's interaction codes: diffraction, specular reflection
#: dB values below are 10 log10 of small rationals, written to 4 decimals
DB_TOL = 1e-4
US = 1e-6


def paths(links: list[list[tuple]], depth: int):
    """[(tau s, power, (codes...)), ...] per link -> (tau, power, interactions, valid)."""
    n = max(1, max(len(p) for p in links))
    tau = np.full((len(links), n), -1.0)
    power = np.zeros((len(links), n))
    inter = np.zeros((len(links), n, depth), np.uint8)
    valid = np.zeros((len(links), n), bool)
    for i, link in enumerate(links):
        for j, (t, p, seq) in enumerate(link):
            tau[i, j], power[i, j], valid[i, j] = t, p, True
            inter[i, j, :len(seq)] = seq
    return tau, power, inter, valid


def test_power_deviation_conventions():
    # 2/1 -> +3.0103 dB; equal -> 0; lost -> -inf; none in both -> 0 (agree); gained -> +inf
    p = np.array([2e-12, 1e-12, 0.0, 0.0, 1e-12])
    ref = np.array([1e-12, 1e-12, 1e-12, 0.0, 0.0])
    d = lm.power_deviation_db(p, ref)
    assert d[0] == pytest.approx(3.0103, abs=DB_TOL)
    assert d[1] == 0.0 and d[3] == 0.0
    assert d[2] == -np.inf and d[4] == np.inf


def test_link_deviation_by_hand():
    ref = paths([
        # link 0: P = 6e-12; strongest DR (4e-12); first D (1e-12): first/strongest = 1/4
        [(1.000 * US, 1e-12, (D,)), (1.010 * US, 4e-12, (D, R)), (1.020 * US, 1e-12, (D, R, R))],
        # link 1: one path
        [(2.000 * US, 2e-12, (D,))],
        # link 2: one path, lost by the test
        [(3.000 * US, 1e-12, (D,))],
        # link 3: strongest DR at 4.000 us
        [(3.990 * US, 1e-12, (D,)), (4.000 * US, 8e-12, (D, R))],
    ], depth=4)
    test = paths([
        # misses the strongest: P = 2e-12 -> 10 log10(2/6) = -4.7712 dB; first D, strongest tie
        # D/DRR (argmax keeps the first) -> first/strongest 0 dB
        [(1.000 * US, 1e-12, (D,)), (1.020 * US, 1e-12, (D, R, R))],
        # gains a DR path: P = 3e-12 -> +1.7609 dB, strongest D found
        [(2.000 * US, 2e-12, (D,)), (2.050 * US, 1e-12, (D, R))],
        [],
        # a DR 0.3 ns from the reference's strongest is another path: not found
        [(3.990 * US, 1e-12, (D,)), (4.0003 * US, 8e-12, (D, R))],
    ], depth=3)
    d = lm.link_deviation(test, ref)
    np.testing.assert_allclose(d["power_dev_db"][[0, 1, 3]], [-4.7712, 1.7609, 0.0], atol=DB_TOL)
    assert d["power_dev_db"][2] == -np.inf
    np.testing.assert_array_equal(d["strongest_found"], [0.0, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(d["first_delay_dev_s"][[0, 1, 3]], 0.0, atol=1e-15)
    assert np.isnan(d["first_delay_dev_s"][2])
    np.testing.assert_allclose(d["first_rel_db"][[0, 1]], [0.0, 0.0], atol=DB_TOL)
    # link 3: 1/8 -> -9.0309 dB in both
    assert d["first_rel_db"][3] == pytest.approx(-9.0309, abs=DB_TOL)
    np.testing.assert_allclose(d["first_rel_db_ref"], [-6.0206, 0.0, 0.0, -9.0309], atol=DB_TOL)
    # the same DR within the tolerance is found
    found = lm.has_path(test[0][3:], test[2][3:], test[3][3:], np.array([4.0003 * US + 1e-12]),
                        np.array([[D, R, 0, 0]], np.uint8))
    assert found.tolist() == [True]


def test_link_deviation_reference_without_paths():
    ref = paths([[]], depth=2)
    test = paths([[(1 * US, 1e-12, (D,))]], depth=2)
    d = lm.link_deviation(test, ref)
    assert d["power_dev_db"][0] == np.inf
    assert np.isnan(d["strongest_found"][0])
    with pytest.raises(ValueError, match="links"):
        lm.link_deviation(paths([[], []], 2), ref)


def test_quantile_keeps_infinities_and_drops_nan():
    x = np.array([-np.inf, 0.0, 1.0, 2.0, np.nan])
    # 4 values sorted [-inf, 0, 1, 2]; inverted CDF: p50 -> the 2nd, p10 -> the 1st, p90 -> 4th
    assert lm.quantile(x, 50) == 0.0
    assert lm.quantile(x, 10) == -np.inf
    assert lm.quantile(x, 90) == 2.0
    assert lm.quantile(np.array([np.nan]), 50) is None


def test_union_merges_copies_and_keeps_neighbours():
    a = paths([[(1.0 * US, 1e-12, (D,)), (1.01 * US, 2e-12, (D, R))], []], depth=2)
    # a copy of a's D (1e-13 s off), a DR 0.2 ns from a's (another path), a DRR; link 1: one path
    b = paths([[(1.0 * US + 1e-13, 1e-12, (D,)), (1.01 * US + 2e-10, 3e-12, (D, R)),
                (1.02 * US, 4e-12, (D, R, R))], [(2.0 * US, 5e-12, (D,))]], depth=3)
    tau, power, inter, valid, src = lm.union_paths([a, b])
    assert valid.sum(axis=1).tolist() == [4, 1]
    # link 0: a's two paths, then b's DR neighbour and DRR; total 1 + 2 + 3 + 4 = 10e-12
    assert src[0][valid[0]].tolist() == [0, 0, 1, 1]
    assert lm.link_power(power, valid)[0] == pytest.approx(10e-12, rel=1e-12)
    assert src[1][valid[1]].tolist() == [1]
    assert inter.shape[-1] == 3


def test_path_class_letters():
    assert lm.path_class(np.array([D, R, R, 0], np.uint8)) == "DRR"
    assert lm.path_class(np.zeros(3, np.uint8)) == "LoS"
