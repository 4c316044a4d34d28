"""SRS-like uplink sequence: unit modulus, Zadoff-Chu autocorrelation, cyclic-shift orthogonality."""

import numpy as np
import pytest

from veriloc_rt.phy.nr.srs import srs_grid, srs_sequence


def test_zadoff_chu_base_has_ideal_periodic_autocorrelation():
    # with length = N_ZC + 1 ... use the N_ZC-long core: a ZC sequence of prime length has zero
    # periodic autocorrelation at every non-zero lag (independent property, Chu 1972)
    r = srs_sequence(7, 156, 0)  # M = 156 -> N_ZC = 151
    core = r[:151]
    for lag in (1, 5, 50, 150):
        assert abs(np.vdot(core, np.roll(core, lag))) < 1e-9 * 151
    np.testing.assert_allclose(np.abs(r), 1.0, atol=1e-12)
    np.testing.assert_array_equal(r[151:], r[:5])  # cyclic extension


def test_cyclic_shifts_are_orthogonal():
    # alpha = 2 pi n_cs / n_cs_max and length a multiple of n_cs_max: sum exp(j 2 pi d n / 12) = 0
    a, b = srs_sequence(3, 156, 0, comb=4), srs_sequence(3, 156, 5, comb=4)
    assert abs(np.vdot(a, b)) < 1e-9


def test_grid_mapping():
    g = srs_grid(52, 3, comb=4, comb_offset=2, symbols=(12, 13))
    assert g.shape == (14, 624)
    assert np.flatnonzero(g[13]).tolist() == list(range(2, 624, 4))
    assert np.count_nonzero(g[:12]) == 0


@pytest.mark.parametrize("kwargs", [dict(n_id=1024, length=48), dict(n_id=0, length=30),
                                    dict(n_id=0, length=48, cyclic_shift=12)])
def test_bad_arguments(kwargs):
    with pytest.raises(ValueError):
        srs_sequence(**kwargs)
