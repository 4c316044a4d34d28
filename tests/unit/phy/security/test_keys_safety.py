"""Key material on a shared machine (issue 37): `keys --force` all or none, a new key folder
0700 with 0600 files, world-writable key material refused, readable secret keys warned about,
a byte-order mark handled, a keys_dir that is a file named as such."""

import errno
import logging
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.errors import InputError
from veriloc_rt.phy.security import keys as keys_module
from veriloc_rt.phy.security.keys import generate_keys, key_paths, load_keys

BOM = b"\xef\xbb\xbf"


def files(folder: Path) -> dict:
    return {p.name: (p.read_bytes(), stat.S_IMODE(p.stat().st_mode))
            for p in sorted(folder.iterdir())}


def failing_on(monkeypatch, n: int) -> list:
    """The n-th key file written fails with ENOSPC when it is synced (each file is synced once,
    right after its write; a full disk reports there what the page cache accepted)."""
    calls: list = []
    real = os.fsync

    def fsync(fd):
        calls.append(fd)
        if len(calls) == n:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    return calls


def test_force_replaces_the_whole_set_or_nothing(tmp_path, monkeypatch):
    """Issue 37: keys --force replaced some keys before failing on another."""
    out = tmp_path / "keys"
    generate_keys(out, [0, 1, 2], rng=np.random.default_rng(1))
    old = files(out)
    calls = failing_on(monkeypatch, 2)          # the second write of the new set fails
    with pytest.raises(InputError) as err:
        generate_keys(out, [0, 1, 2], overwrite=True)
    assert len(calls) == 2
    assert str(err.value) == (f"{out}: cannot write key files (No space left on device); "
                              "nothing was changed there")
    assert files(out) == old                                  # the old keys, complete
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keys"]  # no staging folder left
    load_keys(out, [0, 1, 2])
    # the swap itself failing: the same
    monkeypatch.undo()

    def no_swap(a, b):
        raise OSError(errno.EXDEV, os.strerror(errno.EXDEV))

    monkeypatch.setattr(keys_module, "exchange_folders", no_swap)
    with pytest.raises(InputError, match="nothing was changed there"):
        generate_keys(out, [0, 1, 2], overwrite=True)
    assert files(out) == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keys"]
    monkeypatch.undo()
    # and succeeding: every file new, keys of other BSs kept, the folder 0700
    generate_keys(tmp_path / "more", [7], rng=np.random.default_rng(2))
    for p in (tmp_path / "more").iterdir():
        os.link(p, out / p.name)
    generate_keys(out, [0, 1, 2], overwrite=True)
    new = files(out)
    assert sorted(new) == sorted(old) + sorted(p.name for p in (tmp_path / "more").iterdir())
    assert all(new[name][0] != old[name][0] for name in old)
    assert new["bs7.prs.aes"] == files(tmp_path / "more")["bs7.prs.aes"]
    assert stat.S_IMODE(out.stat().st_mode) == 0o700
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keys", "more"]
    load_keys(out, [0, 1, 2, 7])


def test_force_refuses_a_folder_holding_other_files(tmp_path):
    """The swap replaces the folder as a whole: other files would go with the old keys."""
    out = tmp_path / "keys"
    generate_keys(out, [0])
    (out / "notes.txt").write_text("mine")
    old = files(out)
    with pytest.raises(InputError, match=r"holds 'notes.txt', not a key file: keys --force "
                       r"replaces the key folder as a whole"):
        generate_keys(out, [0], overwrite=True)
    assert files(out) == old


def test_new_keys_into_a_folder_with_other_files_place_all_or_none(tmp_path, monkeypatch):
    out = tmp_path / "project"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    failing_on(monkeypatch, 6)
    with pytest.raises(InputError, match="nothing was changed there"):
        generate_keys(out, [0, 1])
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["project"]
    monkeypatch.undo()
    generate_keys(out, [0, 1])
    assert len(list(out.iterdir())) == 9 and (out / "notes.txt").read_text() == "mine"


def test_keys_command_creates_the_folder_0700_and_files_0600(tmp_path):
    """Issue 37: keys --out D created D 0755. Through the installed command, umask 022."""
    out = tmp_path / "a" / "keys"
    r = subprocess.run([str(Path(sys.executable).parent / "veriloc-rt"), "keys", "--out",
                        str(out), "--num-bs", "2"], capture_output=True, text=True, timeout=120,
                       preexec_fn=lambda: os.umask(0o022))
    assert r.returncode == 0, r.stderr
    assert stat.S_IMODE(out.stat().st_mode) == 0o700
    assert {mode for _, mode in files(out).values()} == {0o600}
    assert len(files(out)) == 8


@pytest.mark.parametrize("name", ["aes", "hmac", "sign", "verify"])
def test_world_writable_key_material_is_refused(tmp_path, name):
    generate_keys(tmp_path / "k", [3])
    path = key_paths(tmp_path / "k", 3)[name]
    path.chmod(0o602)
    with pytest.raises(InputError) as err:
        load_keys(tmp_path / "k", [3])
    assert str(err.value) == (f"{path}: key file is world-writable (mode 0602): anyone on this "
                              f"machine could replace the key; `chmod 600 {path}`")


def test_a_world_writable_key_folder_is_refused(tmp_path):
    out = tmp_path / "k"
    generate_keys(out, [3])
    out.chmod(0o777)
    with pytest.raises(InputError, match=r"its folder is world-writable \(mode 0777\)"):
        load_keys(out, [3])
    out.chmod(0o1777)      # sticky, as /tmp: others cannot replace the files
    load_keys(out, [3])


def test_secret_key_material_others_may_read_is_warned_about(tmp_path, caplog):
    out = tmp_path / "k"
    generate_keys(out, [3])
    p = key_paths(out, 3)
    p["hmac"].chmod(0o640)
    p["verify"].chmod(0o644)       # a public key: no warning
    with caplog.at_level(logging.WARNING, logger=keys_module.__name__):
        load_keys(out, [3])
    assert [r.getMessage() for r in caplog.records] == [
        f"{p['hmac']}: secret key material readable or writable by others (mode 0640): "
        f"`chmod 600 {p['hmac']}`"]


def test_a_byte_order_mark_is_dropped(tmp_path):
    """Issue 37: a BOM showed as mojibake. An editor's BOM in front of every file: the same
    keys load; in a malformed file, the message quotes no BOM."""
    out = tmp_path / "k"
    generate_keys(out, [2], rng=np.random.default_rng(3))
    want = load_keys(out, [2])[2]
    for path in key_paths(out, 2).values():
        path.write_bytes(BOM + path.read_bytes())
    got = load_keys(out, [2])[2]
    assert (got.aes_key, got.hmac_key) == (want.aes_key, want.hmac_key)
    assert got.verify_key.public_bytes_raw() == want.verify_key.public_bytes_raw()
    assert got.sign_key.private_bytes_raw() == want.sign_key.private_bytes_raw()
    aes = key_paths(out, 2)["aes"]
    aes.write_bytes(BOM + b"hmac-sha256 bs2 " + b"00" * 16 + b"\n")
    with pytest.raises(InputError) as err:
        load_keys(out, [2])
    assert str(err.value) == (f"{aes}: holds a 'hmac-sha256' key, expected aes-128 or aes-256 "
                              "(files swapped?)")
    aes.write_bytes(b"aes-128 bs2 \xe9\xe9\n")
    with pytest.raises(InputError) as err:
        load_keys(out, [2])
    assert str(err.value) == f"{aes}: key file is not UTF-8 text (byte 0xe9 at offset 12)"


def test_a_keys_dir_that_is_a_file_is_not_a_folder(tmp_path):
    """Issue 37: it said 'does not exist'."""
    f = tmp_path / "keys"
    f.write_text("x")
    with pytest.raises(InputError) as err:
        load_keys(f, [0])
    assert str(err.value) == (f"{f}: is not a folder (generate a set with `veriloc-rt keys "
                              "--out DIR`)")
    with pytest.raises(InputError, match="keys directory does not exist"):
        load_keys(tmp_path / "missing", [0])
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    with pytest.raises(InputError, match="is a symbolic link loop"):
        load_keys(loop, [0])
    with pytest.raises(InputError, match=r"^.*keys: is not a folder$"):
        generate_keys(f, [0])
