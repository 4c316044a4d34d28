"""5G NR LDPC BG2: table data, encoding + rate matching against an independent implementation,
round trip, and the AWGN waterfall against the normal approximation."""

import json
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.phy.security.coding_bounds import bi_awgn_mu_at_capacity, normal_approximation_bler
from veriloc_rt.phy.security.ldpc import DECODE_MIN_INFORMATION, NRLDPC, base_graph_2, lifted_h, llr_information

DATA = Path(__file__).parent / "data"

# Rows typed from a second, independent transcription of TS 38.212 Table 5.3.2-3
# (daniestevez/ldpc-toolbox src/codes/nr5g.rs, V18.6.0): (row, col) -> V_ij for iLS 0..7
INDEPENDENT_ROWS = {
    (8, 0): (142, 118, 0, 147, 70, 53, 101, 176), (8, 1): (94, 70, 65, 43, 69, 31, 177, 169),
    (8, 12): (230, 152, 87, 152, 88, 161, 22, 225), (22, 2): (63, 52, 4, 1, 132, 163, 126, 44),
    (33, 10): (235, 124, 13, 109, 2, 29, 179, 106), (41, 1): (129, 147, 0, 120, 48, 132, 191, 53),
    (41, 5): (229, 7, 2, 101, 47, 6, 197, 215), (41, 11): (118, 60, 55, 81, 19, 8, 167, 230),
    (20, 4): (105, 61, 148, 20, 103, 52, 35, 227), (36, 2): (38, 151, 63, 175, 129, 154, 167, 112),
}


def test_base_graph_2_table():
    bg = base_graph_2()
    assert bg.shape == (197, 10)
    assert bg[:, 0].max() == 41 and bg[:, 1].max() == 51
    table = {(int(r[0]), int(r[1])): tuple(int(v) for v in r[2:]) for r in bg}
    for key, vals in INDEPENDENT_ROWS.items():
        assert table[key] == vals
    # structure of BG2 (38.212 5.3.2): each extension row i >= 4 has its own degree-1 parity column 10 + i
    for i in range(4, 42):
        assert table[(i, 10 + i)] == (0,) * 8
        assert sum(1 for (r, c) in table if c == 10 + i) == 1


@pytest.mark.parametrize("vec", json.loads((DATA / "ldpc_bg2_ratematch_vectors.json").read_text())["vectors"])
def test_encode_and_rate_match_against_py3gpp(vec):
    # vectors generated once with py3gpp (MATLAB nrLDPCEncode/nrRateMatchLDPC port); see the JSON
    code = NRLDPC(vec["k"], vec["e"])
    info = np.unpackbits(np.frombuffer(bytes.fromhex(vec["info_hex"]), dtype=np.uint8))[:vec["k"]]
    out = np.unpackbits(np.frombuffer(bytes.fromhex(vec["out_hex"]), dtype=np.uint8))[:vec["e"]]
    np.testing.assert_array_equal(code.encode(info), out)


@pytest.mark.parametrize("k", [256, 512])
def test_codewords_satisfy_h_and_round_trip(k):
    code = NRLDPC(k)
    assert code.rate == 0.5 and code.e == 2 * k
    rng = np.random.default_rng(k)
    bits = rng.integers(0, 2, (5, k), dtype=np.uint8)
    cw = code.codeword(bits)
    assert not np.any((code.h @ cw.T.astype(np.int64)) % 2)
    f = code.encode(bits)
    llr = 8.0 * (1 - 2.0 * f)
    dec, ok = code.decode(llr)
    np.testing.assert_array_equal(dec, bits)
    assert ok.all()


def test_lifted_h_blocks_are_shifted_identities():
    h = lifted_h(32, 4, 14).toarray()
    v = 117 % 32  # BG2 entry (0, 1), iLS 0
    block = h[0:32, 32:64]
    np.testing.assert_array_equal(block, np.roll(np.eye(32, dtype=np.uint8), v, axis=1))


def normal_approximation(ebn0_db: float, n: int, k: int) -> float:
    """:func:`normal_approximation_bler` at Eb/N0 ``ebn0_db`` (rate k/n, BPSK: LLR mean 2 / sigma^2)."""
    s2 = 1 / (2 * (k / n) * 10 ** (ebn0_db / 10))
    return normal_approximation_bler(2 / s2, n, k)


def bler(code: NRLDPC, ebn0_db: float, trials: int, rng) -> float:
    bits = rng.integers(0, 2, (trials, code.k), dtype=np.uint8)
    x = 1 - 2.0 * code.encode(bits)
    s2 = 1 / (2 * code.rate * 10 ** (ebn0_db / 10))
    y = x + np.sqrt(s2) * rng.standard_normal(x.shape)
    dec, _ = code.decode(2 * y / s2)
    return float(np.mean(np.any(dec != bits, axis=1)))


def test_awgn_waterfall_k256_rate_half():
    """Reference: the normal approximation (NA) of the best n = 512, k = 256 code on BI-AWGN gives
    BLER 0.56 at 0 dB, 0.18 at 0.5 dB, 2e-2 at 1 dB. Practical 5G LDPC codes with 25-iteration BP
    sit about 1 dB from the NA at this length (Coskun et al., Phys. Commun. 2019, Fig. 3; Richardson &
    Kudekar, IEEE Commun. Mag. 2018). Checks: no better than the NA at 0 dB (minus 3 sigma of 200
    trials), a waterfall at 1.5 dB, and BLER <= 0.05 at 2.5 dB (NA + 1.5 dB margin)."""
    code = NRLDPC(256, iterations=25)
    rng = np.random.default_rng(2024)
    trials = 200
    sigma = np.sqrt(0.25 / trials)  # largest binomial standard error of a BLER estimate
    assert normal_approximation(0.0, 512, 256) == pytest.approx(0.558, abs=0.01)
    b0 = bler(code, 0.0, trials, rng)
    b15 = bler(code, 1.5, trials, rng)
    b25 = bler(code, 2.5, trials, rng)
    assert b0 >= normal_approximation(0.0, 512, 256) - 3 * sigma
    assert 0.02 <= b15 <= 0.4
    assert b25 <= 0.05


@pytest.mark.parametrize("capacity", [0.25, 0.5, 0.8])
def test_llr_information_is_the_bi_awgn_capacity(capacity):
    """The LLR-only estimate on consistent Gaussian LLRs is the channel's capacity (integrated
    numerically, ``coding_bounds``). Tolerance 0.01: four standard errors of a mean over 20000
    bits, whose per-bit information lies in [0, 1] (standard deviation <= 0.5)."""
    mu = bi_awgn_mu_at_capacity(capacity)
    rng = np.random.default_rng(7)
    sign = 1 - 2.0 * rng.integers(0, 2, 20000)
    llr = sign * rng.normal(mu, np.sqrt(2 * mu), 20000)
    assert llr_information(llr) == pytest.approx(capacity, abs=0.01)


def test_decode_gate_leaves_every_outcome_as_full_belief_propagation():
    """Words below the gate (DECODE_MIN_INFORMATION x the rate, 0.4 bits per sent bit) are not
    decoded. At a channel capacity of 0.4 the normal approximation of the best n = 512, k = 256
    code succeeds with probability 5e-3 (the DS tag's 1024, 512 code 7e-5); BP on the NR code,
    about 1 dB worse, fails (here 0 of 60 words), so gated or not every word fails. Well above
    the gate (capacity 0.8) no word is gated and the decoded bits are the ungated decoder's."""
    gated, full = NRLDPC(256), NRLDPC(256, min_information=0.0)
    assert gated.min_information == DECODE_MIN_INFORMATION == 0.8
    k = 256
    mu_gate = bi_awgn_mu_at_capacity(0.4)
    assert 1 - normal_approximation_bler(mu_gate, 512, k) == pytest.approx(4.9e-3, rel=0.05)
    assert 1 - normal_approximation_bler(mu_gate, 1024, 512) == pytest.approx(6.9e-5, rel=0.05)
    rng = np.random.default_rng(11)
    for capacity, words in ((0.4, 60), (0.8, 20)):
        mu = bi_awgn_mu_at_capacity(capacity)
        bits = rng.integers(0, 2, (words, k), dtype=np.uint8)
        sign = 1 - 2.0 * gated.encode(bits)
        llr = sign * rng.normal(mu, np.sqrt(2 * mu), sign.shape)
        below = llr_information(llr) * gated.e < 0.8 * k
        dec_g, ok_g = gated.decode(llr)
        dec_f, ok_f = full.decode(llr)
        right_f = np.all(dec_f == bits, axis=1)
        if capacity == 0.4:
            assert 0.2 < below.mean() < 0.8        # the gate splits the words about their mean
            assert not right_f.any() and not ok_f.any() and not ok_g.any()
            assert not np.all(dec_g == bits, axis=1).any()
            # gated words are the hard decisions
            np.testing.assert_array_equal(dec_g[below], (gated_llr_total(gated, llr[below]) < 0)[:, :k])
        else:
            assert not below.any()
            assert right_f.all()
            np.testing.assert_array_equal(dec_g, dec_f)
            np.testing.assert_array_equal(ok_g, ok_f)


def gated_llr_total(code: NRLDPC, llr: np.ndarray) -> np.ndarray:
    """The codeword-position LLRs the decoder starts from (sent bits summed onto their
    positions, fillers known 0), for the hard decisions of an undecoded word."""
    total = np.zeros((llr.shape[0], code.n))
    for i, row in enumerate(llr):
        np.add.at(total[i], code.positions, row)
    total[:, code.k:code.k_full] = 40.0
    return total


@pytest.mark.parametrize("k,method", [(256, "sum_product"), (512, "sum_product"), (256, "min_sum")])
def test_words_already_codewords_skip_belief_propagation_with_its_output(k, method, monkeypatch):
    """A word whose hard decisions on the sent bits are a codeword's (and whose sent bits' LLRs
    are not near 0) is not handed to belief propagation: its bits and ``ok`` must be what the
    ``ldpc`` package returns for it (the punctured bits recovered). The reference here runs the
    package on every word (its BpDecoder, received-vector input, error probabilities
    1 / (1 + e^|L|)), from the LLR totals derived independently (:func:`gated_llr_total`).
    Exact equality: the skip claims the package's own output. Consistent Gaussian LLRs of mean
    mu from 2 (nearly no word clean) to 64 (nearly all: bit error rate Q(sqrt(mu / 2))), and
    clean words with a few sent LLRs pulled to 1e-4 (left
    to BP); the package's calls are counted to see both branches taken."""
    code = NRLDPC(k, method=method, min_information=0.0)
    rng = np.random.default_rng(5)
    llrs = []
    for mu in (2.0, 4.0, 8.0, 16.0, 32.0, 64.0):
        sign = 1 - 2.0 * code.encode(rng.integers(0, 2, (40, k), dtype=np.uint8))
        llrs.append(sign * rng.normal(mu, np.sqrt(2 * mu), sign.shape))
    weak = np.abs(llrs[-1][:10]).copy()
    weak[:, rng.integers(0, code.e, 3)] = 1e-4
    llrs.append(np.sign(llrs[-1][:10]) * weak)
    llr = np.concatenate(llrs)
    calls = []
    import ldpc

    real_class = ldpc.BpDecoder

    class Counting:
        """The package's decoder, its decode calls counted (the code builds it on first use)."""

        def __init__(self, *args, **kwargs):
            self.real = real_class(*args, **kwargs)

        def __getattr__(self, name):
            return getattr(self.real, name)

        def decode(self, v):
            calls.append(1)
            return self.real.decode(v)

    monkeypatch.setattr(ldpc, "BpDecoder", Counting)
    dec, ok = code.decode(llr)
    total = np.clip(gated_llr_total(code, llr), -40.0, 40.0)
    hard = (total < 0).astype(np.uint8)
    ref = real_class(code.h, error_channel=np.full(code.n, 0.1), max_iter=25,
                    bp_method="product_sum" if method == "sum_product" else "minimum_sum",
                    ms_scaling_factor=0.75 if method == "min_sum" else 1.0,
                    schedule="parallel", input_vector_type="received_vector")
    sent = np.zeros(code.n, dtype=bool)
    sent[code.positions] = True
    sent[code.k:code.k_full] = True
    clean = np.zeros(llr.shape[0], dtype=bool)
    for i in range(llr.shape[0]):
        ref.update_channel_probs(1.0 / (1.0 + np.exp(np.abs(total[i]))))
        cw = np.asarray(ref.decode(hard[i]), dtype=np.uint8)
        np.testing.assert_array_equal(dec[i], cw[:k])
        assert ok[i] == bool(ref.converge)
        clean[i] = ref.converge and np.array_equal(cw[sent], hard[i, sent])
    # both branches taken: every clean word but the 10 weakened ones skipped, the rest decoded
    assert 60 <= clean.sum() <= llr.shape[0] - 60
    assert clean[-10:].all()
    assert len(calls) == llr.shape[0] - clean.sum() + 10
