"""veriloc_rt.phy.security.ldpc_kernels (through NRLDPC.prepare) against the NumPy code it
replaced (NRLDPC.prepare_reference): the same bits, exactly (the kernel claims the same IEEE
additions in the same order and integer parity arithmetic)."""

import numpy as np
import pytest

from veriloc_rt.phy.security.ldpc import NRLDPC


def words(code: NRLDPC, rng: np.random.Generator) -> np.ndarray:
    """Received words from noise to clean codewords, with the awkward values: NaN, +-inf, LLRs
    beyond the clip, exact zeros and -0.0, near-threshold magnitudes, whole sent bits' copies of
    opposite signs."""
    out = []
    for mu in (0.5, 2.0, 8.0, 16.0, 64.0, 400.0):
        sign = 1 - 2.0 * code.encode(rng.integers(0, 2, (30, code.k), dtype=np.uint8))
        out.append(sign * rng.normal(mu, np.sqrt(2 * mu), sign.shape))
    odd = out[-2][:20].copy()
    for row in odd:
        j = rng.integers(0, code.e, 6)
        row[j[0]], row[j[1]], row[j[2]] = np.nan, np.inf, -np.inf
        row[j[3]], row[j[4]], row[j[5]] = 0.0, -0.0, 1e-300
    big = np.sign(out[-1][:10]) * rng.uniform(1e307, 1.7e308, (10, code.e))  # sums overflow to inf
    return np.concatenate(out + [odd, big])


@pytest.mark.parametrize("k,e,method", [(256, None, "sum_product"), (512, None, "sum_product"),
                                         (256, None, "min_sum"), (40, 1000, "sum_product"),
                                         (256, 4000, "sum_product")])
def test_prepare_is_the_numpy_reference_bit_for_bit(k, e, method):
    """The tags' rate-1/2 codes send each codeword bit once; the low-rate codes (e beyond the
    circular buffer) send bits two to three times, so the order of the copies' sums is tested."""
    code = NRLDPC(k, e, method=method)
    if e is not None:
        assert np.bincount(code.positions).max() >= 2
    flat = words(code, np.random.default_rng(3))
    total, hard, clean, cw = code.prepare(flat)
    t_ref, h_ref, c_ref, cw_ref = code.prepare_reference(flat)
    # exact: the same float64 values bit for bit (NaN-free here: nan_to_num first), and -0.0 kept
    np.testing.assert_array_equal(total.view(np.int64), t_ref.view(np.int64))
    np.testing.assert_array_equal(hard, h_ref)
    np.testing.assert_array_equal(clean, c_ref)
    np.testing.assert_array_equal(cw[clean], cw_ref[clean])   # the codeword is meaningful where clean
    # both outcomes present, so the comparison covers the skip's two branches
    assert 20 <= clean.sum() <= flat.shape[0] - 20


def test_decode_unchanged_on_words_of_every_kind():
    """decode (now on the kernel) gives what decode on the reference gives: the decoded bits and
    ok of every word, including BP's words."""
    code = NRLDPC(256)
    flat = words(code, np.random.default_rng(4))
    bits, ok = code.decode(flat)

    class Reference(NRLDPC):
        def prepare(self, f):
            return self.prepare_reference(f)

    bits_r, ok_r = Reference(256).decode(flat)
    np.testing.assert_array_equal(bits, bits_r)
    np.testing.assert_array_equal(ok, ok_r)
