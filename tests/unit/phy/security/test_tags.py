"""HMAC-SHA256 (RFC 4231) and Ed25519 (RFC 8032) vectors, message binding, constant-time check."""

import pytest
from cryptography.hazmat.primitives.asymmetric import ed25519

from veriloc_rt.phy.security.tags import (PRSParams, hmac_tag, sign, tag_message, verify_hmac,
                                          verify_signature)

RFC4231 = [
    ("0b" * 20, b"Hi There".hex(), "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7"),
    (b"Jefe".hex(), b"what do ya want for nothing?".hex(),
     "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"),
    ("aa" * 20, "dd" * 50, "773ea91e36800e46854db8ebd09181a72959098b3ef8c122d9635514ced565fe"),
    (bytes(range(1, 26)).hex(), "cd" * 50, "82558a389a443c0ea4cc819899f2083a85f0faa3e578f8077a2e3ff46729665b"),
    ("aa" * 131, b"Test Using Larger Than Block-Size Key - Hash Key First".hex(),
     "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54"),
    ("aa" * 131, (b"This is a test using a larger than block-size key and a larger than block-size data. "
                  b"The key needs to be hashed before being used by the HMAC algorithm.").hex(),
     "9b09ffa71b942fcb27635fbcd5b0e944bfdc63644f0713938a7f51535c3a35e2"),
]

RFC8032 = [
    ("9d61b19deffd5a60ba844af492ec2cc44449c5697b326919703bac031cae7f60",
     "d75a980182b10ab7d54bfed3c964073a0ee172f3daa62325af021a68f707511a", "",
     "e5564300c360ac729086e2cc806e828a84877f1eb8e5d974d873e065224901555fb8821590a33bacc61e39701cf9b46bd25bf5f0595bbe24655141438e7a100b"),
    ("4ccd089b28ff96da9db6c346ec114e0f5b8a319f35aba624da8cf6ed4fb8a6fb",
     "3d4017c3e843895a92b70aa74d1b7ebc9c982ccf2ec4968cc0cd55f12af4660c", "72",
     "92a009a9f0d4cab8720e820b5f642540a2b27b5416503f8fb3762223ebdb69da085ac1e43e15996e458f3613d0f11d8c387b2eaeb4302aeeb00d291612bb0c00"),
    ("c5aa8df43f9f837bedb7442f31dcb7b166d38535076f094b85ce3a2e0b4458f7",
     "fc51cd8e6218a1a38da47ed00230f0580816ed13ba3303ac5deb911548908025", "af82",
     "6291d657deec24024827e69c3abe01a30ce548a284743a445e3680d7db5ac3ac18ff9b538d16f290ae67f760984dc6594a7c15e9716ed28dc027beceea1ec40a"),
]


@pytest.mark.parametrize("key,data,mac", RFC4231)
def test_hmac_rfc4231(key, data, mac):
    assert hmac_tag(bytes.fromhex(key), bytes.fromhex(data)).hex() == mac
    assert verify_hmac(bytes.fromhex(key), bytes.fromhex(data), bytes.fromhex(mac))


def test_hmac_rfc4231_case5_truncated():
    assert hmac_tag(b"\x0c" * 20, b"Test With Truncation")[:16].hex() == "a3b6167473100ee06e0c796c2955552b"


@pytest.mark.parametrize("sk,pk,msg,sig", RFC8032)
def test_ed25519_rfc8032(sk, pk, msg, sig):
    key = ed25519.Ed25519PrivateKey.from_private_bytes(bytes.fromhex(sk))
    assert key.public_key().public_bytes_raw().hex() == pk
    assert sign(key, bytes.fromhex(msg)).hex() == sig
    pub = ed25519.Ed25519PublicKey.from_public_bytes(bytes.fromhex(pk))
    assert verify_signature(pub, bytes.fromhex(msg), bytes.fromhex(sig))
    bad = bytearray.fromhex(sig)
    bad[5] ^= 1
    assert not verify_signature(pub, bytes.fromhex(msg), bytes(bad))


def test_message_binds_identity_counter_and_config():
    prs = PRSParams(3, 6, 1, 12, 0, 52, 0, False)
    base = tag_message("hmac", 7, 100, 4, prs)
    variants = [tag_message("hmac", 8, 100, 4, prs), tag_message("hmac", 7, 101, 4, prs),
                tag_message("hmac", 7, 100, 5, prs), tag_message("ds", 7, 100, 4, prs),
                tag_message("hmac", 7, 100, 4, PRSParams(3, 6, 2, 12, 0, 52, 0, False)),
                tag_message("hmac", 7, 100, 4, PRSParams(3, 6, 1, 12, 0, 52, 0, True))]
    assert len({base, *variants}) == 7
    key = b"k" * 32
    assert verify_hmac(key, base, hmac_tag(key, base))
    assert not any(verify_hmac(key, v, hmac_tag(key, base)) for v in variants)
