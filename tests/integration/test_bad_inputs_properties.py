"""Property-based: any config, trajectory CSV, PLY mesh or key file is used or refused cleanly.

The contract (issue #19): exit 0, or exit 2 with one line ``error: <field or file>: <problem>``
and no traceback, within a time limit. Configs are generated from the config's own JSON schema
(``veriloc-rt config schema``) and then mutated (values replaced by arbitrary JSON, keys dropped
or added, the text's bytes damaged); CSV, PLY and key files start from valid ones and have their
bytes damaged. The checks run through the validation entry points (``config show``/``config
check``, :func:`load_csv_trajectory`, :func:`read_ply`, :func:`load_keys`), never a trace.
Examples are derandomized (the ``ci`` profile in ``tests/conftest.py``).
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from veriloc_rt.cli import main
from veriloc_rt.config import (Config, SceneConfig, TrajectoryConfig, config_from_dict,
                               config_schema)
from veriloc_rt.errors import InputError
from veriloc_rt.phy.security.keys import generate_keys, key_paths, load_keys
from veriloc_rt.world.scene.canyon import urban_canyon
from veriloc_rt.world.scene.export import read_ply, write_ply
from veriloc_rt.world.trajectory import check_points, follower, load_csv_trajectory

from .schema_strategies import from_schema

#: per-example time limit, ms: validation of one input is milliseconds; the limit catches a
#: hang or a blow-up (a 2-core CI machine shared with other jobs, hence the slack)
DEADLINE_MS = 5000
#: the geometry-building checks (`config check`) build a small canyon, ~0.1-0.5 s
CHECK_DEADLINE_MS = 20000


# --- strategies --------------------------------------------------------------------------------

JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8)
    | st.sampled_from([2**63, -(2**63) - 1, 10**400, 1e308, -0.0, "", "\x00", "../" * 8]),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner,
                                                                max_size=3),
    max_leaves=6)


@st.composite
def mutated_config(draw, schema: dict) -> dict:
    """A schema-valid config with up to three mutations somewhere in its tree."""
    data = draw(from_schema(schema))
    for _ in range(draw(st.integers(0, 3))):
        node, sch = data, schema
        while True:  # walk down into a random nested section
            subs = [k for k, v in node.items() if isinstance(v, dict)]
            if not subs or draw(st.booleans()):
                break
            k = draw(st.sampled_from(sorted(subs)))
            # a dict that replaced a value has no schema of its own: mutate it freely
            node, sch = node[k], sch.get("properties", {}).get(k, {})
        op = draw(st.sampled_from(["replace", "drop", "unknown", "schema"]))
        keys = sorted(node)
        if op == "replace" and keys:
            node[draw(st.sampled_from(keys))] = draw(JSON)
        elif op == "drop" and keys:
            del node[draw(st.sampled_from(keys))]
        elif op == "unknown":
            node[draw(st.text(min_size=1, max_size=8))] = draw(JSON)
        elif sch.get("properties"):
            k = draw(st.sampled_from(sorted(sch["properties"])))
            node[k] = draw(from_schema(sch["properties"][k]))
    return data


#: tokens worth splicing into text files: separators, markers, numbers at the limits
TOKENS = [b",", b"\n", b"\r\n", b'"', b"\xef\xbb\xbf", b"\x00", b"nan", b"inf", b"-inf",
          b"1e308", b"1e400", b"-0", b"9" * 400, b"\xff", b"{", b"[", b"}", b"]", b"null",
          b" ", b"\t"]


@st.composite
def mutated_bytes(draw, base: bytes) -> bytes:
    """``base`` with one to four byte-level changes."""
    data = bytearray(base)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["flip", "insert", "token", "delete", "truncate", "repeat"]))
        pos = draw(st.integers(0, len(data)))
        if op == "flip" and data:
            data[min(pos, len(data) - 1)] ^= 1 << draw(st.integers(0, 7))
        elif op == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif op == "token":
            data[pos:pos] = draw(st.sampled_from(TOKENS))
        elif op == "delete":
            del data[pos:pos + draw(st.integers(1, 16))]
        elif op == "truncate":
            del data[pos:]
        elif op == "repeat":
            data[pos:pos] = data[pos:pos + draw(st.integers(1, 64))]
    return bytes(data)


# --- the contract ------------------------------------------------------------------------------

def run_cli(*args) -> tuple[int, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue()


def assert_contract(code: int, err: str) -> None:
    event(f"exit {code}")  # --hypothesis-show-statistics: how many were used, how many refused
    assert "Traceback" not in err, err
    assert code in (0, 2), err
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), err
        assert lines[0].split(": ", 2)[1], err  # a field or file is named


def assert_input_error(exc: InputError) -> None:
    event("refused")
    assert exc.field and "\n" not in str(exc) and len(str(exc)) < 20_000


SCHEMA = config_schema()


@settings(max_examples=400, deadline=DEADLINE_MS)
@given(mutated_config(SCHEMA))
def test_schema_configs_load_or_fail_cleanly(data):
    try:
        cfg = config_from_dict(data)
    except InputError as exc:
        assert_input_error(exc)
    else:
        event("used")
        assert isinstance(cfg, Config)


@settings(max_examples=120, deadline=DEADLINE_MS)
@given(st.data())
def test_config_files_show_or_fail_cleanly(data):
    cfg = data.draw(mutated_config(SCHEMA))
    text = json.dumps(cfg, allow_nan=True).encode()
    if data.draw(st.booleans()):
        text = data.draw(mutated_bytes(text))
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "c.json"
        f.write_bytes(text)
        assert_contract(*run_cli("config", "show", f))


#: the small canyon the geometry checks run on (as configs/ci-tiny.json)
TINY = {"seed": 3, "scene": {"extent_m": 140.0, "margin_m": 30.0},
        "trajectory": {"num_points": 12, "region_m": 70.0}}
#: sections whose generated values are laid over TINY for `config check`: everything but the
#: world (the geometry's cost grows with scene.extent_m and trajectory.num_points)
CHECK_SECTIONS = ("nr", "security", "receiver", "detectors", "threats", "run", "channel")


@settings(max_examples=25, deadline=CHECK_DEADLINE_MS)
@given(st.data())
def test_config_check_passes_or_fails_cleanly(data):
    cfg = dict(TINY)
    for name in data.draw(st.lists(st.sampled_from(CHECK_SECTIONS), max_size=3, unique=True)):
        cfg[name] = data.draw(mutated_config(SCHEMA["properties"][name]))
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "c.json"
        f.write_text(json.dumps(cfg))
        assert_contract(*run_cli("config", "check", f))


@lru_cache(maxsize=1)
def tiny_canyon():
    return urban_canyon(SceneConfig(extent_m=140.0, margin_m=30.0), np.random.default_rng(0))


STREET_CSV = b"t,x,y,z\n0,0,0,1.5\n1,0,5,1.5\n2,0,10,1.5\n3,0,15,1.5\n4,0,20,1.5\n5,0,25,1.5\n"


@settings(max_examples=200, deadline=DEADLINE_MS)
@given(mutated_bytes(STREET_CSV))
def test_trajectory_csv_loads_or_fails_cleanly(text):
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "t.csv"
        f.write_bytes(text)
        try:
            ue = load_csv_trajectory(f, TrajectoryConfig())
            check_points(tiny_canyon(), ue.pos, "trajectory", str(f))
            adv = follower(ue, 2, 5.0)
        except InputError as exc:
            assert_input_error(exc)
        else:
            event("used")
            assert np.all(np.isfinite(ue.pos)) and np.all(np.isfinite(adv.pos))
            assert np.all(np.diff(ue.t) > 0)


def _ply_bytes() -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "m.ply"
        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
        write_ply(p, v, np.array([[0, 1, 2], [0, 1, 3], [1, 2, 3]]))
        return p.read_bytes()


@settings(max_examples=200, deadline=DEADLINE_MS)
@given(mutated_bytes(_ply_bytes()))
def test_ply_reads_or_fails_cleanly(data):
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "m.ply"
        f.write_bytes(data)
        try:
            v, faces = read_ply(f)
        except InputError as exc:
            assert_input_error(exc)
        else:
            event("used")
            assert np.all(np.isfinite(v)) and len(faces) > 0
            assert faces.min() >= 0 and faces.max() < len(v)


@pytest.fixture(scope="module")
def key_template(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("keys")
    generate_keys(d, [0], rng=np.random.default_rng(1))
    return d


@settings(max_examples=120, deadline=DEADLINE_MS)
@given(name=st.sampled_from(["aes", "hmac", "sign", "verify"]), data=st.data())
def test_key_files_load_or_fail_cleanly(key_template, name, data):
    with tempfile.TemporaryDirectory() as tmp:
        keys = Path(tmp) / "k"
        shutil.copytree(key_template, keys)
        path = key_paths(keys, 0)[name]
        path.write_bytes(data.draw(mutated_bytes(path.read_bytes())))
        try:
            k = load_keys(keys, [0], aes_bits=128)[0]
        except InputError as exc:
            assert_input_error(exc)
        else:
            event("used")
            assert len(k.aes_key) == 16 and len(k.hmac_key) == 32
