"""Gold sequence, c_init and r(m) against an independent bit-serial implementation and fixed vectors."""

import numpy as np
import pytest

from .nr_oracles import gold_reference
from veriloc_rt.phy.nr.prs import (check_comb, gold_sequence, k_prime, prs_c_init, prs_sequence,
                                   prs_subcarriers)


def c_init_reference(n_id, n_s, l, n_symb=14):
    return (2**22 * (n_id // 1024) + 2**10 * (n_symb * n_s + l + 1) * (2 * (n_id % 1024) + 1)
            + (n_id % 1024)) % 2**31


@pytest.mark.parametrize("c_init", [0, 1, 3932177, 2**31 - 1, 12345678])
def test_gold_matches_bit_serial_reference(c_init):
    assert gold_sequence(c_init, 700).tolist() == gold_reference(c_init, 700)


def test_gold_fixed_vectors():
    # MATLAB doc example nrPUSCHPRBS(17,120,300): c_init = 120 * 2^15 + 17, first 15 bits
    # (https://ww2.mathworks.cn/help/5g/ref/nrpuschprbs.html, via standards-and-limits.md 1a)
    assert gold_sequence(3932177, 15).tolist() == [0, 1, 1, 0, 1, 1, 0, 1, 0, 0, 0, 0, 1, 1, 1]
    # self-computed in standards-and-limits.md 1a (numpy implementation of the recursion)
    assert "".join(map(str, gold_sequence(1, 32))) == "00000010100000110000001101110100"
    assert "".join(map(str, gold_sequence(0, 32))) == "00000010000110100001001001111010"


@pytest.mark.parametrize("n_id,n_s,l,expected", [
    (0, 0, 0, 1024), (0, 0, 11, 12288), (1, 0, 0, 3073), (1023, 0, 0, 2097151),
    (1024, 0, 0, 4195328), (4095, 9, 13, 306041855),
    (1023, 79, 13, 200180735),  # mu = 3: raw 2 347 664 383 wraps modulo 2^31
])
def test_c_init_table(n_id, n_s, l, expected):
    # values of standards-and-limits.md 1a, table "Self-computed c_init values"
    assert prs_c_init(n_id, n_s, l) == expected == c_init_reference(n_id, n_s, l)


def test_c_init_formula_over_grid():
    rng = np.random.default_rng(1)
    for n_id, n_s, l in zip(rng.integers(0, 4096, 50), rng.integers(0, 160, 50), rng.integers(0, 14, 50)):
        assert prs_c_init(int(n_id), int(n_s), int(l)) == c_init_reference(int(n_id), int(n_s), int(l))


@pytest.mark.parametrize("n_id,n_s,l,signs", [
    (0, 0, 0, "++ -+ ++ --"), (0, 0, 11, "-- ++ -- -+"), (1, 0, 0, "++ -- ++ --"),
    (1023, 0, 0, "+- ++ +- +-"), (1024, 0, 0, "++ +- ++ +-"), (4095, 9, 13, "++ -- ++ -+"),
])
def test_prs_sequence_fixed_vectors(n_id, n_s, l, signs):
    # origin: the first 8 bits of the bit-serial reference above (``gold_reference``, 5.2.1 as
    # written) at prs_c_init(n_id, n_s, l), mapped by 5.1.3 QPSK (bit 0 -> +, 1 -> -); stored
    # so that a change in the vectorised Gold generator or the QPSK map shows up as a diff
    r = prs_sequence(n_id, n_s, l, 4)
    got = " ".join(("+" if z.real > 0 else "-") + ("+" if z.imag > 0 else "-") for z in r)
    assert got == signs
    np.testing.assert_allclose(np.abs(r), 1.0, atol=1e-15)


def test_prs_sequence_is_qpsk_of_gold_pairs():
    c = np.array(gold_reference(prs_c_init(7, 3, 5), 208))
    r = prs_sequence(7, 3, 5, 104)
    np.testing.assert_array_equal(r, ((1 - 2 * c[0::2]) + 1j * (1 - 2 * c[1::2])) / np.sqrt(2))


def test_k_prime_table_38211():
    # TS 38.211 Table 7.4.1.7.3-1, typed from standards-and-limits.md 1a
    assert k_prime(2, 12).tolist() == [0, 1] * 6
    assert k_prime(4, 12).tolist() == [0, 2, 1, 3] * 3
    assert k_prime(6, 12).tolist() == [0, 3, 1, 4, 2, 5] * 2
    assert k_prime(12, 12).tolist() == [0, 6, 3, 9, 1, 7, 4, 10, 2, 8, 5, 11]


@pytest.mark.parametrize("comb,num", [(2, 2), (2, 4), (2, 6), (2, 12), (4, 4), (4, 12), (6, 6),
                                      (6, 12), (12, 12)])
def test_every_allowed_pair_is_fully_staggered(comb, num):
    # each subcarrier of the band is hit exactly num/comb times per slot (the staggering goal)
    k = prs_subcarriers(comb, num, 1, 624)
    assert k.shape == (num, 624 // comb)
    counts = np.bincount(k.ravel(), minlength=624)
    assert np.all(counts == num // comb)
    # the formula k = m K_comb + ((k_offset + k') mod K_comb)
    kp = k_prime(comb, num)
    np.testing.assert_array_equal(k % comb, ((1 + kp) % comb)[:, None] * np.ones((1, 624 // comb)))


@pytest.mark.parametrize("comb,num", [(4, 2), (4, 6), (6, 2), (6, 4), (12, 6), (3, 12), (6, 8)])
def test_disallowed_comb_symbol_pairs(comb, num):
    with pytest.raises(ValueError):
        check_comb(comb, num)


def test_bad_arguments_name_the_argument():
    with pytest.raises(ValueError, match="c_init"):
        gold_sequence(2**31, 4)
    with pytest.raises(ValueError, match="n_id_seq"):
        prs_c_init(4096, 0, 0)
    with pytest.raises(TypeError, match="slot"):
        prs_c_init(0, 1.5, 0)
