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
