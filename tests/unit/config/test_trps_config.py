"""topology.num_trps: per-TRP tuples completed (TS 38.211 7.4.1.7.2 ids, 7.4.1.7.3 comb
offsets), errors naming the field."""

import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.errors import InputError


def test_three_trps_keep_the_paper_tuples():
    cfg = config_from_dict({})
    assert cfg.topology.num_trps == 3
    assert cfg.nr.comb_offsets == (0, 1, 2) and cfg.nr.prs_ids == (0, 1, 2)
    assert cfg.security.encrypted == (False,) * 3


def test_derived_offsets_without_tags_fill_the_comb():
    cfg = config_from_dict({"topology": {"num_trps": 12},
                            "nr": {"comb": 12, "comb_offsets": [3, 0], "prs_ids": [0, 1]},
                            "security": {"tag_scheme": "none", "encrypted": [True]}})
    assert cfg.nr.comb_offsets == (3, 0, 1, 2, 4, 5, 6, 7, 8, 9, 10, 11)
    assert cfg.nr.prs_ids == (0, 1) + tuple(range(2, 12))
    assert cfg.security.encrypted == (True,) * 12


def test_derived_offsets_with_tags_leave_the_tag_offsets_free():
    # comb 12 with tags: TRP i's tag sits at k_offset + 6; offsets 0, 1, 2 (tags 6, 7, 8)
    # leave 3, 4, 5 (tags 9, 10, 11)
    cfg = config_from_dict({"topology": {"num_trps": 6}, "nr": {"comb": 12}})
    assert cfg.nr.comb_offsets == (0, 1, 2, 3, 4, 5)
    owners = [o for o in cfg.nr.comb_offsets] + [(o + 6) % 12 for o in cfg.nr.comb_offsets]
    assert sorted(owners) == list(range(12))


def test_prs_ids_skip_listed_ids():
    cfg = config_from_dict({"topology": {"num_trps": 5}, "nr": {"comb": 12, "prs_ids": [4095, 0, 1],
                                                                  "comb_offsets": [0, 1, 2]}})
    assert cfg.nr.prs_ids == (4095, 0, 1, 2, 3)


@pytest.mark.parametrize("data, field", [
    ({"topology": {"num_trps": 4}}, "topology.num_trps"),          # comb 6 + tags holds 3
    ({"topology": {"num_trps": 2}}, "topology.num_trps"),
    ({"topology": {"num_trps": 6, "selection": "cell"}}, "topology.selection"),
    ({"topology": {"num_trps": 3}, "nr": {"comb_offsets": [0, 1, 2, 3], "prs_ids": [0, 1, 2, 3],
                                          "comb": 12}}, "nr.comb_offsets"),
    ({"topology": {"num_trps": 6}, "nr": {"comb": 12},
      "threats": {"fbs": {"spoofed_slots": [6]}}}, "threats.fbs.spoofed_slots[0]"),
])
def test_errors_name_the_field(data, field):
    with pytest.raises(InputError) as e:
        config_from_dict(data)
    assert e.value.field == field


def test_spoofed_slot_beyond_three():
    cfg = config_from_dict({"topology": {"num_trps": 6}, "nr": {"comb": 12},
                            "threats": {"fbs": {"spoofed_slots": [5]}}})
    assert cfg.threats.fbs.spoofed_slots == (5,)
