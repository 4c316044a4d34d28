"""The run's first frame counter: key files must not see the same AES-CTR counter blocks twice."""

import dataclasses

from veriloc_rt.config import Config, TrajectoryConfig, config_from_dict
from veriloc_rt.config.fields import json_schema
from veriloc_rt.phy.security.encryption import counter_block
from veriloc_rt.sim.runner import FRAME_OFFSETS, frame_offset

#: the paper's trajectory length
PAPER_POINTS = 1200


def test_default_run_keeps_frame_zero():
    # simulated keys are drawn per seed: no key spans two seeds, and the default numbers stay
    assert frame_offset(Config()) == 0


def test_key_file_runs_use_disjoint_counter_blocks(tmp_path):
    base = config_from_dict({"security": {"keys_dir": str(tmp_path)}})
    offsets = [frame_offset(base.replace(seed=s)) for s in (1, 2, 3)]
    assert offsets[0] == frame_offset(base.replace(seed=1))  # reproducible
    assert len(set(offsets)) == 3
    blocks = [{counter_block(0, o + i, 0, 0) for i in range(PAPER_POINTS)} for o in offsets]
    assert not (blocks[0] & blocks[1]) and not (blocks[0] & blocks[2]) and not (blocks[1] & blocks[2])


def test_frame_counter_stays_within_32_bits():
    hi = json_schema(TrajectoryConfig)["properties"]["num_points"]["maximum"]
    # the largest offset plus the longest trajectory still fits the 32-bit frame field
    assert FRAME_OFFSETS - 1 + hi - 1 < 2**32
    cfg = dataclasses.replace(Config(), security=dataclasses.replace(Config().security,
                                                                      keys_dir="/k"))
    assert 0 <= frame_offset(cfg) < FRAME_OFFSETS
