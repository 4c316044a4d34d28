"""AES-CTR PRS encryption: NIST vectors, counter-block uniqueness, the paper's three properties."""

import itertools

import numpy as np
import pytest

from veriloc_rt.phy.nr.prs import prs_sequence
from veriloc_rt.phy.security.encryption import (BLOCK_COUNTER_BITS, aes_ctr_keystream,
                                                counter_block, encrypted_prs_bits,
                                                encrypted_prs_sequence, keystream_bits)
from veriloc_rt.phy.nr.prs import prs_bits

# NIST SP 800-38A F.5.1 / F.5.5 (CTR-AES128 / CTR-AES256 encrypt)
NIST_CTR = "f0f1f2f3f4f5f6f7f8f9fafbfcfdfeff"
NIST_PT = ("6bc1bee22e409f96e93d7e117393172a" "ae2d8a571e03ac9c9eb76fac45af8e51"
           "30c81c46a35ce411e5fbc1191a0a52ef" "f69f2445df4f9b17ad2b417be66c3710")
NIST = {
    "2b7e151628aed2a6abf7158809cf4f3c":
        "874d6191b620e3261bef6864990db6ce" "9806f66b7970fdff8617187bb9fffdff"
        "5ae4df3edbd5d35e5b4f09020db03eab" "1e031dda2fbe03d1792170a0f3009cee",
    "603deb1015ca71be2b73aef0857d77811f352c073b6108d72d9810a30914dff4":
        "601ec313775789a5b7a7f504bbf3d228" "f443e3ca4d62b59aca84e990cacaf5c5"
        "2b0930daa23de94ce87017ba2d84988d" "dfc9c58db67aada613c2dd08457941a6",
}


@pytest.mark.parametrize("key,ct", NIST.items())
def test_nist_sp800_38a_ctr(key, ct):
    ks = aes_ctr_keystream(bytes.fromhex(key), bytes.fromhex(NIST_CTR), 64)
    assert bytes(a ^ b for a, b in zip(ks, bytes.fromhex(NIST_PT))).hex() == ct


def test_rfc3686_vector_2():
    # counter block = nonce || IV || 00000001
    block = bytes.fromhex("006CB6DB" "C0543B59DA48D90B" "00000001")
    ks = aes_ctr_keystream(bytes.fromhex("7E24067817FAE0D743D6CE1F32539163"), block, 32)
    ct = bytes(a ^ b for a, b in zip(ks, bytes(range(32))))
    assert ct.hex().upper() == "5104A106168A72D9790D41EE8EDAD388EB2E1EFC46DA57C8FCE630DF9141BE28"


def test_counter_blocks_never_repeat_across_bs_frame_slot_symbol():
    """Every 128-bit counter block used by every (BS, frame, slot, symbol) keystream is distinct.
    Checked exhaustively over 3 BSs x 3 frames (incl. a 32-bit wrap neighbour) x 20 slots x 14 symbols,
    with the longest per-symbol keystream the grid allows (272 PRB, comb 2: 3264 bits = 26 blocks)."""
    blocks_per_symbol = -(-2 * 272 * 12 // 2 // 128)
    used = set()
    count = 0
    for bs, frame, slot, sym in itertools.product((0, 1, 2**24 - 1), (0, 1, 2**32 - 1), range(20), range(14)):
        first = int.from_bytes(counter_block(bs, frame, slot, sym), "big")
        for i in range(blocks_per_symbol):
            used.add((first + i) % 2**128)  # CTR increments the full 128-bit block
            count += 1
    assert len(used) == count
    assert blocks_per_symbol < 2**BLOCK_COUNTER_BITS


def test_keystreams_differ_and_match_the_cipher():
    key = bytes(range(16))
    a = keystream_bits(key, 1, 5, 3, 2, 208)
    assert not np.array_equal(a, keystream_bits(key, 2, 5, 3, 2, 208))
    assert not np.array_equal(a, keystream_bits(key, 1, 6, 3, 2, 208))
    assert not np.array_equal(a, keystream_bits(key, 1, 5, 4, 2, 208))
    assert not np.array_equal(a, keystream_bits(key, 1, 5, 3, 3, 208))
    raw = aes_ctr_keystream(key, counter_block(1, 5, 3, 2), 26)
    np.testing.assert_array_equal(a, np.unpackbits(np.frombuffer(raw, np.uint8))[:208])
    np.testing.assert_array_equal(encrypted_prs_bits(key, 1, 9, 5, 3, 2, 104), prs_bits(9, 3, 2, 104) ^ a)


@pytest.mark.parametrize("field,args", [("bs_id", (2**24, 0, 0, 0)), ("frame", (0, 2**32, 0, 0)),
                                        ("slot", (0, 0, 2**16, 0)), ("symbol", (0, 0, 0, 256))])
def test_counter_fields_reject_overflow(field, args):
    with pytest.raises(ValueError, match=field):
        counter_block(*args)


# --- the paper's three properties of encrypted PRS (section IV.A), tested statistically ---------
#: trials per estimate; the mean of |R|^2 / N over T trials has relative standard error 1/sqrt(T)
TRIALS = 300
#: 5 standard errors: a false failure has probability < 1e-6 per check
Z = 5.0


def _enc(key, frame, n, slot=0, symbol=0):
    return encrypted_prs_sequence(key, 1, 3, frame, slot, symbol, n)


@pytest.mark.parametrize("n", [104, 1248])
def test_property_i_cross_correlation_with_standard_prs(n):
    key = bytes.fromhex("2b7e151628aed2a6abf7158809cf4f3c")
    s_prs = prs_sequence(3, 0, 0, n)
    r = np.array([np.vdot(s_prs, _enc(key, f, n)) for f in range(TRIALS)])
    # E[R] = 0: each of Re, Im has variance N/2, so the mean has std sqrt(N / (2 T))
    assert abs(r.real.mean()) < Z * np.sqrt(n / 2 / TRIALS)
    assert abs(r.imag.mean()) < Z * np.sqrt(n / 2 / TRIALS)
    # Var(R) = N sigma_s^4 = N (unit-energy QPSK): |R|^2 / N averages to 1
    assert abs(np.mean(np.abs(r) ** 2) / n - 1) < Z / np.sqrt(TRIALS)


def test_property_ii_autocorrelation_peak_n_squared_and_flat_sidelobes():
    key = bytes(16)
    n = 1248
    s = _enc(key, 42, n)
    spectrum = np.fft.fft(s)
    acf = np.fft.ifft(np.abs(spectrum) ** 2)  # periodic autocorrelation, all lags
    assert abs(acf[0]) ** 2 == pytest.approx(n**2, rel=1e-12)
    side = np.abs(acf[1:]) ** 2
    assert abs(side.mean() / n - 1) < Z / np.sqrt(n - 1) * 1.5  # |R(tau)|^2 ~ N Exp(1), weakly dependent
    assert side.max() < n**2 / 50  # peak-to-sidelobe > 17 dB (max of 1247 Exp(1) ~ 7 N, here < 31 N)


def test_property_iii_two_keys_uncorrelated():
    k1, k2 = bytes(16), bytes([1]) + bytes(15)
    n = 1248
    r = np.array([np.vdot(_enc(k1, f, n), _enc(k2, f, n)) for f in range(TRIALS)])
    assert abs(r.mean()) < Z * np.sqrt(n / TRIALS)
    assert abs(np.mean(np.abs(r) ** 2) / n - 1) < Z / np.sqrt(TRIALS)
    # the same key, another frame, is equally uncorrelated (no keystream reuse)
    assert abs(np.vdot(_enc(k1, 0, n), _enc(k1, 1, n))) < Z * np.sqrt(n)


def test_encrypted_bits_are_balanced():
    key = bytes(range(32))
    bits = np.concatenate([encrypted_prs_bits(key, 0, 0, f, 0, 0, 1000) for f in range(20)])
    assert abs(bits.mean() - 0.5) < Z * 0.5 / np.sqrt(bits.size)


def test_keystreams_of_a_frame_in_one_call_equal_the_per_symbol_ctr_streams():
    """keystream_bits_many (ECB over the counter blocks) against CTR mode symbol by symbol,
    including a stream of several blocks (5000 bits = 40 blocks)."""
    from veriloc_rt.phy.security.encryption import keystream_bits_many

    key = bytes(range(32))
    pairs = [(s, l) for s in (0, 7, 19) for l in (0, 5, 13)] + [(300, 255), (2**16 - 1, 1)]  # both slot bytes
    for n in (208, 5000):
        many = keystream_bits_many(key, 4095, 2**32 - 1, pairs, n)
        assert many.shape == (len(pairs), n)
        for row, (s, l) in zip(many, pairs):
            np.testing.assert_array_equal(row, keystream_bits(key, 4095, 2**32 - 1, s, l, n))


@pytest.mark.parametrize("pair, err", [((2**16, 0), ValueError), ((0, 256), ValueError), ((-1, 0), ValueError),
                                       ((1.0, 0), TypeError), ((0, True), TypeError)])
def test_keystreams_of_a_frame_reject_what_a_counter_block_rejects(pair, err):
    from veriloc_rt.phy.security.encryption import keystream_bits_many

    with pytest.raises(err):
        counter_block(1, 2, *pair)
    with pytest.raises(err):
        keystream_bits_many(bytes(16), 1, 2, [(0, 0), pair], 208)
