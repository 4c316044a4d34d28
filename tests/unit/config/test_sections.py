"""Config sections: defaults are the paper's, bad values are InputErrors naming the field."""

import pytest

from veriloc_rt.config.fields import from_dict, json_schema
from veriloc_rt.errors import InputError
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig


def test_paper_defaults():
    nr, sec = NRConfig(), SecurityConfig()
    assert (nr.numerology, nr.num_prb, nr.comb, nr.num_symbols, nr.slots_per_frame) == (0, 52, 6, 12, 10)
    assert nr.num_bs == 3 and nr.resolved_sample_rate_hz == 15.36e6
    assert sec.ldpc_iterations == 25 and sec.tag_scheme in ("hmac", "ds")
    json_schema(NRConfig), json_schema(SecurityConfig)


@pytest.mark.parametrize("data,field", [
    ({"comb": 5}, "nr.comb"), ({"num_prb": 50}, "nr.num_prb"), ({"comb": 12, "num_symbols": 6}, "nr.num_symbols"),
    ({"start_symbol": 4}, "nr.start_symbol"), ({"comb_offsets": [0, 6, 1]}, "nr.comb_offsets[1]"),
    ({"prs_ids": [1, 2]}, "nr.prs_ids"), ({"slots_per_frame": 20}, "nr.slots_per_frame"),
    ({"bogus": 1}, "nr.bogus"),
])
def test_nr_errors(data, field):
    with pytest.raises(InputError) as exc:
        from_dict(NRConfig, data, "nr")
    assert exc.value.field == field


def test_security_errors():
    with pytest.raises(InputError, match="security.tag_scheme"):
        from_dict(SecurityConfig, {"tag_scheme": "rsa"}, "security")
    assert from_dict(SecurityConfig, {"encrypted": [True, False, True]}, "security").encrypted == (True, False, True)
