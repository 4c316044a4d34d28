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
    ({"topology": {"num_trps": 31}}, "topology.num_trps"),    # 11 groups of 3 > 10 slots
    ({"topology": {"num_trps": 9}, "nr": {"slots_per_frame": 2}}, "topology.num_trps"),
    ({"topology": {"num_trps": 9}, "receiver": {"tag_slots": [2]}}, "receiver.tag_slots[0]"),
    ({"topology": {"num_trps": 6}, "nr": {"comb_offsets": [0, 1, 2, 0, 0, 1],
                                          "prs_ids": [0, 1, 2, 3, 4, 5]}}, "nr.comb_offsets"),
    ({"nr": {"comb_offsets": [0, 3, 1]}}, "nr.comb_offsets"),   # offset 3 is BS 0's tag
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


def test_slot_groups_beyond_one_slot():
    """comb 6 with tags holds 3 TRPs per slot: 9 TRPs are 3 slot groups with the first group's
    offsets; T_rep = 2, the largest TS 38.214 repetition factor with 3 x T_rep <= 10 slots."""
    cfg = config_from_dict({"topology": {"num_trps": 9}})
    assert cfg.nr.comb_offsets == (0, 1, 2) * 3
    assert cfg.nr.prs_ids == tuple(range(9))
    assert cfg.nr.slot_plan(True) == ((0, 0, 0, 1, 1, 1, 2, 2, 2), 2)
    # without tags one slot holds 6: two groups, T_rep = 4 (2 x 6 > 10)
    nr = config_from_dict({"topology": {"num_trps": 9},
                           "security": {"tag_scheme": "none"}}).nr
    assert nr.comb_offsets == (0, 1, 2, 3, 4, 5, 0, 1, 2)
    assert nr.slot_plan(False) == ((0,) * 6 + (1,) * 3, 4)
    # the paper's three: one group in every slot
    assert config_from_dict({}).nr.slot_plan(True) == ((0, 0, 0), 10)


def test_input_error_survives_a_worker_process():
    """An InputError raised in a worker crosses back to the pool (pickled) intact."""
    import pickle

    e = pickle.loads(pickle.dumps(InputError("topology.num_trps", "too many")))
    assert (type(e), e.field, e.problem) == (InputError, "topology.num_trps", "too many")
