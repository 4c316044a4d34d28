"""Key files: generate/load round trip and one-line errors naming the file."""

import numpy as np
import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ec

from veriloc_rt.errors import InputError
from veriloc_rt.phy.security.keys import generate_keys, key_paths, load_keys


def test_generate_and_load_round_trip(tmp_path):
    files = generate_keys(tmp_path, [1, 2], rng=np.random.default_rng(0))
    assert len(files) == 8
    keys = load_keys(tmp_path, [1, 2])
    assert len(keys[1].aes_key) == 16 and len(keys[2].hmac_key) == 32
    sig = keys[1].sign_key.sign(b"m")
    keys[1].verify_key.verify(sig, b"m")
    ue = load_keys(tmp_path, [1, 2], private=False)
    assert ue[1].sign_key is None and ue[1].hmac_key == keys[1].hmac_key
    # same generator seed, same keys; OS randomness differs
    other = tmp_path / "b"
    generate_keys(other, [1], rng=np.random.default_rng(0))
    assert load_keys(other, [1])[1].aes_key == keys[1].aes_key
    with pytest.raises(InputError, match="exists"):
        generate_keys(tmp_path, [1])


def test_missing_file_names_it(tmp_path):
    generate_keys(tmp_path, [1])
    key_paths(tmp_path, 1)["hmac"].unlink()
    with pytest.raises(InputError) as exc:
        load_keys(tmp_path, [1])
    assert exc.value.field.endswith("bs1.tag.hmac") and "missing" in exc.value.problem
    with pytest.raises(InputError, match="does not exist"):
        load_keys(tmp_path / "nope", [1])


@pytest.mark.parametrize("name,content,problem", [
    ("aes", "zz-not-hex\n", "malformed"),
    ("aes", "00" * 20 + "\n", "wrong key size"),
    ("sign", "-----BEGIN PRIVATE KEY-----\ngarbage\n-----END PRIVATE KEY-----\n", "malformed"),
    ("verify", "hello", "malformed"),
])
def test_malformed_files(tmp_path, name, content, problem):
    generate_keys(tmp_path, [4])
    path = key_paths(tmp_path, 4)[name]
    path.write_text(content)
    with pytest.raises(InputError) as exc:
        load_keys(tmp_path, [4])
    assert exc.value.field == str(path) and problem in exc.value.problem
    assert "\n" not in str(exc.value)


def test_wrong_key_type(tmp_path):
    generate_keys(tmp_path, [5])
    ecdsa = ec.generate_private_key(ec.SECP256R1())
    path = key_paths(tmp_path, 5)["sign"]
    path.write_bytes(ecdsa.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                         serialization.NoEncryption()))
    with pytest.raises(InputError, match="Ed25519 private key") as exc:
        load_keys(tmp_path, [5])
    assert exc.value.field == str(path)


def test_key_files_created_0600_all_or_none(tmp_path, monkeypatch):
    # regression (issue 19): files were written 0644 and chmodded afterwards, one by one
    import os
    import stat

    out = tmp_path / "k"
    generate_keys(out, [0, 1])
    assert stat.S_IMODE(out.stat().st_mode) == 0o700        # issue 37: it was 0755
    for b in (0, 1):
        p = key_paths(out, b)
        for name in ("aes", "hmac", "sign", "verify"):
            assert stat.S_IMODE(p[name].stat().st_mode) == 0o600
    # an existing file of a later BS: nothing of the earlier ones is written
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    key_paths(fresh, 2)["hmac"].write_text("x")
    with pytest.raises(InputError, match="exists"):
        generate_keys(fresh, [1, 2])
    assert sorted(f.name for f in fresh.iterdir()) == ["bs2.tag.hmac"]
    # a write failing half-way leaves no key file and no temporary file
    calls = []
    real_fsync = os.fsync

    def failing_fsync(fd):
        calls.append(fd)
        if len(calls) == 5:
            raise OSError(28, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", failing_fsync)
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(InputError, match="No space left"):
        generate_keys(tmp_path / "full", [0, 1])
    assert not (tmp_path / "full").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == before     # no staging folder left


def test_bskeys_repr_shows_no_secret(tmp_path):
    generate_keys(tmp_path, [3])
    keys = load_keys(tmp_path, [3])[3]
    text = repr(keys) + str(keys)
    assert keys.aes_key.hex() not in text and repr(keys.aes_key) not in text
    assert keys.hmac_key.hex() not in text and repr(keys.hmac_key) not in text
    assert "Ed25519PrivateKey" not in text and "bs_id=3" in text


def test_legacy_bare_hex_key_files_still_load(tmp_path):
    generate_keys(tmp_path, [0], aes_bits=256)
    p = key_paths(tmp_path, 0)
    key = load_keys(tmp_path, [0])[0]
    p["aes"].write_text(key.aes_key.hex() + "\n")
    p["hmac"].write_text(key.hmac_key.hex() + "\n")
    again = load_keys(tmp_path, [0], aes_bits=256)[0]
    assert again.aes_key == key.aes_key and again.hmac_key == key.hmac_key
    with pytest.raises(InputError, match="aes_key_bits is 128"):
        load_keys(tmp_path, [0], aes_bits=128)

